// A fake V4L2 capture device behind the V4l2Sys seam: the state machine of a UVC camera
// (formats, S_FMT adjusting, controls with auto modes, REQBUFS/QUERYBUF/QBUF/DQBUF over mmap'd
// buffers, STREAMON/OFF) producing frames on a real clock, with unplugging and faults on
// request.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "capture/v4l2/v4l2_sys.h"

namespace revolve::capture::testing {

class FakeV4l2 final : public V4l2Sys {
 public:
  using Clock = std::chrono::steady_clock;

  struct Format {
    std::uint32_t fourcc = 0;
    std::vector<std::pair<int, int>> sizes;
  };
  enum class Stamp { kStartOfExposure, kEndOfFrame, kUnknown };
  struct Control {
    std::int32_t minimum = 0, maximum = 0, value = 0;
    std::uint32_t auto_id = 0;     // the auto control that makes this one inactive
    std::int32_t auto_manual = 0;  // the auto control's value meaning "manual"
    std::int32_t auto_value = 0;   // what the auto mode settles on
  };
  struct Options {
    std::string path = "/dev/fake-video0";
    std::vector<Format> formats;
    double frame_period_s = 0.02;
    Stamp stamp = Stamp::kStartOfExposure;
    bool capture_device = true;
    std::uint32_t substitute_fourcc = 0;  // S_FMT of this (listed) format sets formats[0]
  };

  explicit FakeV4l2(Options options);

  // The default controls of a UVC camera: exposure (auto menu: 1 manual, 3 aperture priority),
  // gain with autogain, white balance temperature with auto, focus with autofocus; no power line.
  void AddUvcControls();

  // Test levers.
  void Unplug();  // every open fd dies; Open fails with ENOENT
  void Replug();  // Open works again (old fds stay dead)
  void SetProducing(bool producing);
  void FlagNextFramesAsErrors(int count);
  void TruncateNextJpegFrames(int count);

  // Observations.
  int open_fds() const;
  int mapped_buffers() const;
  int opens() const;
  std::vector<std::string> log() const;  // "S_CTRL <id> <value>", "S_FMT ...", "STREAMON"...
  std::int32_t control(std::uint32_t id) const;
  std::uint64_t frames_produced() const;

  // V4l2Sys.
  int Open(const std::string& path, int flags) override;
  int Close(int fd) override;
  int Ioctl(int fd, unsigned long request, void* arg) override;
  void* Mmap(std::size_t length, int fd, std::int64_t offset, int* error) override;
  int Munmap(void* address, std::size_t length) override;
  int Poll(int fd, short events, int timeout_ms, short* revents) override;

 private:
  struct Buffer {
    std::vector<std::uint8_t> data;
    std::size_t bytes_used = 0;
    enum class State { kUser, kQueued, kDone } state = State::kUser;
    std::uint32_t sequence = 0;
    std::uint32_t flags = 0;
    std::chrono::nanoseconds timestamp{0};
  };

  bool Alive(int fd) const;
  // Produces every frame due by `now` into queued buffers.
  void Advance(Clock::time_point now);
  Clock::time_point DeliveryTime(std::uint64_t n) const;
  double ExposureS() const;
  void Fill(Buffer& buffer, std::uint64_t n);
  void StopStreaming();
  int DoIoctl(unsigned long request, void* arg);

  Options options_;
  mutable std::mutex mutex_;
  std::map<std::uint32_t, Control> controls_;
  std::map<int, int> fds_;  // fd -> generation
  int next_fd_ = 100;
  int generation_ = 0;
  bool unplugged_ = false;
  int opens_ = 0;
  int mapped_ = 0;
  std::vector<std::string> log_;
  // Format.
  std::uint32_t fourcc_ = 0;
  int width_ = 0, height_ = 0;
  // Streaming.
  std::vector<Buffer> buffers_;
  std::deque<int> queued_, done_;
  bool streaming_ = false;
  bool producing_ = true;
  Clock::time_point t0_;
  std::uint64_t next_frame_ = 0;
  std::uint64_t produced_ = 0;
  int error_frames_ = 0;
  int truncated_frames_ = 0;
};

}  // namespace revolve::capture::testing
