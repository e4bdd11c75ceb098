// The simulated camera: renders the known scene (capture/synthetic/scene.h) at the angle the
// shared SimulatedPlate holds when the exposure starts.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "base/sim_plate.h"
#include "capture/camera.h"
#include "capture/synthetic/render.h"
#include "capture/synthetic/scene.h"

namespace revolve::capture {

// Accepted ranges of the [camera.synthetic] options; ParseOptions and ValidateSyntheticOptions
// both use them.
struct OptionRange {
  double min;
  double max;
};
inline constexpr OptionRange kImageSidePxRange{16, 16384};
inline constexpr OptionRange kHfovDegRange{1.0, 170.0};
inline constexpr OptionRange kDistanceMmRange{1.0, 1e6};
inline constexpr OptionRange kElevationDegRange{-89.0, 89.0};
inline constexpr OptionRange kTargetHeightMmRange{-1e5, 1e5};
inline constexpr OptionRange kObjectSizeMmRange{0.1, 1e5};
inline constexpr OptionRange kBackdropGreyRange{0, 255};
inline constexpr OptionRange kNoiseSigmaRange{0.0, 100.0};

// The scene the options describe. Errors: bad_input (unknown object, bad size).
Expected<Scene> SceneFromOptions(const SyntheticOptions& options);

// The rig the options describe: Intrinsics::FromFieldOfView(width, height, hfov) and
// cam_from_table = CamFromTableLookingAtAxis(distance, elevation, target_height).
Rig RigFromOptions(const SyntheticOptions& options);

// bad_input (naming distance_mm) unless the camera stands outside the object's enclosing
// cylinder, which the renderer requires. Assumes the sizes are valid.
Expected<void> CheckCameraOutsideObject(const SyntheticOptions& options);

// Checks every field's range and that the camera stands outside the object's enclosing
// cylinder. Errors: bad_input naming [camera.synthetic] and the field.
Expected<void> ValidateSyntheticOptions(const SyntheticOptions& options);

class SyntheticCamera final : public Camera {
 public:
  // Errors: bad_input for invalid options (see ValidateSyntheticOptions) or a null plate.
  static Expected<std::unique_ptr<SyntheticCamera>> Create(
      const SyntheticOptions& options, std::shared_ptr<const SimulatedPlate> plate);

  // Always succeeds: {width_px, height_px, "BGR3"}.
  Expected<FrameFormat> Start() override;

  // Exposes at max(now, not_before), sleeping until then, and renders the plate's angle at that
  // moment. Errors: timeout (at once, without sleeping) when not_before lies beyond now +
  // timeout; aborted when Stop() is called while waiting; internal when not started.
  // Frames are numbered 0, 1, ... from construction; frame k's noise is seeded by (seed, k),
  // so the same scan gives the same images.
  Expected<Frame> Capture(Clock::time_point not_before, Clock::duration timeout) override;

  // Thread-safe; wakes a Capture waiting for not_before.
  void Stop() noexcept override;

  std::optional<Rig> KnownRig() const override { return rig_; }
  std::optional<SceneTruth> KnownScene() const override { return scene_.Truth(); }
  std::string Describe() const override;

  const Scene& scene() const { return scene_; }
  const Rig& rig() const { return rig_; }

  // The frame the camera delivers as frame `sequence` with the plate at `plate_angle_deg`
  // (noise included), without timing or plate. Thread-safe.
  cv::Mat Render(double plate_angle_deg, std::uint64_t sequence) const;

  // The exact silhouette at pixel centres (RenderTrueMask): CV_8UC1 0/255, no noise.
  cv::Mat TrueMask(double plate_angle_deg) const;

 private:
  SyntheticCamera(const SyntheticOptions& options, Scene scene,
                  std::shared_ptr<const SimulatedPlate> plate);

  SyntheticOptions options_;
  Scene scene_;
  Rig rig_;
  RenderSettings render_settings_;
  std::shared_ptr<const SimulatedPlate> plate_;

  std::mutex mutex_;
  std::condition_variable wake_;
  // Guarded by mutex_.
  bool started_ = false;
  std::uint64_t next_sequence_ = 0;
  bool warned_moving_ = false;
};

}  // namespace revolve::capture
