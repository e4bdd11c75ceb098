#include "fake_v4l2.h"

#include <linux/videodev2.h>
#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <thread>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "capture/v4l2/pixel_convert.h"

namespace revolve::capture::testing {
namespace {

constexpr std::int64_t kOffsetStride = std::int64_t{1} << 24;

int BytesPerLine(std::uint32_t fourcc, int width) {
  if (fourcc == kFourCcYuyv || fourcc == kFourCcUyvy) return 2 * width;
  if (fourcc == kFourCcGrey) return width;
  if (fourcc == kFourCcRgb24 || fourcc == kFourCcBgr24) return 3 * width;
  return 0;
}

}  // namespace

FakeV4l2::FakeV4l2(Options options) : options_(std::move(options)) {
  if (!options_.formats.empty()) {
    fourcc_ = options_.formats[0].fourcc;
    width_ = options_.formats[0].sizes.at(0).first;
    height_ = options_.formats[0].sizes.at(0).second;
  }
}

void FakeV4l2::AddUvcControls() {
  std::lock_guard lock(mutex_);
  controls_[V4L2_CID_EXPOSURE_AUTO] = {0, 3, 3, 0, 0, 0};
  controls_[V4L2_CID_EXPOSURE_ABSOLUTE] = {3, 2047, 250, V4L2_CID_EXPOSURE_AUTO, 1, 157};
  controls_[V4L2_CID_EXPOSURE_AUTO_PRIORITY] = {0, 1, 1, 0, 0, 0};
  controls_[V4L2_CID_AUTOGAIN] = {0, 1, 1, 0, 0, 0};
  controls_[V4L2_CID_GAIN] = {0, 255, 64, V4L2_CID_AUTOGAIN, 0, 80};
  controls_[V4L2_CID_AUTO_WHITE_BALANCE] = {0, 1, 1, 0, 0, 0};
  controls_[V4L2_CID_WHITE_BALANCE_TEMPERATURE] = {2800, 6500, 4600, V4L2_CID_AUTO_WHITE_BALANCE,
                                                   0,    5100};
  controls_[V4L2_CID_FOCUS_AUTO] = {0, 1, 1, 0, 0, 0};
  controls_[V4L2_CID_FOCUS_ABSOLUTE] = {0, 250, 0, V4L2_CID_FOCUS_AUTO, 0, 30};
}

void FakeV4l2::Unplug() {
  std::lock_guard lock(mutex_);
  unplugged_ = true;
  ++generation_;
  log_.push_back("UNPLUG");
}

void FakeV4l2::Replug() {
  std::lock_guard lock(mutex_);
  unplugged_ = false;
  log_.push_back("REPLUG");
}

void FakeV4l2::SetProducing(bool producing) {
  std::lock_guard lock(mutex_);
  if (producing && !producing_) {
    // Resume on the clock from now: no burst of missed frames.
    const double elapsed = std::chrono::duration<double>(Clock::now() - t0_).count();
    next_frame_ = static_cast<std::uint64_t>(std::ceil(elapsed / options_.frame_period_s));
  }
  producing_ = producing;
}

void FakeV4l2::FlagNextFramesAsErrors(int count) {
  std::lock_guard lock(mutex_);
  error_frames_ = count;
}

void FakeV4l2::TruncateNextJpegFrames(int count) {
  std::lock_guard lock(mutex_);
  truncated_frames_ = count;
}

int FakeV4l2::open_fds() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(fds_.size());
}
int FakeV4l2::mapped_buffers() const {
  std::lock_guard lock(mutex_);
  return mapped_;
}
int FakeV4l2::opens() const {
  std::lock_guard lock(mutex_);
  return opens_;
}
std::vector<std::string> FakeV4l2::log() const {
  std::lock_guard lock(mutex_);
  return log_;
}
std::int32_t FakeV4l2::control(std::uint32_t id) const {
  std::lock_guard lock(mutex_);
  auto it = controls_.find(id);
  return it == controls_.end() ? -1 : it->second.value;
}
std::uint64_t FakeV4l2::frames_produced() const {
  std::lock_guard lock(mutex_);
  return produced_;
}

bool FakeV4l2::Alive(int fd) const {
  auto it = fds_.find(fd);
  return it != fds_.end() && it->second == generation_ && !unplugged_;
}

int FakeV4l2::Open(const std::string& path, int /*flags*/) {
  std::lock_guard lock(mutex_);
  if (path != options_.path || unplugged_) return -ENOENT;
  ++opens_;
  const int fd = next_fd_++;
  fds_[fd] = generation_;
  return fd;
}

