#include "base/mask_bits.h"

#include <algorithm>
#include <cstring>

namespace revolve {

std::vector<std::uint64_t> PackMaskBits(const cv::Mat& mask, const cv::Rect& roi, int words) {
  std::vector<std::uint64_t> bits(static_cast<std::size_t>(std::max(words, 0)) *
                                      static_cast<std::size_t>(std::max(roi.height, 0)),
                                  0);
  for (int y = 0; y < roi.height; ++y) {
    const std::uint8_t* row = mask.ptr<std::uint8_t>(roi.y + y) + roi.x;
    std::uint64_t* out = &bits[static_cast<std::size_t>(y) * static_cast<std::size_t>(words)];
    int x = 0;
    // Eight pixels at a time: each byte to 0 or 1 (any bit set), then each byte gathers its 7
    // successors' bits above its own.
    for (; x + 8 <= roi.width; x += 8) {
      std::uint64_t bytes;
      std::memcpy(&bytes, row + x, 8);
      bytes |= bytes >> 4;
      bytes |= bytes >> 2;
      bytes |= bytes >> 1;
      bytes &= 0x0101010101010101ull;
      bytes |= bytes >> 7;
      bytes |= bytes >> 14;
      bytes |= bytes >> 28;
      out[x >> 6] |= (bytes & 0xFF) << (x & 63);
    }
    for (; x < roi.width; ++x) out[x >> 6] |= std::uint64_t{row[x] != 0} << (x & 63);
  }
  return bits;
}

}  // namespace revolve
