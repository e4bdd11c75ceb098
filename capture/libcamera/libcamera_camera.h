// The libcamera backend (Raspberry Pi cameras and others libcamera drives). Built against
// Debian 12's libcamera 0.0.3 and only compile-tested: no Raspberry Pi 5 (PiSP) support in that
// version; on Raspberry Pi OS prefer its own libcamera or the V4L2 path (libcamerify).
// This header includes no libcamera header, so the rest of capture needs none.
#pragma once

#include <memory>
#include <string>

#include "capture/camera.h"

namespace revolve::capture {

// A camera that captures stills through libcamera: StillCapture role, RGB888 (or YUYV/MJPEG
// when that is all the pipeline offers), manual exposure / gain / colour gains when configured,
// frames chosen by their timestamp like the V4L2 backend's. Errors: no_device when there is no
// such camera, busy, io.
Expected<std::unique_ptr<Camera>> CreateLibcameraCamera(const LibcameraOptions& options);

// "libcamera: <id> (<model>)" lines, or a line saying there is none.
std::string ListLibcameraCameras();

}  // namespace revolve::capture
