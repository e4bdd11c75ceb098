// The interface between revolve and its libcamera plugin (librevolve_libcamera.so, built from
// capture/libcamera/libcamera_camera.cc): linking libcamera loaded it and its libraries
// (lttng-ust, which starts two threads and reads the sections of every library loaded, gnutls,
// udev, ...) at every start of every revolve command, ~12 ms of a ~24 ms start; the plugin is
// loaded the first time a libcamera camera is listed or opened (libcamera_camera.h). Internal to
// capture; both sides are built together: `version` only guards against a stale plugin. The
// camera is revolve's Camera; its pixels are converted by revolve's ConvertToBgr, passed in (the
// plugin holds no copy of revolve's libraries).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "capture/camera.h"

namespace revolve::capture::libcamera_plugin {

inline constexpr int kVersion = 1;
inline constexpr const char* kEntryPoint = "revolve_libcamera_plugin_v1";

// capture/v4l2/pixel_convert.h's ConvertToBgr.
using ConvertFn = Expected<cv::Mat> (*)(std::span<const std::uint8_t> data, std::uint32_t fourcc,
                                        int width, int height, int stride);

struct Table {
  int version = kVersion;
  // CreateLibcameraCamera's contract, the frames converted with `convert`.
  Expected<std::unique_ptr<Camera>> (*create)(const LibcameraOptions& options,
                                              ConvertFn convert) = nullptr;
  // ListLibcameraCameras's.
  std::string (*list)() = nullptr;
};

}  // namespace revolve::capture::libcamera_plugin
