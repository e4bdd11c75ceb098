// The camera and the frames it delivers.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

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
  // The true surface as triangles (object frame, mm); analytic shapes are tessellated finely.
  std::vector<Eigen::Vector3d> mesh_vertices_mm;
  std::vector<Eigen::Vector3i> mesh_triangles;
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
  // Ground truth from a simulated camera: CV_8UC1, 255 where the object is seen. Empty for
  // real cameras.
  cv::Mat true_mask;
  // The plate angle the frame shows when the camera knows it (simulated and replay cameras).
  std::optional<double> plate_angle_deg;
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

  // A frame of the empty scene (no object: backdrop, plate, fixtures) for background-difference
  // segmentation, exposed like Capture's. The simulated camera renders it; the replay camera
  // serves its configured background image. Real cameras cannot remove the object:
  // unsupported (the station then captures the empty table with Capture before the object is
  // placed, or loads [segment] background from a file).
  virtual Expected<Frame> CaptureBackground(Clock::time_point not_before, Clock::duration timeout) {
    (void)not_before;
    (void)timeout;
    return MakeError(ErrorCode::kUnsupported,
                     Describe() + " cannot capture the empty scene by itself");
  }

  // The true rig geometry when the camera knows it (the simulated camera); nullopt for real
  // cameras, whose geometry comes from a calibration.
  virtual std::optional<Rig> KnownRig() const { return std::nullopt; }

  // The projection of object points at a plate angle when the camera knows it: KnownRig's
  // pinhole by default; an affine view for the orthographic simulated camera (which has no
  // KnownRig). Reconstruction should use this rather than KnownRig.
  virtual std::optional<View> KnownView(double plate_angle_deg) const {
    const std::optional<Rig> rig = KnownRig();
    if (!rig) return std::nullopt;
    View view;
    view.pixel_from_object = rig->PixelFromObject(plate_angle_deg);
    view.width_px = rig->intrinsics.width_px;
    view.height_px = rig->intrinsics.height_px;
    return view;
  }

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
  std::string projection = "pinhole";  // pinhole | orthographic (magnification fx / distance)
  double axis_offset_px = 0.0;  // the axis appears this many pixels right of the middle column
  // The camera rolled about its optical axis: the picture turns clockwise by this angle about the
  // principal point (a camera not quite level; off the thesis's assumptions).
  double roll_deg = 0.0;
  // false hides the true rig (KnownRig, KnownView: nullopt) so that the camera behaves like a
  // real one whose geometry must come from a calibration or the thesis's assumptions. The scene's
  // truth (KnownScene) stays, for accuracy checks.
  bool known_geometry = true;
  std::string object = "vase";  // sphere | cylinder | vase | cone | box | torus | mesh
  double radius_mm = 40.0;
  double height_mm = 100.0;
  std::string mesh_path;      // object = "mesh": an OBJ or PLY file (relative: to the config)
  std::string mesh_up = "y";  // the mesh file's up axis: x | y | z
  int backdrop_grey = 20;
  std::vector<double> backdrop_bgr;  // B G R 0..255; empty: backdrop_grey in every channel
  double object_albedo = 1.0;        // texture brightness, (0, 1]
  // checker | speckle: the checker alone, or with fine blotches over it (features for
  // photogrammetry: SIFT finds few on flat checker cells).
  std::string texture = "checker";
  double plate_radius_mm = 0.0;  // 0: no plate
  double plate_thickness_mm = 8.0;
  std::vector<double> plate_top_bgr;  // empty: the backdrop's colour
  std::vector<double> plate_rim_bgr = {150.0, 150.0, 150.0};
  std::vector<double> fixture_mm;  // boxes fixed to the table: groups of x0 y0 z0 x1 y1 z1
  std::vector<double> fixture_bgr = {200.0, 200.0, 200.0};
  double blur_sigma_px = 0.0;
  double noise_sigma = 3.0;
  std::uint64_t seed = 1;
};

