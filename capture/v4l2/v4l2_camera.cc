#include "capture/v4l2/v4l2_camera.h"

#include <linux/videodev2.h>

#include <algorithm>
#include <cmath>
#include <thread>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "base/log.h"
#include "capture/v4l2/pixel_convert.h"

namespace revolve::capture {
namespace {

using std::chrono::milliseconds;

// Longest single poll, so that Stop() and deadlines are noticed promptly.
constexpr milliseconds kPollSlice{50};
constexpr milliseconds kFirstBackoff{50};
constexpr milliseconds kMaxBackoff{1000};

// One manual setting: switch `auto_id` to `manual_value` (when the device has it), then write
// the value control.
struct ControlPlan {
  const char* name;
  std::uint32_t auto_id;
  std::int32_t manual_value;
  std::uint32_t value_id;
};

constexpr ControlPlan kExposure{"exposure", V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL,
                                V4L2_CID_EXPOSURE_ABSOLUTE};
constexpr ControlPlan kGain{"gain", V4L2_CID_AUTOGAIN, 0, V4L2_CID_GAIN};
constexpr ControlPlan kWhiteBalance{"white_balance", V4L2_CID_AUTO_WHITE_BALANCE, 0,
                                    V4L2_CID_WHITE_BALANCE_TEMPERATURE};
constexpr ControlPlan kFocus{"focus", V4L2_CID_FOCUS_AUTO, 0, V4L2_CID_FOCUS_ABSOLUTE};
constexpr ControlPlan kLockable[] = {kExposure, kGain, kWhiteBalance};

bool Recoverable(ErrorCode code) {
  return code == ErrorCode::kNoDevice || code == ErrorCode::kNotFound || code == ErrorCode::kBusy ||
         code == ErrorCode::kIo || code == ErrorCode::kLinkDown;
}

// The configured value of a plan, in device units; nullopt when not configured.
std::optional<std::int32_t> Configured(const V4l2Options& o, const ControlPlan& plan) {
  auto value = [](double v) -> std::optional<std::int32_t> {
    if (v < 0.0) return std::nullopt;
    return static_cast<std::int32_t>(std::lround(v));
  };
  if (plan.value_id == kExposure.value_id) {
    if (o.exposure_us < 0.0) return std::nullopt;
    return std::max<std::int32_t>(1, static_cast<std::int32_t>(std::lround(o.exposure_us / 100.0)));
  }
  if (plan.value_id == kGain.value_id) return value(o.gain);
  if (plan.value_id == kWhiteBalance.value_id) return value(o.white_balance_k);
  if (plan.value_id == kFocus.value_id) return value(o.focus);
  return std::nullopt;
}

}  // namespace

Expected<std::unique_ptr<V4l2Camera>> V4l2Camera::Create(const V4l2Options& options,
                                                         std::shared_ptr<V4l2Sys> sys) {
  for (const std::string& name : options.pixel_formats) {
    auto fourcc = ParseFourCc(name);
    if (!fourcc) return std::unexpected(WithContext(fourcc.error(), "[camera.v4l2] pixel_formats"));
  }
  if (options.device.empty()) {
    return MakeError(ErrorCode::kBadInput, "[camera.v4l2] device is empty");
  }
  if (sys == nullptr) {
    if (options.use_libv4l2) {
      sys = MakeLibV4l2Sys();
      if (sys == nullptr) {
        return MakeError(ErrorCode::kUnsupported,
                         "[camera.v4l2] use_libv4l2 = true, but this build has no libv4l2 "
                         "(install libv4l-dev and rebuild)");
      }
    } else {
      sys = MakeKernelV4l2Sys();
    }
  }
  return std::unique_ptr<V4l2Camera>(new V4l2Camera(options, std::move(sys)));
}

V4l2Camera::V4l2Camera(const V4l2Options& options, std::shared_ptr<V4l2Sys> sys)
    : options_(options), sys_(std::move(sys)) {}

V4l2Camera::~V4l2Camera() { Stop(); }

std::string V4l2Camera::Describe() const {
  std::lock_guard lock(mutex_);
  std::string text = fmt::format("V4L2 camera {}", options_.device);
  if (!card_.empty()) text += fmt::format(" ({})", card_);
  if (format_) {
    text += fmt::format(" {}x{} {}", format_->width_px, format_->height_px,
                        FourCcToString(format_->fourcc));
  }
  return text;
}

std::map<std::string, std::int32_t> V4l2Camera::AppliedControls() const {
  std::lock_guard lock(mutex_);
  return applied_;
}

V4l2Counters V4l2Camera::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

std::optional<NegotiatedFormat> V4l2Camera::format() const {
  std::lock_guard lock(mutex_);
  return format_;
}

Expected<void> V4l2Camera::OpenAndConfigure() {
  auto log = Logger("capture");
  auto device = V4l2Device::Open(*sys_, options_.device);
  if (!device) return std::unexpected(device.error());
  auto caps = (*device)->QueryCaps();
  if (!caps) return std::unexpected(caps.error());
  if (!caps->video_capture || !caps->streaming) {
    return MakeError(ErrorCode::kUnsupported,
                     fmt::format("{} ({}) is not a streaming video capture device (a UVC "
                                 "camera's second node carries metadata: use the other one)",
                                 options_.device, caps->card));
  }
  card_ = caps->card;
  auto formats = (*device)->EnumerateFormats();
  if (!formats) return std::unexpected(formats.error());

  std::optional<NegotiatedFormat> chosen;
  std::vector<std::string> offered;
  for (const PixelFormatInfo& f : *formats) offered.push_back(FourCcToString(f.fourcc));
  for (const std::string& name : options_.pixel_formats) {
    const std::uint32_t fourcc = *ParseFourCc(name);
    const bool listed = std::any_of(formats->begin(), formats->end(),
                                    [&](const PixelFormatInfo& f) { return f.fourcc == fourcc; });
    if (!listed || !CanConvert(fourcc)) continue;
    auto set = (*device)->SetFormat(fourcc, options_.width_px, options_.height_px);
    if (!set) {
      if (!Recoverable(set.error().code) || set.error().code == ErrorCode::kIo) {
        log->warn("{}: {} refused: {}", options_.device, name, set.error().message);
        continue;
      }
      return std::unexpected(set.error());
    }
    if (set->fourcc != fourcc) {
      log->warn("{}: asked for {}, the driver set {}; trying the next format", options_.device,
                name, FourCcToString(set->fourcc));
      continue;
    }
    if (options_.width_px > 0 && options_.height_px > 0 &&
        (set->width_px != options_.width_px || set->height_px != options_.height_px)) {
      if (options_.exact_size) {
        log->warn("{}: {} {}x{} was adjusted to {}x{}", options_.device, name, options_.width_px,
                  options_.height_px, set->width_px, set->height_px);
        continue;
      }
      log->warn("{}: {}x{} is not offered; the driver chose {}x{}", options_.device,
                options_.width_px, options_.height_px, set->width_px, set->height_px);
    }
    chosen = *set;
    break;
  }
  if (!chosen) {
    return MakeError(ErrorCode::kUnsupported,
                     fmt::format("{}: none of the formats asked for ({}) is usable at {}x{}{}; "
                                 "the device offers {}",
                                 options_.device, fmt::join(options_.pixel_formats, ", "),
                                 options_.width_px, options_.height_px,
                                 options_.exact_size ? " exactly" : "", fmt::join(offered, ", ")));
  }
  if (options_.fps > 0.0) {
    auto period = (*device)->SetFrameRate(options_.fps);
    if (!period) {
      log->warn("{}: cannot set {} fps: {}", options_.device, options_.fps, period.error().message);
    }
  }
  device_ = std::move(*device);
  format_ = chosen;
  frame_period_s_ = device_->FramePeriodS();
  if (auto ok = ApplyControls(); !ok) {
    device_.reset();
    return ok;
  }
  if (auto ok = device_->StartStreaming(options_.buffers); !ok) {
    device_.reset();
    return ok;
  }
  consecutive_timeouts_ = 0;
  return {};
}

Expected<void> V4l2Camera::ApplyControls() {
  auto log = Logger("capture");
  auto set_plan = [&](const ControlPlan& plan, std::int32_t value) -> Expected<void> {
    const ControlInfo info = device_->QueryControl(plan.value_id);
    if (!info.exists) {
      log->warn("{}: the device has no {} control; it stays as the camera sets it", options_.device,
                plan.name);
      return {};
    }
    // Auto off first: the manual control is inactive (and rejected) while auto is on.
    if (device_->QueryControl(plan.auto_id).exists) {
      if (auto ok = device_->SetControl(plan.auto_id, plan.manual_value); !ok) {
        return std::unexpected(
            WithContext(ok.error(), fmt::format("switching auto {} off", plan.name)));
      }
    }
    const auto clamped =
        static_cast<std::int32_t>(std::clamp<std::int64_t>(value, info.minimum, info.maximum));
    if (clamped != value) {
      log->warn("{}: {} = {} is outside [{}, {}]; using {}", options_.device, plan.name, value,
                info.minimum, info.maximum, clamped);
    }
    if (auto ok = device_->SetControl(plan.value_id, clamped); !ok) {
      return std::unexpected(WithContext(ok.error(), fmt::format("setting {}", plan.name)));
    }
    auto readback = device_->GetControl(plan.value_id);
    applied_[plan.name] = readback ? *readback : clamped;
    return {};
  };
  for (const ControlPlan& plan : {kExposure, kGain, kWhiteBalance, kFocus}) {
    std::optional<std::int32_t> value = Configured(options_, plan);
    if (!value) {
      if (auto it = locked_.find(plan.name); it != locked_.end()) value = it->second;
    }
    if (!value) continue;
    if (auto ok = set_plan(plan, *value); !ok) return ok;
    if (plan.value_id == kExposure.value_id &&
        device_->QueryControl(V4L2_CID_EXPOSURE_AUTO_PRIORITY).exists) {
      (void)device_->SetControl(V4L2_CID_EXPOSURE_AUTO_PRIORITY, 0);  // keep the frame rate
    }
  }
  if (options_.power_line_hz >= 0 && device_->QueryControl(V4L2_CID_POWER_LINE_FREQUENCY).exists) {
    const std::int32_t menu = options_.power_line_hz == 50 ? V4L2_CID_POWER_LINE_FREQUENCY_50HZ
                              : options_.power_line_hz == 60
                                  ? V4L2_CID_POWER_LINE_FREQUENCY_60HZ
                                  : V4L2_CID_POWER_LINE_FREQUENCY_DISABLED;
    if (auto ok = device_->SetControl(V4L2_CID_POWER_LINE_FREQUENCY, menu); !ok) {
      return std::unexpected(WithContext(ok.error(), "setting the power line frequency"));
    }
    applied_["power_line"] = menu;
  }
  return {};
}

Expected<void> V4l2Camera::LockAutoControls() {
  std::vector<const ControlPlan*> pending;
  for (const ControlPlan& plan : kLockable) {
    if (!Configured(options_, plan) && !locked_.contains(plan.name) &&
        device_->QueryControl(plan.value_id).exists && device_->QueryControl(plan.auto_id).exists) {
      pending.push_back(&plan);
    }
  }
  if (pending.empty() || options_.lock_after_s <= 0.0) return {};
  // Let the auto modes converge on live frames.
  const auto until = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(options_.lock_after_s));
  while (Clock::now() < until && !stop_requested_) {
    auto ready = device_->Wait(static_cast<int>(kPollSlice.count()));
    if (!ready) return std::unexpected(ready.error());
    if (*ready != WaitResult::kReady) continue;
    auto buffer = device_->Dequeue();
    if (!buffer) return std::unexpected(buffer.error());
    if (*buffer) {
      if (auto ok = device_->Requeue((*buffer)->index); !ok) return ok;
    }
  }
  for (const ControlPlan* plan : pending) {
    auto value = device_->GetControl(plan->value_id);
    if (!value) return std::unexpected(value.error());
    locked_[plan->name] = *value;
  }
  if (auto ok = ApplyControls(); !ok) return ok;
  std::vector<std::string> described;
  for (const auto& [name, value] : locked_) described.push_back(fmt::format("{} {}", name, value));
  Logger("capture")->info("{}: locked {} after {:.1f} s of auto", options_.device,
                          fmt::join(described, ", "), options_.lock_after_s);
  return {};
}

