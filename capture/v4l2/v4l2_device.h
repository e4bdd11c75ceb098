// One open V4L2 capture device, over the V4l2Sys seam: capabilities, formats, controls and
// mmap streaming. Owns its file descriptor and mappings (RAII): destruction stops streaming,
// unmaps every buffer and closes the descriptor, whatever state the device is in (a device that
// was unplugged fails those calls; they are still made, and their errors ignored).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "base/error.h"
#include "capture/v4l2/v4l2_sys.h"

namespace revolve::capture {

// Maps an errno of an open/ioctl/poll to an Error: ENODEV, ENXIO, ENOENT, EIO, ESHUTDOWN ->
// no_device; EBUSY -> busy; EACCES, EPERM -> io; EINVAL, ENOTTY -> unsupported; else io.
Error ErrnoError(int error_number, const std::string& what);

struct DeviceCaps {
  std::string driver;
  std::string card;
  std::string bus_info;
  bool video_capture = false;
  bool streaming = false;
};

struct PixelFormatInfo {
  std::uint32_t fourcc = 0;
  std::string description;
  bool compressed = false;
  std::vector<std::pair<int, int>> sizes;  // discrete sizes; empty for stepwise/continuous
};

struct NegotiatedFormat {
  std::uint32_t fourcc = 0;
  int width_px = 0;
  int height_px = 0;
  int bytes_per_line = 0;
  std::size_t size_image = 0;
};

struct ControlInfo {
  bool exists = false;
  bool inactive = false;
  bool read_only = false;
  std::int64_t minimum = 0;
  std::int64_t maximum = 0;
  std::int64_t step = 1;
  std::int64_t default_value = 0;
};

// A dequeued buffer, valid until Requeue(index).
struct DequeuedBuffer {
  int index = -1;
  std::span<const std::uint8_t> data;  // bytesused bytes of the mapping
  std::uint32_t flags = 0;             // V4L2_BUF_FLAG_*
  std::uint32_t sequence = 0;
  std::chrono::nanoseconds timestamp{0};  // as the driver stamped it
};

enum class WaitResult { kReady, kTimeout };

class V4l2Device {
 public:
  // Opens `path` O_RDWR | O_NONBLOCK | O_CLOEXEC. Errors: no_device (not there), busy, io.
  static Expected<std::unique_ptr<V4l2Device>> Open(V4l2Sys& sys, const std::string& path);
  ~V4l2Device();
  V4l2Device(const V4l2Device&) = delete;
  V4l2Device& operator=(const V4l2Device&) = delete;

  const std::string& path() const { return path_; }

  Expected<DeviceCaps> QueryCaps();
  // VIDIOC_ENUM_FMT and VIDIOC_ENUM_FRAMESIZES for single-planar capture.
  Expected<std::vector<PixelFormatInfo>> EnumerateFormats();
  // VIDIOC_S_FMT then VIDIOC_G_FMT: what the driver really set (it may differ).
  Expected<NegotiatedFormat> SetFormat(std::uint32_t fourcc, int width_px, int height_px);
  // VIDIOC_S_PARM with 1/fps; returns the frame period the driver chose (0 when unknown).
  Expected<double> SetFrameRate(double fps);
  // The current frame period in seconds (VIDIOC_G_PARM), 0 when unknown.
  double FramePeriodS();

  ControlInfo QueryControl(std::uint32_t id);
  Expected<void> SetControl(std::uint32_t id, std::int32_t value);
  Expected<std::int32_t> GetControl(std::uint32_t id);

  // REQBUFS(count, MMAP), QUERYBUF + mmap each, QBUF all, STREAMON. Errors as ErrnoError.
  Expected<void> StartStreaming(int buffer_count);
  bool streaming() const { return streaming_; }
  int buffer_count() const { return static_cast<int>(buffers_.size()); }

  // poll() for POLLIN up to timeout_ms. Errors: no_device on POLLERR/POLLHUP/POLLNVAL.
  Expected<WaitResult> Wait(int timeout_ms);
  // VIDIOC_DQBUF; nullopt on EAGAIN (nothing ready).
  Expected<std::optional<DequeuedBuffer>> Dequeue();
  Expected<void> Requeue(int index);

 private:
  V4l2Device(V4l2Sys& sys, int fd, std::string path) : sys_(sys), fd_(fd), path_(std::move(path)) {}
  Expected<void> Xioctl(unsigned long request, void* arg, const char* name);
  void Release() noexcept;

  struct Mapping {
    void* address = nullptr;
    std::size_t length = 0;
  };
  V4l2Sys& sys_;
  int fd_;
  std::string path_;
  std::vector<Mapping> buffers_;
  bool streaming_ = false;
};

// Device nodes worth offering to a user: /dev/v4l/by-id/* and /dev/v4l/by-path/* (stable
// names) then /dev/video*, each with what it is. Nodes that cannot capture (UVC metadata) are
// marked.
struct DeviceListing {
  std::string path;
  std::string resolves_to;  // the /dev/videoN a by-id link points at
  std::optional<DeviceCaps> caps;
  std::vector<PixelFormatInfo> formats;
  std::string error;  // why the node could not be queried
};
std::vector<DeviceListing> ListV4l2Devices(V4l2Sys& sys);

}  // namespace revolve::capture
