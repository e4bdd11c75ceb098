#include "capture/synthetic/synthetic_camera.h"

#include <chrono>
#include <cmath>
#include <utility>

#include <fmt/format.h>

#include "base/log.h"

namespace revolve::capture {
namespace {

// Nominal exposure reported with every frame (the renderer has no motion blur).
constexpr double kExposureUs = 10000.0;

double Milliseconds(Clock::duration d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

Expected<void> CheckRange(std::string_view key, double value, OptionRange range) {
  if (std::isfinite(value) && value >= range.min && value <= range.max) return {};
  return MakeError(ErrorCode::kBadInput,
                   fmt::format("[camera.synthetic] {} = {} is out of range [{}, {}]", key, value,
                               range.min, range.max));
}

}  // namespace

Expected<Scene> SceneFromOptions(const SyntheticOptions& options) {
  auto shape = ParseShape(options.object);
  if (!shape) return std::unexpected(shape.error());
  return Scene::Create(*shape, options.radius_mm, options.height_mm);
}

Rig RigFromOptions(const SyntheticOptions& options) {
  Rig rig;
  rig.intrinsics =
      Intrinsics::FromFieldOfView(options.width_px, options.height_px, options.hfov_deg);
  rig.cam_from_table = CamFromTableLookingAtAxis(options.distance_mm, options.elevation_deg,
                                                 options.target_height_mm);
  return rig;
}

Expected<void> CheckCameraOutsideObject(const SyntheticOptions& options) {
  auto scene = SceneFromOptions(options);
  if (!scene) return std::unexpected(scene.error());
  const Eigen::Vector3d camera_table =
      RigFromOptions(options).cam_from_table.inverse().translation();
  const bool outside = camera_table.head<2>().norm() > scene->bounding_radius_mm() ||
                       camera_table.z() < 0.0 || camera_table.z() > scene->height_mm();
  if (outside) return {};
  return MakeError(ErrorCode::kBadInput,
                   fmt::format("distance_mm = {} puts the camera inside the {}'s enclosing "
                               "cylinder; move it farther away",
                               options.distance_mm, scene->Describe()));
}

Expected<void> ValidateSyntheticOptions(const SyntheticOptions& options) {
  const std::pair<std::string_view, std::pair<double, OptionRange>> checks[] = {
      {"width_px", {options.width_px, kImageSidePxRange}},
      {"height_px", {options.height_px, kImageSidePxRange}},
      {"hfov_deg", {options.hfov_deg, kHfovDegRange}},
      {"distance_mm", {options.distance_mm, kDistanceMmRange}},
      {"elevation_deg", {options.elevation_deg, kElevationDegRange}},
      {"target_height_mm", {options.target_height_mm, kTargetHeightMmRange}},
      {"radius_mm", {options.radius_mm, kObjectSizeMmRange}},
      {"height_mm", {options.height_mm, kObjectSizeMmRange}},
      {"backdrop_grey", {options.backdrop_grey, kBackdropGreyRange}},
      {"noise_sigma", {options.noise_sigma, kNoiseSigmaRange}},
  };
  for (const auto& [key, check] : checks) {
    if (auto ok = CheckRange(key, check.first, check.second); !ok) return ok;
  }
  if (auto scene = SceneFromOptions(options); !scene) {
    return std::unexpected(WithContext(scene.error(), "[camera.synthetic]"));
  }
  if (auto ok = CheckCameraOutsideObject(options); !ok) {
    return std::unexpected(WithContext(ok.error(), "[camera.synthetic]"));
  }
  return {};
}

Expected<std::unique_ptr<SyntheticCamera>> SyntheticCamera::Create(
    const SyntheticOptions& options, std::shared_ptr<const SimulatedPlate> plate) {
  if (plate == nullptr) {
    return MakeError(ErrorCode::kBadInput,
                     "the synthetic camera needs the simulated plate (the mock turntable's angle)");
  }
  if (auto ok = ValidateSyntheticOptions(options); !ok) return std::unexpected(ok.error());
  auto scene = SceneFromOptions(options);
  if (!scene) return std::unexpected(scene.error());
  return std::unique_ptr<SyntheticCamera>(
      new SyntheticCamera(options, std::move(*scene), std::move(plate)));
}

SyntheticCamera::SyntheticCamera(const SyntheticOptions& options, Scene scene,
                                 std::shared_ptr<const SimulatedPlate> plate)
    : options_(options),
      scene_(std::move(scene)),
      rig_(RigFromOptions(options)),
      render_settings_{options.backdrop_grey, options.noise_sigma, options.seed},
      plate_(std::move(plate)) {}

Expected<FrameFormat> SyntheticCamera::Start() {
  {
    std::lock_guard lock(mutex_);
    started_ = true;
  }
  Logger("capture")->info("{} started", Describe());
  return FrameFormat{options_.width_px, options_.height_px, "BGR3"};
}

void SyntheticCamera::Stop() noexcept {
  {
    std::lock_guard lock(mutex_);
    started_ = false;
  }
  wake_.notify_all();
}

Expected<Frame> SyntheticCamera::Capture(Clock::time_point not_before, Clock::duration timeout) {
  std::unique_lock lock(mutex_);
  if (!started_) {
    return MakeError(ErrorCode::kInternal, "synthetic camera: Capture() called while not started");
  }
  const Clock::time_point now = Clock::now();
  if (not_before > now && not_before - now > timeout) {
    return MakeError(ErrorCode::kTimeout,
                     fmt::format("synthetic camera: the exposure may not start for {:.1f} ms, "
                                 "beyond the capture timeout of {:.1f} ms",
                                 Milliseconds(not_before - now), Milliseconds(timeout)));
  }
  while (started_ && Clock::now() < not_before) wake_.wait_until(lock, not_before);
  if (!started_) {
    return MakeError(ErrorCode::kAborted, "synthetic camera: stopped while waiting to expose");
  }
  Frame frame;
  frame.exposed = Clock::now();
  frame.sequence = next_sequence_++;
  frame.exposure_us = kExposureUs;
  const double angle_deg = plate_->angle_deg.load();
  if (plate_->moving.load() && !warned_moving_) {
    warned_moving_ = true;
    Logger("capture")->warn(
        "synthetic camera: frame {} exposed while the plate was moving (at {:.2f} deg)",
        frame.sequence, angle_deg);
  }
  lock.unlock();
  frame.image = Render(angle_deg, frame.sequence);
  return frame;
}

std::string SyntheticCamera::Describe() const {
  return fmt::format(
      "synthetic camera {}x{} hfov {:g} deg, {:g} mm from the axis at {:g} deg "
      "elevation, seeing a {}",
      options_.width_px, options_.height_px, options_.hfov_deg, options_.distance_mm,
      options_.elevation_deg, scene_.Describe());
}

cv::Mat SyntheticCamera::Render(double plate_angle_deg, std::uint64_t sequence) const {
  return RenderFrame(scene_, rig_, plate_angle_deg, render_settings_, sequence);
}

cv::Mat SyntheticCamera::TrueMask(double plate_angle_deg) const {
  return RenderTrueMask(scene_, rig_, plate_angle_deg);
}

}  // namespace revolve::capture