void V4l2Camera::Teardown(const char* why) noexcept {
  if (device_ == nullptr) return;
  Logger("capture")->warn("{}: closing the device ({})", options_.device, why);
  device_.reset();
}

Expected<FrameFormat> V4l2Camera::Start() {
  std::lock_guard lock(mutex_);
  stop_requested_ = false;
  if (!device_) {
    if (auto ok = OpenAndConfigure(); !ok) return std::unexpected(ok.error());
  }
  if (auto ok = LockAutoControls(); !ok) {
    Teardown("locking the controls failed");
    return std::unexpected(ok.error());
  }
  started_ = true;
  Logger("capture")->info("{}: {}x{} {}, {} buffers, frame period {:.1f} ms", options_.device,
                          format_->width_px, format_->height_px, FourCcToString(format_->fourcc),
                          device_->buffer_count(), frame_period_s_ * 1000.0);
  return FrameFormat{format_->width_px, format_->height_px, FourCcToString(format_->fourcc)};
}

void V4l2Camera::Stop() noexcept {
  stop_requested_ = true;
  std::lock_guard lock(mutex_);
  started_ = false;
  device_.reset();
}

Clock::time_point V4l2Camera::ExposureStart(const DequeuedBuffer& buffer,
                                            Clock::time_point dequeued) const {
  const std::uint32_t type = buffer.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK;
  if (type != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) return dequeued;
  // CLOCK_MONOTONIC is steady_clock's clock on Linux.
  const Clock::time_point stamp{std::chrono::duration_cast<Clock::duration>(buffer.timestamp)};
  if ((buffer.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) == V4L2_BUF_FLAG_TSTAMP_SRC_SOE) return stamp;
  // End of frame: back by the readout (one frame period) and the exposure.
  double exposure_s = 0.0;
  if (auto it = applied_.find("exposure"); it != applied_.end()) exposure_s = it->second * 100e-6;
  const double back_s = frame_period_s_ + exposure_s;
  return stamp - std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(back_s));
}

