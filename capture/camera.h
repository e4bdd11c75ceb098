// The camera and the frames it delivers.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "base/sim_plate.h"
#include "config/config.h"

namespace revolve::capture {

using Clock = std::chrono::steady_clock;

// What a simulated scene really contains, for accuracy checks against ground truth.
// Coordinates are in the object frame (base/rig.h), millimetres.
struct SceneTruth {
  std::string description;  // "sphere r=40 mm"
  double volume_mm3 = 0.0;
  // Unsigned distance from a point to the true surface.
  std::function<double(const Eigen::Vector3d&)> distance_mm;
  // For a sphere: its centre and radius (the foundation's accuracy check fits them).
  std::optional<Eigen::Vector3d> sphere_center_mm;
  std::optional<double> sphere_radius_mm;
};

struct FrameFormat {
  int width_px = 0;
  int height_px = 0;
  std::string pixel_format;  // "BGR3" for the synthetic camera, the V4L2 fourcc otherwise
};

struct Frame {
  cv::Mat image;              // CV_8UC3, BGR
  Clock::time_point exposed;  // start of exposure
  std::uint64_t sequence = 0;
  double exposure_us = 0.0;
};

class Camera {
 public:
  virtual ~Camera() = default;

  // Opens and starts streaming; returns the negotiated format.
  virtual Expected<FrameFormat> Start() = 0;

  // Returns a frame whose exposure started at or after `not_before` (older buffers are
  // dropped), or timeout after `timeout`.
  virtual Expected<Frame> Capture(Clock::time_point not_before, Clock::duration timeout) = 0;

  virtual void Stop() noexcept = 0;

  // The true rig geometry when the camera knows it (the simulated camera); nullopt for real
  // cameras, whose geometry comes from a calibration.
  virtual std::optional<Rig> KnownRig() const { return std::nullopt; }

  // The scene's true geometry when the camera renders a known scene; nullopt otherwise.
  virtual std::optional<SceneTruth> KnownScene() const { return std::nullopt; }

  virtual std::string Describe() const = 0;
};

// [camera.synthetic]
struct SyntheticOptions {
  int width_px = 768;
  int height_px = 576;
  double hfov_deg = 30.0;
  double distance_mm = 450.0;
  double elevation_deg = 0.0;
  double target_height_mm = 50.0;
  std::string object = "vase";  // sphere | cylinder | vase
  double radius_mm = 40.0;
  double height_mm = 100.0;
  int backdrop_grey = 20;
  double noise_sigma = 3.0;
  std::uint64_t seed = 1;
};

struct CameraOptions {
  std::string backend = "synthetic";
  SyntheticOptions synthetic;
};

// Parses [camera] and its backend's sub-table; unknown keys are errors.
Expected<CameraOptions> ParseOptions(const config::Section& section);

// Creates the configured camera. `plate` is the simulated rig's plate (read by the synthetic
// camera; may be null for real backends).
Expected<std::unique_ptr<Camera>> Create(const CameraOptions& options,
                                         std::shared_ptr<const SimulatedPlate> plate);

}  // namespace revolve::capture
