// Reference silhouettes for the Middlebury sparse rings (see README.md here): OpenCV's grabCut
// (colour mixture models + graph cut) seeded per view from seeds.txt, written as 1-bit PNGs, with
// an overlay per view (the mask's outline on a gamma-brightened photo) for checking by eye.
//
// Not part of the build (a one-off tool, kept so the references can be remade):
//   g++ -O2 -std=c++20 make_reference.cc -o make_reference $(pkg-config --cflags --libs opencv4)
//   ./make_reference IMAGE_DIR SEEDS OUT_DIR [OVERLAY_DIR]
//
// seeds.txt, one line per view: FILE SURE_FG SURE_BG [KIND X0 Y0 X1 Y1]...
//   brightest channel > SURE_FG (eroded 3 px): sure object; <= SURE_BG (eroded 4 px): sure
//   backdrop; above the midpoint: probable object; else probable backdrop. KIND bg / fg forces a
//   rectangle to backdrop / object; pbg / pfg marks it probable backdrop / object.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

int main(int argc, char** argv) {
  if (argc < 4) {
    std::cerr << "usage: make_reference IMAGE_DIR SEEDS OUT_DIR [OVERLAY_DIR]\n";
    return 2;
  }
  const std::string dir = argv[1];
  std::ifstream seeds(argv[2]);
  const std::string out = argv[3];
  const std::string overlay_dir = argc > 4 ? argv[4] : "";
  std::string line;
  while (std::getline(seeds, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream in(line);
    std::string file;
    int fg_level = 0, bg_level = 0;
    in >> file >> fg_level >> bg_level;
    const cv::Mat image = cv::imread(dir + "/" + file, cv::IMREAD_COLOR);
    if (image.empty()) {
      std::cerr << file << ": cannot read\n";
      return 1;
    }
    std::vector<cv::Mat> ch;
    cv::split(image, ch);
    cv::Mat brightest = cv::max(ch[0], cv::max(ch[1], ch[2]));
    // Initial labels: sure background below bg_level, sure foreground above fg_level (eroded,
    // so that no edge pixel is forced), probable foreground/background in between.
    cv::Mat mask(image.size(), CV_8UC1, cv::Scalar(cv::GC_PR_BGD));
    mask.setTo(cv::GC_PR_FGD, brightest > (fg_level + bg_level) / 2);
    cv::Mat sure_fg = brightest > fg_level;
    cv::erode(sure_fg, sure_fg, cv::getStructuringElement(cv::MORPH_ELLIPSE, {7, 7}));
    cv::Mat sure_bg = brightest <= bg_level;
    cv::erode(sure_bg, sure_bg, cv::getStructuringElement(cv::MORPH_ELLIPSE, {9, 9}));
    mask.setTo(cv::GC_FGD, sure_fg);
    mask.setTo(cv::GC_BGD, sure_bg);
    std::string kind;
    std::vector<std::pair<cv::Rect, int>> forced;
    while (in >> kind) {
      int x0, y0, x1, y1;
      in >> x0 >> y0 >> x1 >> y1;
      cv::Rect r(cv::Point(x0, y0), cv::Point(x1, y1));
      r &= cv::Rect(0, 0, image.cols, image.rows);
      int label = kind == "bg"    ? cv::GC_BGD
                  : kind == "fg"  ? cv::GC_FGD
                  : kind == "pbg" ? cv::GC_PR_BGD
                                  : cv::GC_PR_FGD;
      if (kind == "bg" || kind == "fg")
        forced.push_back({r, label});
      else if (kind == "pbg") {
        cv::Mat sub = mask(r);
        sub.setTo(cv::GC_PR_BGD, sub != cv::GC_BGD);
      } else
        mask(r).setTo(label);
    }
    for (auto& [r, label] : forced) mask(r).setTo(label);
    cv::Mat bgd, fgd;
    cv::grabCut(image, mask, cv::Rect(), bgd, fgd, 8, cv::GC_INIT_WITH_MASK);
    cv::Mat result = (mask == cv::GC_FGD) | (mask == cv::GC_PR_FGD);
    // Largest component only (the object is one piece in every view).
    cv::Mat labels, stats, centroids;
    int n = cv::connectedComponentsWithStats(result, labels, stats, centroids, 8);
    int best = 0, best_area = 0;
    for (int i = 1; i < n; ++i)
      if (stats.at<int>(i, cv::CC_STAT_AREA) > best_area)
        best_area = stats.at<int>(i, cv::CC_STAT_AREA), best = i;
    result = labels == best;
    const std::string stem = file.substr(0, file.rfind('.'));
    cv::imwrite(out + "/" + stem + ".png", result, {cv::IMWRITE_PNG_BILEVEL, 1});
    std::printf("%s area %d\n", file.c_str(), cv::countNonZero(result));
    if (!overlay_dir.empty()) {
      cv::Mat shown = image.clone();
      // Brighten the dark backdrop so the edge is visible, then draw the contour.
      cv::Mat lut(1, 256, CV_8UC1);
      for (int i = 0; i < 256; ++i)
        lut.at<uchar>(i) = cv::saturate_cast<uchar>(255.0 * std::pow(i / 255.0, 0.4));
      cv::LUT(shown, lut, shown);
      std::vector<std::vector<cv::Point>> contours;
      cv::findContours(result.clone(), contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
      cv::drawContours(shown, contours, -1, cv::Scalar(255, 0, 255), 1);
      for (auto& [r, label] : forced)
        cv::rectangle(shown, r, label == cv::GC_BGD ? cv::Scalar(255, 0, 0) : cv::Scalar(0, 255, 0),
                      1);
      cv::imwrite(overlay_dir + "/" + stem + ".png", shown);
    }
  }
  return 0;
}
