#include "base/rig.h"

#include <cmath>

#include "base/angles.h"

namespace revolve {

Eigen::Matrix3d Intrinsics::K() const {
  Eigen::Matrix3d k;
  k << fx_px, 0.0, cx_px, 0.0, fy_px, cy_px, 0.0, 0.0, 1.0;
  return k;
}

Intrinsics Intrinsics::FromFieldOfView(int width_px, int height_px, double hfov_deg) {
  Intrinsics in;
  in.width_px = width_px;
  in.height_px = height_px;
  in.fx_px = in.fy_px = 0.5 * width_px / std::tan(0.5 * Radians(hfov_deg));
  in.cx_px = 0.5 * (width_px - 1);
  in.cy_px = 0.5 * (height_px - 1);
  return in;
}

Eigen::Isometry3d CamFromTableLookingAtAxis(double distance_mm, double elevation_deg,
                                            double target_height_mm) {
  const double e = Radians(elevation_deg);
  const Eigen::Vector3d target(0.0, 0.0, target_height_mm);
  const Eigen::Vector3d center =
      target + distance_mm * Eigen::Vector3d(0.0, -std::cos(e), std::sin(e));
  const Eigen::Vector3d forward = (target - center).normalized();
  const Eigen::Vector3d right = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d down = forward.cross(right).normalized();
  Eigen::Matrix3d table_from_cam_rotation;
  table_from_cam_rotation.col(0) = right;
  table_from_cam_rotation.col(1) = down;
  table_from_cam_rotation.col(2) = forward;
  Eigen::Isometry3d table_from_cam = Eigen::Isometry3d::Identity();
  table_from_cam.linear() = table_from_cam_rotation;
  table_from_cam.translation() = center;
  return table_from_cam.inverse();
}

Eigen::Isometry3d TableFromObject(double plate_angle_deg) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(Radians(plate_angle_deg), Eigen::Vector3d::UnitZ()).matrix();
  return t;
}

Eigen::Isometry3d Rig::CamFromObject(double plate_angle_deg) const {
  return cam_from_table * TableFromObject(plate_angle_deg);
}

Matrix34d Rig::PixelFromObject(double plate_angle_deg) const {
  return intrinsics.K() * CamFromObject(plate_angle_deg).matrix().topRows<3>();
}

bool View::Project(const Eigen::Vector3d& point_object, Eigen::Vector2d* pixel) const {
  const Eigen::Vector3d h =
      pixel_from_object.leftCols<3>() * point_object + pixel_from_object.col(3);
  if (h.z() <= 0.0) return false;
  *pixel = h.head<2>() / h.z();
  return true;
}

bool View::IsAffine() const { return pixel_from_object.block<1, 3>(2, 0).isZero(0.0); }

Eigen::Vector3d View::DirectionToCamera(const Eigen::Vector3d& point_object) const {
  const Eigen::Matrix3d m = pixel_from_object.leftCols<3>();
  if (IsAffine()) {
    // The viewing direction is the null vector of the top two rows; orient it toward the viewer
    // (the side where the depth row of an equivalent pinhole camera would decrease).
    Eigen::Vector3d d = m.row(0).cross(m.row(1)).normalized();
    // For an orthographic K*[R t] with rows r1, r2: r1 x r2 = r3 (the forward axis); the camera
    // lies opposite to forward.
    return -d;
  }
  const Eigen::Vector3d center = -m.inverse() * pixel_from_object.col(3);
  return (center - point_object).normalized();
}

}  // namespace revolve
