// The interface between revolve and its image-codec plugin (librevolve_imgcodecs.so, built from
// base/image_codecs_plugin.cc): a table of plain functions over OpenCV types, looked up by name
// with dlsym. Internal to base/image_codecs.cc; both sides are built together, so the layout is
// checked by `version` only against a stale plugin left from another build.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace revolve::image_codecs_plugin {

inline constexpr int kVersion = 1;
inline constexpr const char* kEntryPoint = "revolve_image_codecs_v1";

// Each function returns true on success; on failure it fills `error` with OpenCV's words. None
// throws.
struct Table {
  int version = kVersion;
  // cv::imdecode(bytes, flags); an empty image (OpenCV refused the data) is a failure.
  bool (*decode)(const std::uint8_t* bytes, std::size_t size, int imread_flags, cv::Mat* image,
                 std::string* error) = nullptr;
  // cv::imencode(extension, image, bytes, params); `extension` with its dot (".png").
  bool (*encode)(const char* extension, const cv::Mat* image, const std::vector<int>* params,
                 std::vector<std::uint8_t>* bytes, std::string* error) = nullptr;
};

}  // namespace revolve::image_codecs_plugin
