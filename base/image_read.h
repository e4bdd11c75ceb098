// Reading one image file with its header checked first (base/image_header.h): a file too large,
// cut short, damaged or a dangling symbolic link is an error naming it, never a decoder's
// allocation of whatever the header claims nor a picture half filled with grey.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "base/error.h"
#include "base/image_header.h"

namespace revolve {

// The default ceiling on an image's size: 100 megapixels (a generous multiple of any camera the
// station drives; about 300 MB decoded as BGR).
inline constexpr std::int64_t kDefaultMaxImagePixels = 100'000'000;

struct ImageReadOptions {
  int imread_flags = cv::IMREAD_UNCHANGED;  // as cv::imread's (IMREAD_COLOR, IMREAD_GRAYSCALE)
  std::int64_t max_pixels = kDefaultMaxImagePixels;
  // The size every image of a set shares, when known: a file of another size is refused from
  // its header, before it is decoded. It is the size as decoded: turned when the picture is.
  std::optional<cv::Size> expected_size;
  // With IMREAD_UNCHANGED, which leaves a JPEG's pixels as stored: turned as its EXIF orientation
  // says (TurnUpright), as a viewer shows it. The other flags turn it already, as cv::imread
  // does.
  bool upright = false;
};

// The size of the picture as ReadImageFile decodes `header`'s file with `options`: the stored
// size, or its transpose when the picture is turned a quarter.
cv::Size DecodedSize(const ImageHeader& header, const ImageReadOptions& options);

// Turns or mirrors `image` (as stored) as EXIF `orientation` (ImageHeader::orientation) says, the
// same pixels as cv::imread's default gives; 1 and values outside 2..8 leave it as it is.
void TurnUpright(int orientation, cv::Mat* image);

// The header of the image file at `path` (the whole file is read and checked, none of it
// decoded). Errors name the file: not_found (no file; a dangling symbolic link says so and names
// its target), bad_input (not a regular file, empty, cut short, damaged, larger than
// max_pixels allows, unknown format), io (unreadable).
Expected<ImageHeader> ReadImageHeader(const std::filesystem::path& path,
                                      std::int64_t max_pixels = kDefaultMaxImagePixels);

// Reads and decodes `path` after ReadImageHeader's checks and the expected size; the decoded
// image has DecodedSize. Errors as ReadImageHeader, plus bad_input naming the file when
// the size differs from `expected_size`, or the decoder refuses the data or only warns about it
// (base/image_verify.h: every libjpeg, libpng and libtiff warning is an error). Peak memory: the
// file's bytes plus one decoded image.
Expected<cv::Mat> ReadImageFile(const std::filesystem::path& path,
                                const ImageReadOptions& options = {});

}  // namespace revolve