int FakeV4l2::Close(int fd) {
  std::lock_guard lock(mutex_);
  if (fds_.erase(fd) == 0) return -EBADF;
  if (fds_.empty()) {
    StopStreaming();
    buffers_.clear();
  }
  return 0;
}

void* FakeV4l2::Mmap(std::size_t length, int fd, std::int64_t offset, int* error) {
  std::lock_guard lock(mutex_);
  const std::size_t index = static_cast<std::size_t>(offset / kOffsetStride);
  if (!Alive(fd)) {
    *error = ENODEV;
    return nullptr;
  }
  if (index >= buffers_.size() || length > buffers_[index].data.size()) {
    *error = EINVAL;
    return nullptr;
  }
  ++mapped_;
  return buffers_[index].data.data();
}

int FakeV4l2::Munmap(void* /*address*/, std::size_t /*length*/) {
  std::lock_guard lock(mutex_);
  --mapped_;
  return 0;
}

double FakeV4l2::ExposureS() const {
  auto it = controls_.find(V4L2_CID_EXPOSURE_ABSOLUTE);
  return it == controls_.end() ? 0.0 : it->second.value * 100e-6;
}

FakeV4l2::Clock::time_point FakeV4l2::DeliveryTime(std::uint64_t n) const {
  // Frame n's exposure starts at t0 + n P; it is read out and delivered one period later.
  return t0_ + std::chrono::duration_cast<Clock::duration>(
                   std::chrono::duration<double>((n + 1) * options_.frame_period_s));
}

void FakeV4l2::Fill(Buffer& buffer, std::uint64_t n) {
  const auto level = static_cast<std::uint8_t>(16 + (n * 7) % 200);
  if (fourcc_ == kFourCcMjpg || fourcc_ == kFourCcJpeg) {
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", cv::Mat(height_, width_, CV_8UC3, cv::Scalar::all(level)), jpeg);
    if (truncated_frames_ > 0) {
      --truncated_frames_;
      jpeg.resize(jpeg.size() / 2);
    }
    std::copy(jpeg.begin(), jpeg.end(), buffer.data.begin());
    buffer.bytes_used = jpeg.size();
    return;
  }
  if (fourcc_ == kFourCcYuyv || fourcc_ == kFourCcUyvy) {
    for (std::size_t i = 0; i + 1 < buffer.data.size(); i += 2) {
      const bool luma_first = fourcc_ == kFourCcYuyv;
      buffer.data[i] = luma_first ? level : 128;
      buffer.data[i + 1] = luma_first ? 128 : level;
    }
  } else {
    std::fill(buffer.data.begin(), buffer.data.end(), level);
  }
  buffer.bytes_used = buffer.data.size();
}

void FakeV4l2::Advance(Clock::time_point now) {
  if (!streaming_ || !producing_) return;
  while (DeliveryTime(next_frame_) <= now) {
    const std::uint64_t n = next_frame_++;
    if (queued_.empty()) continue;  // no buffer: the frame is lost, as in a real driver
    const int index = queued_.front();
    queued_.pop_front();
    Buffer& b = buffers_[index];
    Fill(b, n);
    b.sequence = static_cast<std::uint32_t>(n);
    b.flags = 0;
    const auto start = t0_ + std::chrono::duration_cast<Clock::duration>(
                                 std::chrono::duration<double>(n * options_.frame_period_s));
    switch (options_.stamp) {
      case Stamp::kStartOfExposure:
        b.flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
        b.timestamp = start.time_since_epoch();
        break;
      case Stamp::kEndOfFrame:
        b.flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_TSTAMP_SRC_EOF;
        b.timestamp =
            (start + std::chrono::duration_cast<Clock::duration>(
                         std::chrono::duration<double>(options_.frame_period_s + ExposureS())))
                .time_since_epoch();
        break;
      case Stamp::kUnknown:
        b.flags = V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN;
        b.timestamp = std::chrono::nanoseconds(0);
        break;
    }
    if (error_frames_ > 0) {
      --error_frames_;
      b.flags |= V4L2_BUF_FLAG_ERROR;
    }
    b.state = Buffer::State::kDone;
    done_.push_back(index);
    ++produced_;
  }
}

void FakeV4l2::StopStreaming() {
  streaming_ = false;
  queued_.clear();
  done_.clear();
  for (Buffer& b : buffers_) b.state = Buffer::State::kUser;
}

