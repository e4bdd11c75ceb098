// The V4L2 camera: mmap streaming with a frame chosen by its timestamp (exposed after the
// table settled), manual controls re-applied after every (re)open, and recovery from a lost
// device. All device access goes through the V4l2Sys seam.
//
// States: closed -> (Start) streaming -> (device lost: ENODEV, POLLERR, or
// timeouts_before_reopen consecutive timeouts) closed -> (next Capture) reopen + reconfigure +
// re-apply controls -> streaming. A lost device is reported as no_device; Capture keeps trying
// to reopen until its deadline, with a back-off from 50 ms to 1 s between attempts.
#pragma once

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "capture/camera.h"
#include "capture/v4l2/v4l2_device.h"
#include "capture/v4l2/v4l2_sys.h"

namespace revolve::capture {

// What a Capture call saw, for tests and logs.
struct V4l2Counters {
  std::uint64_t frames_delivered = 0;
  std::uint64_t stale_dropped = 0;    // exposed before not_before
  std::uint64_t corrupt_dropped = 0;  // error flag, empty or truncated
  std::uint64_t timeouts = 0;
  std::uint64_t device_lost = 0;
  std::uint64_t reopened = 0;
};

class V4l2Camera final : public Camera {
 public:
  // No device access yet. `sys` null: the kernel (or libv4l2 when options.use_libv4l2 and
  // built). Errors: bad_input for an unknown pixel format code; unsupported for use_libv4l2
  // without libv4l2 in this build.
  static Expected<std::unique_ptr<V4l2Camera>> Create(const V4l2Options& options,
                                                      std::shared_ptr<V4l2Sys> sys = nullptr);
  ~V4l2Camera() override;

  // Opens, checks it is a streaming capture device, negotiates the format (the first of
  // pixel_formats the device lists and converts; S_FMT's answer is read back and a changed
  // format falls through to the next; a changed size is accepted unless exact_size), sets the
  // frame rate, applies the controls, starts streaming and (lock_after_s > 0) locks the auto
  // controls once they have settled. Errors: no_device / not_found (no device), unsupported
  // (not a capture device; no usable format), busy, io.
  Expected<FrameFormat> Start() override;

  // The first frame whose exposure started at or after not_before + settle_margin_ms, by the
  // buffer timestamp (start of exposure for SOE stamps; end-of-frame stamps minus the frame
  // period and the exposure; with no usable timestamp, the buffer_count + 1st frame dequeued
  // after not_before). Older frames, and frames flagged as errors or truncated, are requeued
  // unused. Errors: timeout; no_device when the device is gone and has not come back by the
  // deadline; aborted (Stop); internal (not started).
  Expected<Frame> Capture(Clock::time_point not_before, Clock::duration timeout) override;

  // Stops streaming and closes the device. Thread-safe: a Capture in progress returns aborted.
  void Stop() noexcept override;
  std::string Describe() const override;

  // The controls as applied (name -> value in device units), for the scan's metadata.
  std::map<std::string, std::int32_t> AppliedControls() const;
  V4l2Counters counters() const;
  std::optional<NegotiatedFormat> format() const;

 private:
  V4l2Camera(const V4l2Options& options, std::shared_ptr<V4l2Sys> sys);
  Expected<void> OpenAndConfigure();
  Expected<void> ApplyControls();
  Expected<void> LockAutoControls();
  void Teardown(const char* why) noexcept;
  Clock::time_point ExposureStart(const DequeuedBuffer& buffer, Clock::time_point dequeued) const;

  V4l2Options options_;
  std::shared_ptr<V4l2Sys> sys_;
  mutable std::mutex mutex_;  // guards everything below against Stop() from another thread
  std::atomic<bool> stop_requested_{false};
  bool started_ = false;
  std::unique_ptr<V4l2Device> device_;
  std::optional<NegotiatedFormat> format_;
  double frame_period_s_ = 0.0;
  int consecutive_timeouts_ = 0;
  std::map<std::string, std::int32_t> applied_;
  // Values locked from the auto modes, re-applied after a reopen.
  std::map<std::string, std::int32_t> locked_;
  V4l2Counters counters_;
  std::string card_;
};

}  // namespace revolve::capture