// [camera.replay]: a folder of images served as a camera.
struct ReplayOptions {
  std::string dir;  // the folder (relative: to the config file's folder)
  // "" serves every image in the folder in natural order ("img2" before "img10"). Otherwise a
  // file name with {angle} (the stop's angle in whole degrees) or {index} (its number), either
  // optionally zero-padded as {angle:03} / {index:03}: "bw_shoe{angle}.tif", "stop_{index:03}.png".
  std::string pattern;
  double step_deg = 10.0;       // angle between images (for {index} and for natural order)
  std::string order = "angle";  // angle: the image for the plate's angle | sequence: in turn
  std::string background;       // optional image of the empty scene (CaptureBackground)
  // Optional geometry, like [camera.synthetic]'s: when hfov_deg > 0 the camera reports that rig
  // (for replaying simulated scans); otherwise the geometry must come from a calibration.
  double hfov_deg = 0.0;
  double distance_mm = 450.0;
  double elevation_deg = 0.0;
  double target_height_mm = 50.0;
};

// [camera.v4l2]: a USB (UVC) or other V4L2 camera.
struct V4l2Options {
  std::string device = "/dev/video0";  // a path; prefer /dev/v4l/by-id/... (stable)
  int width_px = 1280;
  int height_px = 720;
  // Preference order; the first the device offers wins. YUYV (lossless, best for segmentation),
  // MJPG (high resolution over USB 2), GREY, also UYVY, RGB3, BGR3.
  std::vector<std::string> pixel_formats = {"YUYV", "MJPG", "GREY"};
  bool exact_size = false;  // true: a device that adjusts the size is an error
  double fps = 0.0;         // 0: the driver's default frame interval
  int buffers = 4;
  bool use_libv4l2 = false;  // through libv4l2 (format emulation for odd cameras), when built
  // Manual controls, applied after every (re)open, auto modes switched off first. Unset (< 0):
  // left alone, unless lock_after_s > 0 locks what the auto modes settled on.
  double exposure_us = -1.0;      // V4L2 exposure_time_absolute is in 100 us units
  double gain = -1.0;             // device units
  double white_balance_k = -1.0;  // colour temperature
  double focus = -1.0;            // focus_absolute, device units
  int power_line_hz = -1;         // 0 (off), 50 or 60; -1: left alone
  // Let auto exposure / white balance / gain converge for this long after starting, then lock
  // them at their values (the controls not set above). 0: never lock.
  double lock_after_s = 1.5;
  double settle_margin_ms = 0.0;   // extra delay after not_before before an exposure may start
  int timeouts_before_reopen = 2;  // consecutive capture timeouts before the device is reopened
};

// [camera.libcamera]: a camera through libcamera (Raspberry Pi cameras, some others).
struct LibcameraOptions {
  std::string camera;  // libcamera id; "" the first camera
  int width_px = 1920;
  int height_px = 1080;
  double exposure_us = -1.0;         // -1: auto exposure
  double analogue_gain = -1.0;       // -1: auto
  std::vector<double> colour_gains;  // [red, blue]; empty: auto white balance
};

struct CameraOptions {
  std::string backend = "synthetic";  // synthetic | replay | v4l2 | libcamera
  SyntheticOptions synthetic;
  ReplayOptions replay;
  V4l2Options v4l2;
  LibcameraOptions libcamera;
};

// The backends this build has, e.g. {"synthetic", "replay", "v4l2"}.
std::vector<std::string> BuiltBackends();

// A human-readable list of the cameras this machine has, for bring-up (`revolve camera list`):
// each V4L2 node (stable /dev/v4l/by-id names first) with its card, whether it can capture,
// and its pixel formats and sizes; the libcamera cameras when that backend is built. Text that
// says so when there are none.
std::string ListCameraDevices();

// Writes a scene's true surface (mesh_vertices_mm, mesh_triangles) as an ASCII PLY in the object
// frame, atomically. Errors: bad_input when the truth has no mesh; io.
Expected<void> WriteTruthMeshPly(const SceneTruth& truth, const std::filesystem::path& path);

// Parses [camera] and its backend's sub-table; unknown keys are errors.
Expected<CameraOptions> ParseOptions(const config::Section& section);

// The descriptions of the keys of [camera] and its backends' tables, [segment] and [quality], for
// the configuration reference (config/reference.h).
config::OptionDocs ReferenceDocs();

// Creates the configured camera. `plate` is the simulated rig's plate (read by the synthetic
// camera; may be null for real backends).
Expected<std::unique_ptr<Camera>> Create(const CameraOptions& options,
                                         std::shared_ptr<const SimulatedPlate> plate);

}  // namespace revolve::capture
