// Camera intrinsics and lens distortion from views of a board (OpenCV calibrateCamera), with
// quality gates that refuse a poor calibration and say why.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "calibrate/board.h"
#include "calibrate/camera_model.h"

namespace revolve::calibrate {

struct IntrinsicsOptions {
  // Quality gates: a calibration failing any is refused (bad_input listing every reason).
  int min_views = 10;                 // views in which the board was found
  double min_coverage = 0.35;         // fraction of the image covered by the boards' outlines
  double max_rms_px = 1.0;            // RMS reprojection error over all corners
  double min_tilt_spread_deg = 20.0;  // largest angle between two boards' normals (focal length
                                      // is unobservable from fronto-parallel views)
  // Distortion model: k1, k2, p1, p2 (+ k3 when true). k3 only helps wide-angle lenses and
  // over-fits otherwise.
  bool estimate_k3 = false;
  bool estimate_tangential = true;
};

// How one view contributed.
struct ViewReport {
  std::string name;          // what the caller called it (file name, "stop 3")
  bool used = false;         // the board was found
  std::string problem;       // why not (the detection error), when !used
  double rms_px = 0.0;       // reprojection error of this view's corners
  double tilt_deg = 0.0;     // angle between the board's normal and the optical axis
  double distance_mm = 0.0;  // camera to board origin
};

struct IntrinsicsResult {
  CameraModel camera;
  double rms_px = 0.0;           // over all corners of all used views
  double coverage = 0.0;         // see IntrinsicsOptions::min_coverage
  double tilt_spread_deg = 0.0;  // see IntrinsicsOptions::min_tilt_spread_deg
  int views_used = 0;
  double fx_std_px = 0.0;  // standard deviations estimated by OpenCV
  double fy_std_px = 0.0;
  double cx_std_px = 0.0;
  double cy_std_px = 0.0;
  std::vector<ViewReport> views;  // one per input, in input order
};

// One input view: its name (for messages) and the detection, or why there is none.
struct ViewDetection {
  std::string name;
  Expected<Detection> detection;
};

// Calibrates from detections in images of `image_width_px` x `image_height_px`. Views without a
// detection are reported and skipped. Errors (bad_input): fewer than 3 detections (nothing to
// fit: the message lists the per-view problems, e.g. every "no board found"), or any quality
// gate failing: "calibration refused: only 4 views with the board (need 10: capture more,
// tilting the board differently each time); RMS reprojection error 1.8 px > 1.0 px (...)".
Expected<IntrinsicsResult> CalibrateIntrinsics(const std::vector<ViewDetection>& views,
                                               int image_width_px, int image_height_px,
                                               const IntrinsicsOptions& options = {});

// Detects the board in every image, then calibrates. `names` (may be empty) labels the images in
// messages; all images must have the same size (bad_input otherwise).
Expected<IntrinsicsResult> CalibrateIntrinsicsFromImages(const std::vector<cv::Mat>& images,
                                                         const std::vector<std::string>& names,
                                                         const Board& board,
                                                         const IntrinsicsOptions& options = {},
                                                         const DetectOptions& detect = {});

// Fraction of a width x height image covered by the union of the detections' convex hulls,
// measured on a coarse grid (what IntrinsicsOptions::min_coverage gates).
double Coverage(const std::vector<Detection>& detections, int width_px, int height_px);

}  // namespace revolve::calibrate