Expected<Frame> V4l2Camera::Capture(Clock::time_point not_before, Clock::duration timeout) {
  std::lock_guard lock(mutex_);
  if (!started_) {
    return MakeError(ErrorCode::kInternal, "V4L2 camera: Capture() called while not started");
  }
  auto log = Logger("capture");
  const Clock::time_point deadline = Clock::now() + timeout;
  const Clock::time_point threshold =
      not_before + std::chrono::duration_cast<Clock::duration>(
                       std::chrono::duration<double, std::milli>(options_.settle_margin_ms));
  Clock::duration backoff = kFirstBackoff;
  std::optional<Error> lost;
  int dequeued_after_threshold = 0;  // for drivers without monotonic timestamps
  while (true) {
    if (stop_requested_) return MakeError(ErrorCode::kAborted, "V4L2 camera: stopped");
    const Clock::time_point now = Clock::now();
    if (now >= deadline) {
      if (!device_) {
        return MakeError(ErrorCode::kNoDevice,
                         fmt::format("{} is gone and did not come back ({}); plug it in again",
                                     options_.device, lost ? lost->message : "not open"));
      }
      ++counters_.timeouts;
      if (++consecutive_timeouts_ >= options_.timeouts_before_reopen) {
        Teardown("no frames for several captures");
      }
      return MakeError(
          ErrorCode::kTimeout,
          fmt::format("{}: no frame exposed after the table settled within {:.0f} ms",
                      options_.device, std::chrono::duration<double, std::milli>(timeout).count()));
    }
    if (!device_) {
      auto opened = OpenAndConfigure();
      if (!opened) {
        if (!Recoverable(opened.error().code)) return std::unexpected(opened.error());
        lost = opened.error();
        const auto pause = std::min<Clock::duration>(backoff, deadline - Clock::now());
        const auto wake = Clock::now() + std::max<Clock::duration>(pause, Clock::duration::zero());
        while (Clock::now() < wake && !stop_requested_) {
          std::this_thread::sleep_for(std::min<Clock::duration>(kPollSlice, wake - Clock::now()));
        }
        backoff = std::min<Clock::duration>(2 * backoff, kMaxBackoff);
        continue;
      }
      ++counters_.reopened;
      log->info("{}: reopened and streaming again", options_.device);
      dequeued_after_threshold = 0;
    }
    const auto slice = std::min<Clock::duration>(kPollSlice, deadline - now);
    auto ready = device_->Wait(static_cast<int>(
        std::max<std::int64_t>(1, std::chrono::duration_cast<milliseconds>(slice).count())));
    if (!ready) {
      lost = ready.error();
      ++counters_.device_lost;
      Teardown(ready.error().message.c_str());
      continue;
    }
    if (*ready == WaitResult::kTimeout) continue;
    auto dequeued = device_->Dequeue();
    if (!dequeued) {
      lost = dequeued.error();
      ++counters_.device_lost;
      Teardown(dequeued.error().message.c_str());
      continue;
    }
    if (!*dequeued) continue;
    const DequeuedBuffer buffer = **dequeued;
    const Clock::time_point dequeued_at = Clock::now();
    auto requeue = [&]() -> bool {
      if (auto ok = device_->Requeue(buffer.index); !ok) {
        lost = ok.error();
        ++counters_.device_lost;
        Teardown(ok.error().message.c_str());
        return false;
      }
      return true;
    };
    const bool is_jpeg = format_->fourcc == kFourCcMjpg || format_->fourcc == kFourCcJpeg;
    if ((buffer.flags & V4L2_BUF_FLAG_ERROR) || buffer.data.empty() ||
        (is_jpeg && !IsCompleteJpeg(buffer.data))) {
      ++counters_.corrupt_dropped;
      requeue();
      continue;
    }
    const bool stamped =
        (buffer.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    const Clock::time_point exposed = ExposureStart(buffer, dequeued_at);
    bool stale;
    if (stamped) {
      stale = exposed < threshold;
    } else {
      // No clock to compare: the buffers queued at not_before may all hold older frames.
      stale = dequeued_at < threshold || ++dequeued_after_threshold <= device_->buffer_count();
    }
    if (stale) {
      ++counters_.stale_dropped;
      requeue();
      continue;
    }
    auto image = ConvertToBgr(buffer.data, format_->fourcc, format_->width_px, format_->height_px,
                              format_->bytes_per_line);
    const std::uint32_t sequence = buffer.sequence;
    requeue();
    if (!image) {
      ++counters_.corrupt_dropped;
      log->warn("{}: dropping a frame: {}", options_.device, image.error().message);
      continue;
    }
    Frame frame;
    frame.image = std::move(*image);
    frame.exposed = exposed;
    frame.sequence = sequence;
    if (auto it = applied_.find("exposure"); it != applied_.end()) {
      frame.exposure_us = it->second * 100.0;
    }
    consecutive_timeouts_ = 0;
    ++counters_.frames_delivered;
    return frame;
  }
}

}  // namespace revolve::capture
