#include "capture/v4l2/pixel_convert.h"

#include <algorithm>

#include <fmt/format.h>

#include "base/image_codecs.h"

namespace revolve::capture {
namespace {

std::uint8_t Clamp8(int value) { return static_cast<std::uint8_t>(std::clamp(value, 0, 255)); }

}  // namespace

Expected<std::uint32_t> ParseFourCc(std::string_view text) {
  if (text.size() != 4) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("\"{}\" is not a four-character pixel format code", text));
  }
  return FourCc(text[0], text[1], text[2], text[3]);
}

bool CanConvert(std::uint32_t fourcc) {
  return fourcc == kFourCcYuyv || fourcc == kFourCcUyvy || fourcc == kFourCcGrey ||
         fourcc == kFourCcMjpg || fourcc == kFourCcJpeg || fourcc == kFourCcRgb24 ||
         fourcc == kFourCcBgr24;
}

std::array<std::uint8_t, 3> YuvToBgr(int y, int u, int v) {
  const int c = y - 16, d = u - 128, e = v - 128;
  return {Clamp8((298 * c + 516 * d + 128) >> 8), Clamp8((298 * c - 100 * d - 208 * e + 128) >> 8),
          Clamp8((298 * c + 409 * e + 128) >> 8)};
}

bool IsCompleteJpeg(std::span<const std::uint8_t> data) {
  if (data.size() < 4 || data[0] != 0xFF || data[1] != 0xD8) return false;
  std::size_t end = data.size();
  while (end > 2 && data[end - 1] == 0x00) --end;  // drivers may pad with zeros
  return end >= 4 && data[end - 2] == 0xFF && data[end - 1] == 0xD9;
}

Expected<cv::Mat> ConvertToBgr(std::span<const std::uint8_t> data, std::uint32_t fourcc, int width,
                               int height, int bytes_per_line) {
  if (width <= 0 || height <= 0) {
    return MakeError(ErrorCode::kBadInput, fmt::format("bad frame size {}x{}", width, height));
  }
  if (fourcc == kFourCcMjpg || fourcc == kFourCcJpeg) {
    if (!IsCompleteJpeg(data)) {
      return MakeError(ErrorCode::kBadInput, "truncated MJPEG frame (no SOI or EOI marker)");
    }
    Expected<cv::Mat> opencv = DecodeImage(data, cv::IMREAD_COLOR);
    if (!opencv && opencv.error().code != ErrorCode::kBadInput) return opencv;
    if (!opencv) return MakeError(ErrorCode::kBadInput, "undecodable MJPEG frame");
    cv::Mat decoded = std::move(*opencv);
    if (decoded.cols != width || decoded.rows != height) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("MJPEG frame is {}x{}, the format says {}x{}", decoded.cols,
                                   decoded.rows, width, height));
    }
    return decoded;
  }
  int bytes_per_pixel = 0;
  if (fourcc == kFourCcYuyv || fourcc == kFourCcUyvy) {
    bytes_per_pixel = 2;
    if (width % 2 != 0) {
      return MakeError(ErrorCode::kBadInput, fmt::format("{} needs an even width, got {}",
                                                         FourCcToString(fourcc), width));
    }
  } else if (fourcc == kFourCcGrey) {
    bytes_per_pixel = 1;
  } else if (fourcc == kFourCcRgb24 || fourcc == kFourCcBgr24) {
    bytes_per_pixel = 3;
  } else {
    return MakeError(ErrorCode::kUnsupported,
                     fmt::format("pixel format {} cannot be converted (YUYV, UYVY, GREY, MJPG, "
                                 "RGB3 and BGR3 can)",
                                 FourCcToString(fourcc)));
  }
  const std::size_t stride = bytes_per_line > 0 ? static_cast<std::size_t>(bytes_per_line)
                                                : static_cast<std::size_t>(width) * bytes_per_pixel;
  if (stride < static_cast<std::size_t>(width) * bytes_per_pixel) {
    return MakeError(ErrorCode::kBadInput, fmt::format("stride {} is shorter than a row", stride));
  }
  const std::size_t needed =
      stride * (height - 1) + static_cast<std::size_t>(width) * bytes_per_pixel;
  if (data.size() < needed) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("short {} frame: {} bytes, {} needed", FourCcToString(fourcc),
                                 data.size(), needed));
  }
  cv::Mat out(height, width, CV_8UC3);
  for (int row = 0; row < height; ++row) {
    const std::uint8_t* in = data.data() + stride * row;
    auto* px = out.ptr<cv::Vec3b>(row);
    if (fourcc == kFourCcYuyv || fourcc == kFourCcUyvy) {
      const bool yuyv = fourcc == kFourCcYuyv;
      for (int x = 0; x < width; x += 2, in += 4) {
        const int y0 = yuyv ? in[0] : in[1], y1 = yuyv ? in[2] : in[3];
        const int u = yuyv ? in[1] : in[0], v = yuyv ? in[3] : in[2];
        const auto a = YuvToBgr(y0, u, v), b = YuvToBgr(y1, u, v);
        px[x] = cv::Vec3b(a[0], a[1], a[2]);
        px[x + 1] = cv::Vec3b(b[0], b[1], b[2]);
      }
    } else if (fourcc == kFourCcGrey) {
      for (int x = 0; x < width; ++x) px[x] = cv::Vec3b(in[x], in[x], in[x]);
    } else if (fourcc == kFourCcRgb24) {
      for (int x = 0; x < width; ++x, in += 3) px[x] = cv::Vec3b(in[2], in[1], in[0]);
    } else {
      for (int x = 0; x < width; ++x, in += 3) px[x] = cv::Vec3b(in[0], in[1], in[2]);
    }
  }
  return out;
}

}  // namespace revolve::capture
