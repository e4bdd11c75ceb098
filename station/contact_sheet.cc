#include "station/contact_sheet.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include <opencv2/imgproc.hpp>

namespace revolve::station {
namespace {
constexpr int kTileWidthPx = 192;
constexpr int kColumns = 6;

// The thumbnail's scale: a whole number of frame pixels to one, the least that makes it at most
// kTileWidthPx wide (cv::resize's area averaging is several times faster at a whole factor: 1 ms
// instead of 3.4 for a 1280 x 960 frame).
double ThumbnailScale(int frame_cols) {
  return 1.0 / std::max(1, (frame_cols + kTileWidthPx - 1) / kTileWidthPx);
}
}  // namespace

cv::Mat ContactSheetTile(const cv::Mat& frame, const cv::Mat& mask) {
  return ContactSheetOutline(ContactSheetThumbnail(frame), mask);
}

cv::Mat ContactSheetThumbnail(const cv::Mat& frame) {
  const double scale = ThumbnailScale(frame.cols);
  cv::Mat thumbnail;
  cv::resize(frame, thumbnail, cv::Size(), scale, scale, cv::INTER_AREA);
  return thumbnail;
}

cv::Mat ContactSheetThumbnail(const cv::Mat& frame, const cv::Rect& content) {
  const double fx = ThumbnailScale(frame.cols);
  // cv::resize's own factor (1 / fx, frame pixels a thumbnail pixel): when it is j / 64 exactly,
  // every thumbnail pixel's frame pixels and weights repeat, shifted by `period` frame pixels,
  // every `step` thumbnail pixels; a part cut at multiples of `period` shrinks to the same pixels.
  const double scale = 1.0 / fx;
  const double scale64 = scale * 64.0;
  if (fx >= 1.0 || !(scale64 < 1e6) || scale64 != std::floor(scale64)) {
    return ContactSheetThumbnail(frame);
  }
  const auto j = static_cast<int>(scale64);
  const int step = 64 / std::gcd(j, 64);
  const int period = j / std::gcd(j, 64);  // step * scale
  const cv::Rect inside = content & cv::Rect(0, 0, frame.cols, frame.rows);
  const cv::Size size(cvRound(frame.cols * fx), cvRound(frame.rows * fx));
  if (inside.empty()) return cv::Mat::zeros(size, frame.type());  // a zero frame shrinks to zeros
  const int x0 = inside.x / period * period;
  const int y0 = inside.y / period * period;
  const int x1 = std::min(frame.cols, (inside.br().x + period - 1) / period * period);
  const int y1 = std::min(frame.rows, (inside.br().y + period - 1) / period * period);
  cv::Mat part;
  cv::resize(frame(cv::Rect(x0, y0, x1 - x0, y1 - y0)), part, cv::Size(), fx, fx, cv::INTER_AREA);
  // Where the part's pixels go: its first at the period's; its last at the thumbnail's end when
  // the part reaches the frame's (a shorter last pixel), else at its own period's end.
  const int u0 = x0 / period * step;
  const int v0 = y0 / period * step;
  const int u1 = x1 == frame.cols ? size.width : x1 / period * step;
  const int v1 = y1 == frame.rows ? size.height : y1 / period * step;
  if (part.cols != u1 - u0 || part.rows != v1 - v0) return ContactSheetThumbnail(frame);
  cv::Mat thumbnail = cv::Mat::zeros(size, frame.type());
  part.copyTo(thumbnail(cv::Rect(u0, v0, part.cols, part.rows)));
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

cv::Mat MarkedLeftOut(cv::Mat tile) {
  cv::rectangle(tile, cv::Rect(0, 0, tile.cols, tile.rows), cv::Scalar(0, 165, 255), 3);
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
