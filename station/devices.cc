#include "station/devices.h"

#include <fmt/format.h>

namespace revolve::station {
namespace {

// A camera that is "unplugged" for [station.simulate] camera_fail_count captures after
// camera_fail_after captures: Capture fails with no_device, like a USB camera that dropped off
// the bus, and comes back afterwards.
class LosingCamera final : public capture::Camera {
 public:
  LosingCamera(std::unique_ptr<capture::Camera> inner, SimulateOptions options,
               std::shared_ptr<std::atomic<std::int64_t>> captures)
      : inner_(std::move(inner)), options_(options), captures_(std::move(captures)) {}

  Expected<capture::FrameFormat> Start() override { return inner_->Start(); }
  Expected<capture::Frame> Capture(capture::Clock::time_point not_before,
                                   capture::Clock::duration timeout) override {
    const std::int64_t n = captures_->fetch_add(1);
    if (n >= options_.camera_fail_after &&
        n < options_.camera_fail_after + options_.camera_fail_count) {
      return MakeError(
          ErrorCode::kNoDevice,
          fmt::format("{}: the camera is gone (simulated loss {} of {})", inner_->Describe(),
                      n - options_.camera_fail_after + 1, options_.camera_fail_count));
    }
    return inner_->Capture(not_before, timeout);
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
  if (config.station.simulate.camera_fail_after >= 0) {
    devices.camera = std::make_unique<LosingCamera>(std::move(*camera), config.station.simulate,
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
