#include "station/contact_sheet.h"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <string>
#include <vector>

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

// One thumbnail sample from the column sums of its block's `columns` columns (`step` apart),
// `rows` rows each: OpenCV's rounding of a whole block's (`whole`) or of a cut one's.
inline std::uint8_t BlockSample(const std::uint16_t* sums, int step, int columns, int rows,
                                bool whole, float per_sample) {
  int sum = 0;
  for (std::ptrdiff_t t = 0; t < columns; ++t) sum += sums[t * step];
  if (whole) return cv::saturate_cast<std::uint8_t>(static_cast<float>(sum) * per_sample);
  return columns == 0 ? std::uint8_t{0}
                      : cv::saturate_cast<std::uint8_t>(static_cast<float>(sum) /
                                                        static_cast<float>(columns * rows));
}

// column[x] += row[x] for the `width` samples of a frame row (built for AVX2 too where the
// processor has it).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
void AddRow(const std::uint8_t* row, int width, std::uint16_t* column) {
  for (int x = 0; x < width; ++x) column[x] = static_cast<std::uint16_t>(column[x] + row[x]);
}

// A thumbnail row of kChannels channels from its frame rows' column sums.
template <int kChannels>
void BlockSums(const std::uint16_t* column, int k, int frame_cols, int rows, int whole,
               float per_sample, std::uint8_t* d, int width) {
  // The whole blocks (`whole` samples), a pixel's channels summed together: BlockSample's sums
  // and rounding, without its per-sample choices.
  const int whole_blocks = whole / kChannels;
  for (int j = 0; j < whole_blocks; ++j) {
    const std::uint16_t* sums = column + static_cast<std::ptrdiff_t>(j) * k * kChannels;
    std::array<int, kChannels> sum{};
    for (int t = 0; t < k; ++t, sums += kChannels) {
      for (int c = 0; c < kChannels; ++c) sum[c] += sums[c];
    }
    for (int c = 0; c < kChannels; ++c) {
      d[j * kChannels + c] =
          cv::saturate_cast<std::uint8_t>(static_cast<float>(sum[c]) * per_sample);
    }
  }
  for (int j = whole_blocks; j < width; ++j) {
    const std::uint16_t* sums = column + static_cast<std::ptrdiff_t>(j) * k * kChannels;
    const int columns = std::clamp(frame_cols - j * k, 0, k);
    for (int c = 0; c < kChannels; ++c) {
      d[j * kChannels + c] =
          BlockSample(sums + c, kChannels, columns, rows, j * kChannels + c < whole, per_sample);
    }
  }
}

// cv::resize(src, out, cv::Size(), fx, fx, cv::INTER_AREA), to the bit. When 1 / fx is a whole
// factor k from 3 to 257 (OpenCV's fast area path, whose k = 2 rounds otherwise; 8-bit samples),
// each thumbnail sample of a whole k x k block is round(sum * (1.f / (k k))), and of a block the
// right or bottom border cuts short round(float(sum) / count) over its samples inside, as OpenCV's.
// The sums are made a row of blocks at a time, the k rows' columns first, not from k^2 scattered
// reads per sample (1.5 ms for a 1280 x 960 photo), and a whole block's channels together: 5 M
// instructions a photo instead of 10 M. Otherwise cv::resize itself.
cv::Mat ShrinkByArea(const cv::Mat& src, double fx) {
  const double factor = 1.0 / fx;
  const int k = cv::saturate_cast<int>(factor);
  const cv::Size size(cv::saturate_cast<int>(src.cols * fx), cv::saturate_cast<int>(src.rows * fx));
  if (src.depth() != CV_8U || k < 3 || k > 257 || std::abs(factor - k) >= DBL_EPSILON ||
      size.width <= 0 || size.height <= 0) {
    cv::Mat out;
    cv::resize(src, out, cv::Size(), fx, fx, cv::INTER_AREA);
    return out;
  }
  const int cn = src.channels();
  const int width = src.cols * cn;        // samples of a frame row
  const int whole = (src.cols / k) * cn;  // samples of whole blocks in a thumbnail row
  const int samples = size.width * cn;    // samples of a thumbnail row
  const float per_sample = 1.f / static_cast<float>(k * k);
  cv::Mat out(size, src.type());
  std::vector<std::uint16_t> column(static_cast<std::size_t>(width));  // 255 k fits
  for (int dy = 0; dy < size.height; ++dy) {
    std::uint8_t* d = out.ptr<std::uint8_t>(dy);
    const int y0 = dy * k;
    const int rows = std::min(k, src.rows - y0);
    if (rows <= 0) {
      std::fill(d, d + samples, std::uint8_t{0});
      continue;
    }
    std::copy(src.ptr<std::uint8_t>(y0), src.ptr<std::uint8_t>(y0) + width, column.begin());
    for (int y = y0 + 1; y < y0 + rows; ++y) AddRow(src.ptr<std::uint8_t>(y), width, column.data());
    // Each block's k columns (fewer where the right border cuts it short), channel by channel.
    const int whole_here = rows == k ? whole : 0;
    if (cn == 3) {
      BlockSums<3>(column.data(), k, src.cols, rows, whole_here, per_sample, d, size.width);
    } else if (cn == 1) {
      BlockSums<1>(column.data(), k, src.cols, rows, whole_here, per_sample, d, size.width);
    } else {
      for (int j = 0; j < size.width; ++j) {
        for (int c = 0; c < cn; ++c) {
          d[j * cn + c] = BlockSample(column.data() + static_cast<std::ptrdiff_t>(j) * k * cn + c,
                                      cn, std::clamp(src.cols - j * k, 0, k), rows,
                                      j * cn + c < whole_here, per_sample);
        }
      }
    }
  }
  return out;
}

}  // namespace

cv::Mat ContactSheetTile(const cv::Mat& frame, const cv::Mat& mask) {
  return ContactSheetOutline(ContactSheetThumbnail(frame), mask);
}

cv::Mat ContactSheetThumbnail(const cv::Mat& frame) {
  return ShrinkByArea(frame, ThumbnailScale(frame.cols));
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
  const cv::Mat part = ShrinkByArea(frame(cv::Rect(x0, y0, x1 - x0, y1 - y0)), fx);
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
