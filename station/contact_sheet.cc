#include "station/contact_sheet.h"

#include <algorithm>
#include <string>

#include <opencv2/imgproc.hpp>

namespace revolve::station {
namespace {
constexpr int kTileWidthPx = 192;
constexpr int kColumns = 6;
}  // namespace

cv::Mat ContactSheetTile(const cv::Mat& frame, const cv::Mat& mask) {
  return ContactSheetOutline(ContactSheetThumbnail(frame), mask);
}

cv::Mat ContactSheetThumbnail(const cv::Mat& frame) {
  const double scale = std::min(1.0, static_cast<double>(kTileWidthPx) / frame.cols);
  cv::Mat thumbnail;
  cv::resize(frame, thumbnail, cv::Size(), scale, scale, cv::INTER_AREA);
  return thumbnail;
}

cv::Mat ContactSheetOutline(const cv::Mat& thumbnail, const cv::Mat& mask) {
  cv::Mat tile = thumbnail.clone();
  cv::Mat small_mask;
  cv::resize(mask, small_mask, tile.size(), 0, 0, cv::INTER_NEAREST);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(small_mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  if (contours.empty()) {
    cv::rectangle(tile, cv::Rect(0, 0, tile.cols, tile.rows), cv::Scalar(0, 0, 255), 3);
  } else {
    cv::drawContours(tile, contours, -1, cv::Scalar(0, 255, 0), 1, cv::LINE_AA);
  }
  return tile;
}

cv::Mat AssembleContactSheet(const std::vector<cv::Mat>& tiles) {
  if (tiles.empty()) return cv::Mat(16, 16, CV_8UC3, cv::Scalar::all(0));
  const int w = tiles.front().cols;
  const int h = tiles.front().rows;
  const int cols = std::min<int>(kColumns, static_cast<int>(tiles.size()));
  const int rows = (static_cast<int>(tiles.size()) + cols - 1) / cols;
  cv::Mat sheet(rows * h, cols * w, CV_8UC3, cv::Scalar::all(0));
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    const int r = static_cast<int>(i) / cols;
    const int c = static_cast<int>(i) % cols;
    cv::Mat roi = sheet(cv::Rect(c * w, r * h, w, h));
    cv::Mat tile;
    if (tiles[i].size() == roi.size()) {
      tile = tiles[i];
    } else {
      cv::resize(tiles[i], tile, roi.size());
    }
    tile.copyTo(roi);
    cv::putText(roi, std::to_string(i), cv::Point(4, 16), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  return sheet;
}

}  // namespace revolve::station
