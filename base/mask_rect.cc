#include "base/mask_rect.h"

#include <cstdint>
#include <cstring>

namespace revolve {
namespace {

// The first non-zero byte of p[begin, end), or `end` when there is none.
int FirstSet(const std::uint8_t* p, int begin, int end) {
  int x = begin;
  for (; x + 8 <= end; x += 8) {
    std::uint64_t word;
    std::memcpy(&word, p + x, sizeof word);
    if (word != 0) break;
  }
  for (; x < end; ++x) {
    if (p[x] != 0) return x;
  }
  return end;
}

// The last non-zero byte of p[begin, end), or begin - 1 when there is none.
int LastSet(const std::uint8_t* p, int begin, int end) {
  int x = end;
  for (; x - 8 >= begin; x -= 8) {
    std::uint64_t word;
    std::memcpy(&word, p + x - 8, sizeof word);
    if (word != 0) break;
  }
  for (; x > begin; --x) {
    if (p[x - 1] != 0) return x - 1;
  }
  return begin - 1;
}

}  // namespace

cv::Rect MaskRect(const cv::Mat& mask) {
  CV_Assert(mask.channels() == 1 && (mask.depth() == CV_8U || mask.depth() == CV_8S));
  const int cols = mask.cols;
  int top = 0;
  while (top < mask.rows && FirstSet(mask.ptr<std::uint8_t>(top), 0, cols) == cols) ++top;
  if (top == mask.rows) return {};
  int bottom = mask.rows - 1;
  while (bottom > top && FirstSet(mask.ptr<std::uint8_t>(bottom), 0, cols) == cols) --bottom;
  // Each row between is read only left of the columns found so far and right of them.
  int left = cols;
  int right = -1;
  for (int y = top; y <= bottom; ++y) {
    const auto* row = mask.ptr<std::uint8_t>(y);
    left = FirstSet(row, 0, left);
    const int last = LastSet(row, right + 1, cols);
    if (last > right) right = last;
  }
  return {left, top, right - left + 1, bottom - top + 1};
}

}  // namespace revolve
