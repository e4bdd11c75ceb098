// Pixel conversion from V4L2 capture formats to BGR: pure functions, no device involved.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include <opencv2/core.hpp>

#include "base/error.h"

namespace revolve::capture {

// The V4L2 four-character code of a pixel format, as v4l2_fourcc() builds it.
constexpr std::uint32_t FourCc(char a, char b, char c, char d) {
  return static_cast<std::uint32_t>(static_cast<unsigned char>(a)) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(b)) << 8) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(c)) << 16) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(d)) << 24);
}
inline constexpr std::uint32_t kFourCcYuyv = FourCc('Y', 'U', 'Y', 'V');
inline constexpr std::uint32_t kFourCcUyvy = FourCc('U', 'Y', 'V', 'Y');
inline constexpr std::uint32_t kFourCcGrey = FourCc('G', 'R', 'E', 'Y');
inline constexpr std::uint32_t kFourCcMjpg = FourCc('M', 'J', 'P', 'G');
inline constexpr std::uint32_t kFourCcJpeg = FourCc('J', 'P', 'E', 'G');
inline constexpr std::uint32_t kFourCcRgb24 = FourCc('R', 'G', 'B', '3');
inline constexpr std::uint32_t kFourCcBgr24 = FourCc('B', 'G', 'R', '3');

// "YUYV" for kFourCcYuyv; non-printable bytes become '?'.
// Inline: the libcamera plugin uses it too (capture/libcamera/libcamera_plugin.h).
inline std::string FourCcToString(std::uint32_t fourcc) {
  std::string out(4, '?');
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xFF);
    if (c >= 0x20 && c < 0x7F) out[i] = c;
  }
  return out;
}

// bad_input unless `text` has exactly four characters.
Expected<std::uint32_t> ParseFourCc(std::string_view text);

// True for the formats ConvertToBgr handles.
bool CanConvert(std::uint32_t fourcc);

// One pixel of BT.601 limited-range YCbCr (what UVC cameras send) as B, G, R:
//   R = 1.164 (Y - 16) + 1.596 (V - 128)
//   G = 1.164 (Y - 16) - 0.392 (U - 128) - 0.813 (V - 128)
//   B = 1.164 (Y - 16) + 2.017 (U - 128)
// in 8-bit fixed point (coefficients x 256, rounded), clamped to [0, 255].
std::array<std::uint8_t, 3> YuvToBgr(int y, int u, int v);

// True when `data` starts with a JPEG SOI marker (FF D8) and holds an EOI marker (FF D9) at its
// end, zero padding after it allowed. UVC cameras deliver truncated MJPEG frames now and then.
bool IsCompleteJpeg(std::span<const std::uint8_t> data);

// Converts one captured frame to BGR (CV_8UC3, width x height). `bytes_per_line` is the
// driver's stride (0: tightly packed). YUYV and UYVY by YuvToBgr (a pair of pixels shares U and
// V), GREY replicated, RGB3/BGR3 reordered, MJPG/JPEG decoded (cv::imdecode).
// Errors: bad_input for too little data, a truncated or undecodable JPEG, a decoded JPEG of
// another size, an odd width for YUYV/UYVY; unsupported for other formats.
Expected<cv::Mat> ConvertToBgr(std::span<const std::uint8_t> data, std::uint32_t fourcc, int width,
                               int height, int bytes_per_line);

}  // namespace revolve::capture
