// A real lens: pinhole intrinsics (base/rig.h) plus OpenCV's radial-tangential distortion, and
// the undistortion that turns its frames into ones the pinhole model (Rig) describes exactly.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "base/rig.h"

namespace revolve::calibrate {

struct CameraModel {
  Intrinsics intrinsics;
  // OpenCV order (k1, k2, p1, p2[, k3[, k4, k5, k6]]); empty or all zero: no distortion.
  std::vector<double> distortion;

  bool HasDistortion() const;
  cv::Mat CameraMatrix() const;      // 3x3 CV_64F
  cv::Mat DistortionVector() const;  // 1xN CV_64F (N >= 4; zeros when there is none)

  // Pixels as an ideal pinhole camera with the same intrinsics would see them (what Rig and
  // undistorted frames use). Iterative; accurate to ~1e-6 px for ordinary lenses.
  std::vector<cv::Point2f> UndistortPixels(const std::vector<cv::Point2f>& distorted_px) const;
  // The inverse: where an ideal pixel appears in the raw image.
  Eigen::Vector2d DistortPixel(const Eigen::Vector2d& ideal_px) const;
};

// Undistorts whole frames with precomputed maps: the output is what the pinhole camera
// `model.intrinsics` (same K, same size) would have captured, so that Rig{model.intrinsics,
// cam_from_table} describes it. Build once per calibration, apply to every frame.
class Undistorter {
 public:
  explicit Undistorter(const CameraModel& model);
  // Any type cv::remap accepts (CV_8UC1/3 frames, masks: use nearest for masks). The frame must
  // have the calibrated size; a frame of another size is returned unchanged (callers check the
  // size beforehand: see Calibration::CheckFrameSize).
  cv::Mat Apply(const cv::Mat& frame, int interpolation = cv::INTER_LINEAR) const;
  bool identity() const { return map_x_.empty(); }

 private:
  cv::Mat map_x_;
  cv::Mat map_y_;
  cv::Size size_;
};

// One-off convenience: Undistorter(model).Apply(frame).
cv::Mat UndistortFrame(const CameraModel& model, const cv::Mat& frame);

}  // namespace revolve::calibrate
