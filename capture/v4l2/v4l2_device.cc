#include "capture/v4l2/v4l2_device.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include <fmt/format.h>

#include "capture/v4l2/pixel_convert.h"

namespace revolve::capture {

Error ErrnoError(int error_number, const std::string& what) {
  ErrorCode code = ErrorCode::kIo;
  switch (error_number) {
    case ENODEV:
    case ENXIO:
    case ENOENT:
    case EIO:
    case ESHUTDOWN:
      code = ErrorCode::kNoDevice;
      break;
    case EBUSY:
      code = ErrorCode::kBusy;
      break;
    case EINVAL:
    case ENOTTY:
      code = ErrorCode::kUnsupported;
      break;
    default:
      break;
  }
  return Error{code, fmt::format("{}: {}", what, std::strerror(error_number))};
}

Expected<std::unique_ptr<V4l2Device>> V4l2Device::Open(V4l2Sys& sys, const std::string& path) {
  const int fd = sys.Open(path, O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return std::unexpected(ErrnoError(-fd, "opening " + path));
  return std::unique_ptr<V4l2Device>(new V4l2Device(sys, fd, path));
}

V4l2Device::~V4l2Device() { Release(); }

void V4l2Device::Release() noexcept {
  if (streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    (void)sys_.Ioctl(fd_, VIDIOC_STREAMOFF, &type);
    streaming_ = false;
  }
  for (const Mapping& m : buffers_) {
    if (m.address != nullptr) (void)sys_.Munmap(m.address, m.length);
  }
  buffers_.clear();
  if (fd_ >= 0) {
    (void)sys_.Close(fd_);
    fd_ = -1;
  }
}

Expected<void> V4l2Device::Xioctl(unsigned long request, void* arg, const char* name) {
  const int r = sys_.Ioctl(fd_, request, arg);
  if (r < 0) return std::unexpected(ErrnoError(-r, fmt::format("{} on {}", name, path_)));
  return {};
}

Expected<DeviceCaps> V4l2Device::QueryCaps() {
  v4l2_capability cap{};
  if (auto ok = Xioctl(VIDIOC_QUERYCAP, &cap, "VIDIOC_QUERYCAP"); !ok) {
    return std::unexpected(ok.error());
  }
  const std::uint32_t caps =
      (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  DeviceCaps out;
  out.driver = reinterpret_cast<const char*>(cap.driver);
  out.card = reinterpret_cast<const char*>(cap.card);
  out.bus_info = reinterpret_cast<const char*>(cap.bus_info);
  out.video_capture = (caps & V4L2_CAP_VIDEO_CAPTURE) != 0;
  out.streaming = (caps & V4L2_CAP_STREAMING) != 0;
  return out;
}

Expected<std::vector<PixelFormatInfo>> V4l2Device::EnumerateFormats() {
  std::vector<PixelFormatInfo> formats;
  for (std::uint32_t i = 0;; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    const int r = sys_.Ioctl(fd_, VIDIOC_ENUM_FMT, &desc);
    if (r == -EINVAL) break;  // the end of the list
    if (r < 0) return std::unexpected(ErrnoError(-r, "VIDIOC_ENUM_FMT on " + path_));
    PixelFormatInfo info;
    info.fourcc = desc.pixelformat;
    info.description = reinterpret_cast<const char*>(desc.description);
    info.compressed = (desc.flags & V4L2_FMT_FLAG_COMPRESSED) != 0;
    for (std::uint32_t j = 0;; ++j) {
      v4l2_frmsizeenum size{};
      size.index = j;
      size.pixel_format = desc.pixelformat;
      if (sys_.Ioctl(fd_, VIDIOC_ENUM_FRAMESIZES, &size) < 0) break;
      if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE) break;
      info.sizes.emplace_back(static_cast<int>(size.discrete.width),
                              static_cast<int>(size.discrete.height));
    }
    formats.push_back(std::move(info));
  }
  return formats;
}

Expected<NegotiatedFormat> V4l2Device::SetFormat(std::uint32_t fourcc, int width_px,
                                                 int height_px) {
  v4l2_format format{};
  format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (width_px > 0 && height_px > 0) {
    format.fmt.pix.width = static_cast<std::uint32_t>(width_px);
    format.fmt.pix.height = static_cast<std::uint32_t>(height_px);
  } else {
    // Keep the driver's current size.
    if (auto ok = Xioctl(VIDIOC_G_FMT, &format, "VIDIOC_G_FMT"); !ok) {
      return std::unexpected(ok.error());
    }
  }
  format.fmt.pix.pixelformat = fourcc;
  format.fmt.pix.field = V4L2_FIELD_ANY;
  if (auto ok = Xioctl(VIDIOC_S_FMT, &format, "VIDIOC_S_FMT"); !ok) {
    return std::unexpected(ok.error());
  }
  // Read back: S_FMT may adjust anything.
  v4l2_format actual{};
  actual.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (auto ok = Xioctl(VIDIOC_G_FMT, &actual, "VIDIOC_G_FMT"); !ok) {
    return std::unexpected(ok.error());
  }
  NegotiatedFormat out;
  out.fourcc = actual.fmt.pix.pixelformat;
  out.width_px = static_cast<int>(actual.fmt.pix.width);
  out.height_px = static_cast<int>(actual.fmt.pix.height);
  out.bytes_per_line = static_cast<int>(actual.fmt.pix.bytesperline);
  out.size_image = actual.fmt.pix.sizeimage;
  return out;
}

Expected<double> V4l2Device::SetFrameRate(double fps) {
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  parm.parm.capture.timeperframe.numerator = 1000;
  parm.parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(fps * 1000.0 + 0.5);
  if (auto ok = Xioctl(VIDIOC_S_PARM, &parm, "VIDIOC_S_PARM"); !ok) {
    return std::unexpected(ok.error());
  }
  const auto& t = parm.parm.capture.timeperframe;
  return t.denominator > 0 ? static_cast<double>(t.numerator) / t.denominator : 0.0;
}

double V4l2Device::FramePeriodS() {
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (sys_.Ioctl(fd_, VIDIOC_G_PARM, &parm) < 0) return 0.0;
  const auto& t = parm.parm.capture.timeperframe;
  return t.denominator > 0 ? static_cast<double>(t.numerator) / t.denominator : 0.0;
}

ControlInfo V4l2Device::QueryControl(std::uint32_t id) {
  v4l2_queryctrl query{};
  query.id = id;
  ControlInfo info;
  if (sys_.Ioctl(fd_, VIDIOC_QUERYCTRL, &query) < 0) return info;
  info.exists = (query.flags & V4L2_CTRL_FLAG_DISABLED) == 0;
  info.inactive = (query.flags & V4L2_CTRL_FLAG_INACTIVE) != 0;
  info.read_only = (query.flags & V4L2_CTRL_FLAG_READ_ONLY) != 0;
  info.minimum = query.minimum;
  info.maximum = query.maximum;
  info.step = query.step > 0 ? query.step : 1;
  info.default_value = query.default_value;
  return info;
}

Expected<void> V4l2Device::SetControl(std::uint32_t id, std::int32_t value) {
  v4l2_control control{id, value};
  return Xioctl(VIDIOC_S_CTRL, &control, "VIDIOC_S_CTRL");
}

Expected<std::int32_t> V4l2Device::GetControl(std::uint32_t id) {
  v4l2_control control{id, 0};
  if (auto ok = Xioctl(VIDIOC_G_CTRL, &control, "VIDIOC_G_CTRL"); !ok) {
    return std::unexpected(ok.error());
  }
  return control.value;
}

Expected<void> V4l2Device::StartStreaming(int buffer_count) {
  v4l2_requestbuffers request{};
  request.count = static_cast<std::uint32_t>(buffer_count);
  request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  request.memory = V4L2_MEMORY_MMAP;
  if (auto ok = Xioctl(VIDIOC_REQBUFS, &request, "VIDIOC_REQBUFS"); !ok) return ok;
  if (request.count < 2) {
    return MakeError(ErrorCode::kIo,
                     fmt::format("{}: the driver granted {} buffers, 2 at least are needed", path_,
                                 request.count));
  }
  for (std::uint32_t i = 0; i < request.count; ++i) {
    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    buffer.index = i;
    if (auto ok = Xioctl(VIDIOC_QUERYBUF, &buffer, "VIDIOC_QUERYBUF"); !ok) return ok;
    int error = 0;
    void* address = sys_.Mmap(buffer.length, fd_, buffer.m.offset, &error);
    if (address == nullptr) return std::unexpected(ErrnoError(error, "mmap on " + path_));
    buffers_.push_back({address, buffer.length});
  }
  for (int i = 0; i < static_cast<int>(buffers_.size()); ++i) {
    if (auto ok = Requeue(i); !ok) return ok;
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (auto ok = Xioctl(VIDIOC_STREAMON, &type, "VIDIOC_STREAMON"); !ok) return ok;
  streaming_ = true;
  return {};
}

Expected<WaitResult> V4l2Device::Wait(int timeout_ms) {
  short revents = 0;
  const int r = sys_.Poll(fd_, POLLIN, timeout_ms, &revents);
  if (r < 0) return std::unexpected(ErrnoError(-r, "poll on " + path_));
  if (r == 0) return WaitResult::kTimeout;
  if (revents & (POLLERR | POLLHUP | POLLNVAL)) {
    return MakeError(ErrorCode::kNoDevice,
                     fmt::format("{}: the device reported an error (unplugged?)", path_));
  }
  return WaitResult::kReady;
}

Expected<std::optional<DequeuedBuffer>> V4l2Device::Dequeue() {
  v4l2_buffer buffer{};
  buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buffer.memory = V4L2_MEMORY_MMAP;
  const int r = sys_.Ioctl(fd_, VIDIOC_DQBUF, &buffer);
  if (r == -EAGAIN) return std::optional<DequeuedBuffer>();
  if (r < 0) return std::unexpected(ErrnoError(-r, "VIDIOC_DQBUF on " + path_));
  if (buffer.index >= buffers_.size()) {
    return MakeError(ErrorCode::kProtocol, fmt::format("{}: the driver returned buffer {} of {}",
                                                       path_, buffer.index, buffers_.size()));
  }
  DequeuedBuffer out;
  out.index = static_cast<int>(buffer.index);
  const Mapping& m = buffers_[buffer.index];
  out.data = std::span<const std::uint8_t>(static_cast<const std::uint8_t*>(m.address),
                                           std::min<std::size_t>(buffer.bytesused, m.length));
  out.flags = buffer.flags;
  out.sequence = buffer.sequence;
  out.timestamp = std::chrono::seconds(buffer.timestamp.tv_sec) +
                  std::chrono::microseconds(buffer.timestamp.tv_usec);
  return std::optional<DequeuedBuffer>(out);
}

Expected<void> V4l2Device::Requeue(int index) {
  v4l2_buffer buffer{};
  buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buffer.memory = V4L2_MEMORY_MMAP;
  buffer.index = static_cast<std::uint32_t>(index);
  return Xioctl(VIDIOC_QBUF, &buffer, "VIDIOC_QBUF");
}

std::vector<DeviceListing> ListV4l2Devices(V4l2Sys& sys) {
  std::vector<std::string> paths;
  std::error_code ec;
  for (const char* dir : {"/dev/v4l/by-id", "/dev/v4l/by-path"}) {
    std::vector<std::string> found;
    for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
      found.push_back(entry.path().string());
    }
    std::sort(found.begin(), found.end());
    paths.insert(paths.end(), found.begin(), found.end());
  }
  std::vector<std::string> nodes;
  for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("video", 0) == 0) nodes.push_back(entry.path().string());
  }
  std::sort(nodes.begin(), nodes.end());
  paths.insert(paths.end(), nodes.begin(), nodes.end());

  std::vector<DeviceListing> out;
  for (const std::string& path : paths) {
    DeviceListing listing;
    listing.path = path;
    const auto target = std::filesystem::canonical(path, ec);
    if (!ec && target.string() != path) listing.resolves_to = target.string();
    auto device = V4l2Device::Open(sys, path);
    if (!device) {
      listing.error = device.error().message;
      out.push_back(listing);
      continue;
    }
    auto caps = (*device)->QueryCaps();
    if (!caps) {
      listing.error = caps.error().message;
    } else {
      listing.caps = *caps;
      if (caps->video_capture) {
        auto formats = (*device)->EnumerateFormats();
        if (formats) listing.formats = std::move(*formats);
      }
    }
    out.push_back(std::move(listing));
  }
  return out;
}

}  // namespace revolve::capture
