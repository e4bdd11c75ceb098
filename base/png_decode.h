// The PNGs revolve meets most (silhouettes, frames: 8-bit grey or RGB) decoded without libpng:
// the image data inflated by libdeflate (Debian libdeflate-dev, several times zlib's speed) and
// the rows unfiltered here. libpng's own unfiltering of one byte a pixel runs through memory
// byte by byte; together they took ~55 ms of CPU for 36 silhouettes of 720 x 576, this ~6.
#pragma once

#include <cstdint>
#include <optional>
#include <span>

#include <opencv2/core.hpp>

namespace revolve {

// The pixels of a PNG as DecodeVerifiedPng (base/image_verify.h) gives them, or nullopt. Decoded
// here only when the file is plainly well formed: IHDR first (8-bit grey or RGB, not interlaced,
// at most 1,000,000 pixels a side), one run of IDAT chunks holding exactly one zlib stream of
// exactly the image's rows (each with a filter type 0..4), IEND last and nothing after it, every
// chunk's CRC right, no chunk but those and the ancillary ones that change no pixel (libpng's
// skipped list in image_verify.cc; not tRNS, not eXIf); flags IMREAD_UNCHANGED or IMREAD_GRAYSCALE
// (grey) or IMREAD_COLOR. Anything else, or anything amiss, is nullopt: the caller lets libpng
// decode it or say what is wrong, as before.
std::optional<cv::Mat> DecodePlainPng(std::span<const std::uint8_t> bytes, int imread_flags);

}  // namespace revolve
