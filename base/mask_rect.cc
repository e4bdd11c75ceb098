#include "base/mask_rect.h"

#include <bit>
#include <cstdint>
#include <cstring>

namespace revolve {
namespace {

std::uint64_t Word(const std::uint8_t* p) {
  std::uint64_t word;
  std::memcpy(&word, p, sizeof word);
  return word;
}

// The first and the last non-zero byte of a non-zero word read from memory.
int FirstByte(std::uint64_t word) {
  if constexpr (std::endian::native == std::endian::little) return std::countr_zero(word) / 8;
  return std::countl_zero(word) / 8;
}
int LastByte(std::uint64_t word) {
  if constexpr (std::endian::native == std::endian::little) return 7 - std::countl_zero(word) / 8;
  return 7 - std::countr_zero(word) / 8;
}

// The first non-zero byte of p[begin, end), or `end` when there is none: 32 bytes a test (four
// words or'ed), then the word, then the byte.
int FirstSet(const std::uint8_t* p, int begin, int end) {
  int x = begin;
  while (x + 32 <= end) {
    const std::uint64_t w0 = Word(p + x), w1 = Word(p + x + 8);
    const std::uint64_t w2 = Word(p + x + 16), w3 = Word(p + x + 24);
    if (((w0 | w1) | (w2 | w3)) != 0) break;
    x += 32;
  }
  for (; x + 8 <= end; x += 8) {
    const std::uint64_t w = Word(p + x);
    if (w != 0) return x + FirstByte(w);
  }
  for (; x < end; ++x) {
    if (p[x] != 0) return x;
  }
  return end;
}

// The last non-zero byte of p[begin, end), or begin - 1 when there is none.
int LastSet(const std::uint8_t* p, int begin, int end) {
  int x = end;  // bytes [x, end) hold none
  while (x - 32 >= begin) {
    const std::uint64_t w0 = Word(p + x - 32), w1 = Word(p + x - 24);
    const std::uint64_t w2 = Word(p + x - 16), w3 = Word(p + x - 8);
    if (((w0 | w1) | (w2 | w3)) != 0) break;
    x -= 32;
  }
  for (; x - 8 >= begin; x -= 8) {
    const std::uint64_t w = Word(p + x - 8);
    if (w != 0) return x - 8 + LastByte(w);
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
