#include "station/devices.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace revolve::station {
namespace {

// The camera faults of [station.simulate], counted in captures since start-up:
// - "unplugged" for camera_fail_count captures after camera_fail_after: Capture fails with
//   no_device, like a USB camera that dropped off the bus, and comes back afterwards;
// - camera_glitch: camera_glitch_count bad frames (blank, overexposed or blurred) after
//   camera_glitch_after, for the quality gates.
class FaultyCamera final : public capture::Camera {
 public:
  FaultyCamera(std::unique_ptr<capture::Camera> inner, SimulateOptions options,
               std::shared_ptr<std::atomic<std::int64_t>> captures)
      : inner_(std::move(inner)), options_(std::move(options)), captures_(std::move(captures)) {}

  Expected<capture::FrameFormat> Start() override { return inner_->Start(); }
  Expected<capture::Frame> Capture(capture::Clock::time_point not_before,
                                   capture::Clock::duration timeout) override {
    const std::int64_t n = captures_->fetch_add(1);
    if (options_.camera_fail_after >= 0 && n >= options_.camera_fail_after &&
        n < options_.camera_fail_after + options_.camera_fail_count) {
      return MakeError(
          ErrorCode::kNoDevice,
          fmt::format("{}: the camera is gone (simulated loss {} of {})", inner_->Describe(),
                      n - options_.camera_fail_after + 1, options_.camera_fail_count));
    }
    auto frame = inner_->Capture(not_before, timeout);
    if (frame && options_.camera_glitch != "none" && n >= options_.camera_glitch_after &&
        n < options_.camera_glitch_after + options_.camera_glitch_count) {
      Glitch(frame->image);
    }
    return frame;
  }
  void Stop() noexcept override { inner_->Stop(); }
  Expected<capture::Frame> CaptureBackground(capture::Clock::time_point not_before,
                                             capture::Clock::duration timeout) override {
    return inner_->CaptureBackground(not_before, timeout);
  }
  std::optional<Rig> KnownRig() const override { return inner_->KnownRig(); }
  std::optional<View> KnownView(double plate_angle_deg) const override {
    return inner_->KnownView(plate_angle_deg);
  }
  std::optional<capture::SceneTruth> KnownScene() const override { return inner_->KnownScene(); }
  std::string Describe() const override { return inner_->Describe(); }

 private:
  void Glitch(cv::Mat& image) const {
    if (options_.camera_glitch == "blank") {
      image.setTo(cv::Scalar::all(0));
    } else if (options_.camera_glitch == "overexposed") {
      image.convertTo(image, -1, 4.0);
    } else if (options_.camera_glitch == "blurred") {
      cv::GaussianBlur(image, image, cv::Size(), 6.0);
    }
  }

  std::unique_ptr<capture::Camera> inner_;
  SimulateOptions options_;
  std::shared_ptr<std::atomic<std::int64_t>> captures_;
};

}  // namespace

Expected<void> ReopenCamera(const StationConfig& config, Devices& devices) {
  if (devices.camera) devices.camera->Stop();
  devices.camera.reset();
  auto camera = capture::Create(config.camera, devices.plate);
  if (!camera) return std::unexpected(camera.error());
  if (config.station.simulate.camera_fail_after >= 0 ||
      config.station.simulate.camera_glitch != "none") {
    devices.camera = std::make_unique<FaultyCamera>(std::move(*camera), config.station.simulate,
                                                    devices.captures);
  } else {
    devices.camera = std::move(*camera);
  }
  auto segmenter = capture::CreateSegmenter(config.segment);
  if (!segmenter) return std::unexpected(segmenter.error());
  devices.segmenter = std::move(*segmenter);
  return {};
}

Expected<Devices> OpenDevices(const StationConfig& config) {
  Devices devices;
  devices.plate = std::make_shared<SimulatedPlate>();
  turntable::TurntableOptions table = config.turntable;
  const SimulateOptions& sim = config.station.simulate;
  if (sim.drive_fault != "none") {
    turntable::MockFault fault;
    fault.kind = sim.drive_fault == "stall"   ? turntable::MockFault::Kind::kStall
                 : sim.drive_fault == "alarm" ? turntable::MockFault::Kind::kAlarm
                                              : turntable::MockFault::Kind::kLinkDown;
    fault.move_index = sim.drive_fault_move;
    fault.count = sim.drive_fault_count;
    fault.at_fraction = sim.drive_fault_at;
    fault.alarm_code = sim.drive_alarm_code;
    fault.alarm_text = "simulated drive alarm (station.simulate.drive_fault)";
    table.mock.faults.push_back(fault);
  }
  auto turntable = turntable::Create(table, devices.plate);
  if (!turntable) return std::unexpected(turntable.error());
  devices.turntable = std::move(*turntable);
  if (auto camera = ReopenCamera(config, devices); !camera) {
    return std::unexpected(camera.error());
  }
  return devices;
}

}  // namespace revolve::station