int FakeV4l2::Poll(int fd, short /*events*/, int timeout_ms, short* revents) {
  const auto deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  std::unique_lock lock(mutex_);
  while (true) {
    if (!Alive(fd)) {
      *revents = POLLERR;
      return 1;
    }
    const auto now = Clock::now();
    Advance(now);
    if (!done_.empty()) {
      *revents = POLLIN;
      return 1;
    }
    if (now >= deadline) {
      *revents = 0;
      return 0;
    }
    auto wake = deadline;
    if (streaming_ && producing_) wake = std::min(wake, DeliveryTime(next_frame_));
    lock.unlock();
    std::this_thread::sleep_until(std::min(wake, now + std::chrono::milliseconds(5)));
    lock.lock();
  }
}

int FakeV4l2::Ioctl(int fd, unsigned long request, void* arg) {
  std::lock_guard lock(mutex_);
  if (!Alive(fd)) return -ENODEV;
  return DoIoctl(request, arg);
}

int FakeV4l2::DoIoctl(unsigned long request, void* arg) {
  switch (request) {
    case VIDIOC_QUERYCAP: {
      auto* cap = static_cast<v4l2_capability*>(arg);
      std::memset(cap, 0, sizeof(*cap));
      std::strncpy(reinterpret_cast<char*>(cap->driver), "fake", sizeof(cap->driver) - 1);
      std::strncpy(reinterpret_cast<char*>(cap->card), "Fake Camera", sizeof(cap->card) - 1);
      std::strncpy(reinterpret_cast<char*>(cap->bus_info), "fake:0", sizeof(cap->bus_info) - 1);
      cap->device_caps = options_.capture_device ? (V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING)
                                                 : V4L2_CAP_META_CAPTURE;
      cap->capabilities = cap->device_caps | V4L2_CAP_DEVICE_CAPS;
      return 0;
    }
    case VIDIOC_ENUM_FMT: {
      auto* desc = static_cast<v4l2_fmtdesc*>(arg);
      if (desc->index >= options_.formats.size()) return -EINVAL;
      const std::uint32_t fourcc = options_.formats[desc->index].fourcc;
      desc->pixelformat = fourcc;
      desc->flags = fourcc == kFourCcMjpg ? V4L2_FMT_FLAG_COMPRESSED : 0;
      std::strncpy(reinterpret_cast<char*>(desc->description), FourCcToString(fourcc).c_str(),
                   sizeof(desc->description) - 1);
      return 0;
    }
    case VIDIOC_ENUM_FRAMESIZES: {
      auto* size = static_cast<v4l2_frmsizeenum*>(arg);
      for (const Format& f : options_.formats) {
        if (f.fourcc != size->pixel_format) continue;
        if (size->index >= f.sizes.size()) return -EINVAL;
        size->type = V4L2_FRMSIZE_TYPE_DISCRETE;
        size->discrete.width = static_cast<std::uint32_t>(f.sizes[size->index].first);
        size->discrete.height = static_cast<std::uint32_t>(f.sizes[size->index].second);
        return 0;
      }
      return -EINVAL;
    }
    case VIDIOC_S_FMT:
    case VIDIOC_G_FMT: {
      auto* format = static_cast<v4l2_format*>(arg);
      if (format->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return -EINVAL;
      if (request == VIDIOC_S_FMT) {
        if (!buffers_.empty()) return -EBUSY;
        const Format* chosen = &options_.formats[0];
        for (const Format& f : options_.formats) {
          if (f.fourcc == format->fmt.pix.pixelformat && f.fourcc != options_.substitute_fourcc) {
            chosen = &f;
          }
        }
        // The nearest offered size.
        auto best = chosen->sizes[0];
        const long w = format->fmt.pix.width, h = format->fmt.pix.height;
        for (const auto& s : chosen->sizes) {
          if (std::abs(s.first - w) + std::abs(s.second - h) <
              std::abs(best.first - w) + std::abs(best.second - h)) {
            best = s;
          }
        }
        fourcc_ = chosen->fourcc;
        width_ = best.first;
        height_ = best.second;
        log_.push_back(fmt::format("S_FMT {} {}x{}", FourCcToString(fourcc_), width_, height_));
      }
      format->fmt.pix.pixelformat = fourcc_;
      format->fmt.pix.width = static_cast<std::uint32_t>(width_);
      format->fmt.pix.height = static_cast<std::uint32_t>(height_);
      format->fmt.pix.field = V4L2_FIELD_NONE;
      format->fmt.pix.bytesperline = static_cast<std::uint32_t>(BytesPerLine(fourcc_, width_));
      const int bpl = BytesPerLine(fourcc_, width_);
      format->fmt.pix.sizeimage =
          static_cast<std::uint32_t>(bpl > 0 ? bpl * height_ : width_ * height_ * 3 + 4096);
      return 0;
    }
    case VIDIOC_S_PARM:
    case VIDIOC_G_PARM: {
      auto* parm = static_cast<v4l2_streamparm*>(arg);
      auto& t = parm->parm.capture.timeperframe;
      if (request == VIDIOC_S_PARM && t.denominator > 0) {
        options_.frame_period_s = static_cast<double>(t.numerator) / t.denominator;
      }
      t.numerator = static_cast<std::uint32_t>(std::lround(options_.frame_period_s * 1e6));
      t.denominator = 1000000;
      return 0;
    }
    case VIDIOC_QUERYCTRL: {
      auto* query = static_cast<v4l2_queryctrl*>(arg);
      auto it = controls_.find(query->id);
      if (it == controls_.end()) return -EINVAL;
      const Control& c = it->second;
      query->minimum = c.minimum;
      query->maximum = c.maximum;
      query->step = 1;
      query->default_value = c.value;
      query->flags = 0;
      if (c.auto_id != 0 && controls_[c.auto_id].value != c.auto_manual) {
        query->flags |= V4L2_CTRL_FLAG_INACTIVE;
      }
      return 0;
    }
    case VIDIOC_G_CTRL:
    case VIDIOC_S_CTRL: {
      auto* control = static_cast<v4l2_control*>(arg);
      auto it = controls_.find(control->id);
      if (it == controls_.end()) return -EINVAL;
      Control& c = it->second;
      const bool automatic = c.auto_id != 0 && controls_[c.auto_id].value != c.auto_manual;
      if (request == VIDIOC_G_CTRL) {
        control->value = automatic ? c.auto_value : c.value;
        return 0;
      }
      if (automatic) {
        log_.push_back(fmt::format("S_CTRL {} {} refused (auto)", control->id, control->value));
        return -EACCES;
      }
      if (control->value < c.minimum || control->value > c.maximum) return -ERANGE;
      c.value = control->value;
      log_.push_back(fmt::format("S_CTRL {} {}", control->id, control->value));
      return 0;
    }
    case VIDIOC_REQBUFS: {
      auto* request_buffers = static_cast<v4l2_requestbuffers*>(arg);
      if (streaming_) return -EBUSY;
      buffers_.clear();
      v4l2_format format{};
      format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      DoIoctl(VIDIOC_G_FMT, &format);
      request_buffers->count = std::min<std::uint32_t>(request_buffers->count, 8);
      buffers_.resize(request_buffers->count);
      for (Buffer& b : buffers_) b.data.assign(format.fmt.pix.sizeimage, 0);
      log_.push_back(fmt::format("REQBUFS {}", request_buffers->count));
      return 0;
    }
    case VIDIOC_QUERYBUF: {
      auto* buffer = static_cast<v4l2_buffer*>(arg);
      if (buffer->index >= buffers_.size()) return -EINVAL;
      buffer->length = static_cast<std::uint32_t>(buffers_[buffer->index].data.size());
      buffer->m.offset = static_cast<std::uint32_t>(buffer->index * kOffsetStride);
      return 0;
    }
    case VIDIOC_QBUF: {
      auto* buffer = static_cast<v4l2_buffer*>(arg);
      if (buffer->index >= buffers_.size()) return -EINVAL;
      Buffer& b = buffers_[buffer->index];
      if (b.state != Buffer::State::kUser) return -EINVAL;
      b.state = Buffer::State::kQueued;
      queued_.push_back(static_cast<int>(buffer->index));
      return 0;
    }
    case VIDIOC_DQBUF: {
      auto* buffer = static_cast<v4l2_buffer*>(arg);
      if (!streaming_) return -EINVAL;
      Advance(Clock::now());
      if (done_.empty()) return -EAGAIN;
      const int index = done_.front();
      done_.pop_front();
      Buffer& b = buffers_[index];
      b.state = Buffer::State::kUser;
      buffer->index = static_cast<std::uint32_t>(index);
      buffer->bytesused = static_cast<std::uint32_t>(b.bytes_used);
      buffer->flags = b.flags;
      buffer->sequence = b.sequence;
      const auto us = std::chrono::duration_cast<std::chrono::microseconds>(b.timestamp).count();
      buffer->timestamp.tv_sec = us / 1000000;
      buffer->timestamp.tv_usec = us % 1000000;
      return 0;
    }
    case VIDIOC_STREAMON:
      if (buffers_.empty()) return -EINVAL;
      streaming_ = true;
      t0_ = Clock::now();
      next_frame_ = 0;
      log_.push_back("STREAMON");
      return 0;
    case VIDIOC_STREAMOFF:
      StopStreaming();
      log_.push_back("STREAMOFF");
      return 0;
    default:
      return -ENOTTY;
  }
}

}  // namespace revolve::capture::testing
