// Decoding an image file's compressed data once, to its end, with every complaint of the
// format's library (libjpeg, libpng, libtiff) taken as an error: a decoder that only warns
// ("Corrupt JPEG data: 3 extraneous bytes before marker", a bad Huffman code, a short TIFF strip)
// still fills the picture with something, and a carved model would trust it.
#pragma once

#include <cstdint>
#include <optional>
#include <span>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/image_header.h"

namespace revolve {

// Decodes `bytes` (a whole file whose header CheckImageBytes accepted as `format`) and discards
// the pixels: memory is one row or strip, plus libjpeg's coefficient buffer for a progressive
// JPEG. Every error and every warning of the library fails, with the library's words:
//   JPEG  every libjpeg warning (corrupt data, bad Huffman code, extraneous bytes, premature end,
//         an unsupported marker in the scan data);
//   PNG   every libpng warning or error (bad zlib data, too little or too much image data, a
//         damaged critical chunk); ancillary chunks that do not change the pixels (text, colour
//         profiles, times) are skipped unread, so a harmless "known incorrect sRGB profile" is
//         not refused;
//   TIFF  every libtiff warning or error, except "unknown field with tag" (private tags of
//         cameras and editors are legitimate);
//   BMP, PNM: nothing more to check (their structure is checked whole by CheckImageBytes).
// Errors: bad_input, the message naming the format and the library's complaint but not the file.
Expected<void> VerifyImageData(ImageFormat format, std::span<const std::uint8_t> bytes);

// Decodes a PNG as VerifyImageData checks it (every libpng warning fatal) and keeps the pixels,
// as cv::imdecode(bytes, imread_flags) would give them, in one pass; for the common kinds only:
// 8-bit grey, RGB or RGBA, or 1-bit grey (masks, base/png_encode.h), no transparency chunk, no
// EXIF chunk; flags IMREAD_UNCHANGED, IMREAD_COLOR, or IMREAD_GRAYSCALE of a grey file. nullopt for
// any other file or flags: the caller verifies (VerifyImageData) and decodes with OpenCV.
std::optional<Expected<cv::Mat>> DecodeVerifiedPng(std::span<const std::uint8_t> bytes,
                                                   int imread_flags);

// The same for a JPEG: decoded once, every libjpeg warning fatal, to the pixels cv::imdecode gives
// (the same library and settings: BGR or grey, the accurate DCT, fancy upsampling); flags
// IMREAD_UNCHANGED, IMREAD_COLOR or IMREAD_GRAYSCALE. nullopt for what OpenCV would do more with:
// CMYK or YCCK files, an EXIF orientation other than upright (OpenCV turns the picture) unless
// IMREAD_UNCHANGED, other flags.
std::optional<Expected<cv::Mat>> DecodeVerifiedJpeg(std::span<const std::uint8_t> bytes,
                                                    int imread_flags);

}  // namespace revolve
