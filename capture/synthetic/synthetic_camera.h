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
inline constexpr OptionRange kAxisOffsetPxRange{-1e4, 1e4};
inline constexpr OptionRange kRollDegRange{-180.0, 180.0};
inline constexpr OptionRange kAlbedoRange{0.01, 1.0};
inline constexpr OptionRange kPlateMmRange{0.0, 1e5};
inline constexpr OptionRange kBlurSigmaPxRange{0.0, 50.0};

// The scene the options describe (reads the mesh file for object = "mesh").
// Errors: bad_input (unknown object, bad size, bad mesh), not_found (no mesh file).
Expected<Scene> SceneFromOptions(const SyntheticOptions& options);

// The rig the options describe: Intrinsics::FromFieldOfView(width, height, hfov) with the
// principal point moved right by axis_offset_px, and cam_from_table = Rz(roll_deg) *
// CamFromTableLookingAtAxis(distance, elevation, target_height) (the roll about the optical axis).
Rig RigFromOptions(const SyntheticOptions& options);

// RigFromOptions, orthographic when projection = "orthographic" (px_per_mm = fx / distance).
SimProjection ProjectionFromOptions(const SyntheticOptions& options);

// The backdrop, plate and fixture settings of the options (noise, blur, seed included).
RenderSettings RenderSettingsFromOptions(const SyntheticOptions& options);

// bad_input (naming distance_mm) unless the camera stands outside the object's enclosing
// cylinder, which the renderer requires. Assumes the sizes are valid.
Expected<void> CheckCameraOutsideObject(const SyntheticOptions& options, const Scene& scene);
Expected<void> CheckCameraOutsideObject(const SyntheticOptions& options);

// Checks every field's range and that the camera stands outside the object's enclosing
// cylinder. Errors: bad_input naming [camera.synthetic] and the field.
Expected<void> ValidateSyntheticOptions(const SyntheticOptions& options);

class SyntheticCamera final : public Camera {
 public:
  // Errors: bad_input for invalid options (see ValidateSyntheticOptions) or a null plate;
  // not_found for a missing mesh file.
  static Expected<std::unique_ptr<SyntheticCamera>> Create(
      const SyntheticOptions& options, std::shared_ptr<const SimulatedPlate> plate);

  // Always succeeds: {width_px, height_px, "BGR3"}.
  Expected<FrameFormat> Start() override;

  // Exposes at max(now, not_before), sleeping until then, and renders the plate's angle at that
  // moment. Errors: timeout (at once, without sleeping) when not_before lies beyond now +
  // timeout; aborted when Stop() is called while waiting; internal when not started.
  // Frames are numbered 0, 1, ... from construction; frame k's noise is seeded by (seed, k),
  // so the same scan gives the same images. The frame carries its true mask and plate angle.
  Expected<Frame> Capture(Clock::time_point not_before, Clock::duration timeout) override;

  // Like Capture, without the object (backdrop, plate and fixtures only).
  Expected<Frame> CaptureBackground(Clock::time_point not_before, Clock::duration timeout) override;

  // Thread-safe; wakes a Capture waiting for not_before.
  void Stop() noexcept override;

  // The pinhole rig; nullopt for the orthographic projection (use KnownView) and with
  // known_geometry = false.
  std::optional<Rig> KnownRig() const override;
  // nullopt with known_geometry = false.
  std::optional<View> KnownView(double plate_angle_deg) const override {
    if (!options_.known_geometry) return std::nullopt;
    return projection_.ViewAt(plate_angle_deg);
  }
  std::optional<SceneTruth> KnownScene() const override { return scene_.Truth(); }
  std::string Describe() const override;

  const Scene& scene() const { return scene_; }
  const Rig& rig() const { return projection_.rig; }
  const SimProjection& projection() const { return projection_; }
  const RenderSettings& render_settings() const { return render_settings_; }

  // The frame the camera delivers as frame `sequence` with the plate at `plate_angle_deg`
  // (noise included), without timing or plate. Thread-safe.
  cv::Mat Render(double plate_angle_deg, std::uint64_t sequence) const;

  // Render with the true mask; `draw_object` false renders the empty scene.
  RenderOutput RenderWithTruth(double plate_angle_deg, std::uint64_t sequence,
                               bool draw_object = true) const;

  // The exact silhouette at pixel centres: CV_8UC1 0/255, no noise; the plate and fixtures
  // hide what they cover.
  cv::Mat TrueMask(double plate_angle_deg) const;

 private:
  SyntheticCamera(const SyntheticOptions& options, Scene scene,
                  std::shared_ptr<const SimulatedPlate> plate);
  Expected<Frame> Expose(Clock::time_point not_before, Clock::duration timeout, bool draw_object);

  SyntheticOptions options_;
  Scene scene_;
  SimProjection projection_;
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
