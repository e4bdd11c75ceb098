// Fuzzes what an image file goes through before OpenCV may decode it: the header check, then a
// decode to the end with libjpeg, libpng or libtiff where every warning is an error
// (base/image_verify.h). No input may crash, leak, read out of bounds or hang. The one-pass
// decoders, and DecodePlainPng (base/png_decode.h, libdeflate) among them, decode exactly what
// libpng's check passes.
#include <cstdint>
#include <cstdlib>
#include <span>

#include <opencv2/imgcodecs.hpp>

#include "base/image_header.h"
#include "base/image_verify.h"
#include "base/png_decode.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  auto header = revolve::CheckImageBytes(bytes);
  // The decoders run only on files within a small size here, so that a run stays fast.
  if (!header || header->pixels() > 4'000'000) return 0;
  const bool verified = revolve::VerifyImageData(header->format, bytes).has_value();
  const bool png = header->format == revolve::ImageFormat::kPng;
  if (png || header->format == revolve::ImageFormat::kJpeg) {
    // The one-pass decoders agree with the check, and give the header's size.
    for (const int flags : {cv::IMREAD_UNCHANGED, cv::IMREAD_COLOR, cv::IMREAD_GRAYSCALE}) {
      auto decoded = png ? revolve::DecodeVerifiedPng(bytes, flags)
                         : revolve::DecodeVerifiedJpeg(bytes, flags);
      if (!decoded) continue;
      if (decoded->has_value() != verified) std::abort();
      if (*decoded &&
          ((*decoded)->cols != header->width_px || (*decoded)->rows != header->height_px)) {
        std::abort();
      }
      // What DecodePlainPng decodes, libpng passes too.
      if (png && revolve::DecodePlainPng(bytes, flags) && !verified) std::abort();
    }
  }
  return 0;
}
