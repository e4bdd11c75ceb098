// OpenCV's image codecs (imgcodecs), loaded the first time an image needs them.
//
// opencv_imgcodecs pulls in about 140 shared libraries (GDAL, GDCM, codecs of every kind): linked
// into revolve, loading them took ~65 ms and 32 MB at every start of every command. revolve
// decodes the common kinds itself (base/image_verify.h: PNG and JPEG) and encodes PNG itself
// (base/png_encode.h); everything else (BMP, TIFF, PNM, WebP…, JPEG encoding, odd
// PNGs and JPEGs) goes through these functions, which load the plugin librevolve_imgcodecs.so
// (base/image_codecs_plugin.cc) once, thread-safely.
//
// The plugin is looked for where `cmake --install` puts it relative to the running executable
// (<prefix>/<libdir>/revolve/), then in the build tree it was built in. When neither loads, every
// call fails with an io error naming the paths tried and what to do.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>  // the IMREAD_* and IMWRITE_* constants (header only)

#include "base/error.h"

namespace revolve {

// cv::imdecode(bytes, imread_flags). Errors: bad_input when OpenCV refuses the data (the message
// names neither file nor format: callers add them), io when the plugin cannot be loaded.
Expected<cv::Mat> DecodeImage(std::span<const std::uint8_t> bytes, int imread_flags);

// cv::imencode(extension, image, params): the file's bytes. `extension` with its dot (".jpg").
// Errors: bad_input when OpenCV refuses (unknown extension, an image the format cannot hold),
// io when the plugin cannot be loaded.
Expected<std::vector<std::uint8_t>> EncodeImage(std::string_view extension, const cv::Mat& image,
                                                const std::vector<int>& params = {});

// EncodeImage by `path`'s extension, then written atomically (base/atomic_file.h): an existing
// file is replaced whole or left as it was. Errors name the file.
Expected<void> WriteImageFile(const std::filesystem::path& path, const cv::Mat& image,
                              const std::vector<int>& params = {});

// Whether the plugin is loaded in this process (for tests: the common kinds never load it).
bool ImageCodecsLoaded();

}  // namespace revolve
