// 8-bit images as PNG, encoded by revolve itself over zlib on every core (oneTBB): the texture
// atlas, the masks and the frames of a scan, without loading OpenCV's codecs
// (base/image_codecs.h).
//
// The rows are cut into fixed bands, each filtered (Paeth) and deflated on its own (level 1,
// run-length matching), as pigz does; the bytes depend only on the image, never on the number of
// threads. Larger than libpng's best by a few per cent, several times faster.
#pragma once

#include <filesystem>
#include <string>

#include <opencv2/core.hpp>

#include "base/error.h"

namespace revolve {

// An 8-bit BGR or grey image as PNG bytes (RGB or grey). A grey image of only 0 and 255 (a
// mask) is written one bit a pixel: every PNG reader gives back 0 and 255 (libpng expands
// 1-bit grey to 8 bits by scaling), and it is an eighth of the bytes to filter and deflate.
// Errors: internal for another kind of image (depth, channels, empty) or when zlib fails.
Expected<std::string> EncodePng(const cv::Mat& image);

// EncodePng, written atomically (base/atomic_file.h). Errors name the file.
Expected<void> WritePngFile(const std::filesystem::path& path, const cv::Mat& image);

}  // namespace revolve
