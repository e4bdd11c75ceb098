#include "calibrate/camera_model.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace revolve::calibrate {

bool CameraModel::HasDistortion() const {
  return std::any_of(distortion.begin(), distortion.end(), [](double d) { return d != 0.0; });
}

cv::Mat CameraModel::CameraMatrix() const {
  cv::Mat k = cv::Mat::eye(3, 3, CV_64F);
  k.at<double>(0, 0) = intrinsics.fx_px;
  k.at<double>(1, 1) = intrinsics.fy_px;
  k.at<double>(0, 2) = intrinsics.cx_px;
  k.at<double>(1, 2) = intrinsics.cy_px;
  return k;
}

cv::Mat CameraModel::DistortionVector() const {
  const int n = std::max<int>(4, static_cast<int>(distortion.size()));
  cv::Mat d = cv::Mat::zeros(1, n, CV_64F);
  for (std::size_t i = 0; i < distortion.size(); ++i) {
    d.at<double>(0, static_cast<int>(i)) = distortion[i];
  }
  return d;
}

std::vector<cv::Point2f> CameraModel::UndistortPixels(
    const std::vector<cv::Point2f>& distorted_px) const {
  if (!HasDistortion() || distorted_px.empty()) return distorted_px;
  std::vector<cv::Point2f> ideal;
  const cv::Mat k = CameraMatrix();
  cv::undistortPoints(distorted_px, ideal, k, DistortionVector(), cv::noArray(), k,
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
  return ideal;
}

Eigen::Vector2d CameraModel::DistortPixel(const Eigen::Vector2d& ideal_px) const {
  if (!HasDistortion()) return ideal_px;
  std::vector<cv::Point3d> ray = {cv::Point3d((ideal_px.x() - intrinsics.cx_px) / intrinsics.fx_px,
                                              (ideal_px.y() - intrinsics.cy_px) / intrinsics.fy_px,
                                              1.0)};
  std::vector<cv::Point2d> out;
  cv::projectPoints(ray, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), CameraMatrix(), DistortionVector(),
                    out);
  return Eigen::Vector2d(out[0].x, out[0].y);
}

Undistorter::Undistorter(const CameraModel& model)
    : size_(model.intrinsics.width_px, model.intrinsics.height_px) {
  if (!model.HasDistortion()) return;
  const cv::Mat k = model.CameraMatrix();
  cv::initUndistortRectifyMap(k, model.DistortionVector(), cv::noArray(), k, size_, CV_32FC1,
                              map_x_, map_y_);
}

cv::Mat Undistorter::Apply(const cv::Mat& frame, int interpolation) const {
  if (identity() || frame.size() != size_) return frame;
  cv::Mat out;
  cv::remap(frame, out, map_x_, map_y_, interpolation, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return out;
}

cv::Mat UndistortFrame(const CameraModel& model, const cv::Mat& frame) {
  return Undistorter(model).Apply(frame);
}

}  // namespace revolve::calibrate
