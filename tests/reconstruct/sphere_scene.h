// Analytic silhouettes for tests and benchmarks, with no renderer: the mask of a sphere seen by
// a pinhole camera (pixel set iff the ray through the pixel centre passes closer than the
// radius to the sphere's centre, in front of the camera).
#pragma once

#include <cmath>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/rig.h"

namespace revolve::reconstruct::testing {

struct Sphere {
  Eigen::Vector3d centre_mm{0.0, 0.0, 40.0};
  double radius_mm = 40.0;
};

// The brief's station: 768x576, 30 deg horizontal field of view, 450 mm from the axis, aiming
// at z = 40 mm, no elevation.
inline Rig StationRig(double distance_mm = 450.0, double elevation_deg = 0.0,
                      double target_height_mm = 40.0, int width_px = 768, int height_px = 576,
                      double hfov_deg = 30.0) {
  Rig rig;
  rig.intrinsics = Intrinsics::FromFieldOfView(width_px, height_px, hfov_deg);
  rig.cam_from_table = CamFromTableLookingAtAxis(distance_mm, elevation_deg, target_height_mm);
  return rig;
}

inline View ViewOf(const Rig& rig, double plate_angle_deg) {
  View view;
  view.pixel_from_object = rig.PixelFromObject(plate_angle_deg);
  view.width_px = rig.intrinsics.width_px;
  view.height_px = rig.intrinsics.height_px;
  return view;
}

// CV_8UC1 mask (255 = sphere) of `spheres` (their union) seen at `plate_angle_deg`.
inline cv::Mat SphereMask(const Rig& rig, double plate_angle_deg,
                          const std::vector<Sphere>& spheres) {
  const Eigen::Isometry3d cam_from_object = rig.CamFromObject(plate_angle_deg);
  const Eigen::Matrix3d object_from_cam_rotation = cam_from_object.linear().transpose();
  const Eigen::Vector3d camera_centre = -object_from_cam_rotation * cam_from_object.translation();
  const Eigen::Matrix3d k_inv = rig.intrinsics.K().inverse();
  const Eigen::Matrix3d ray_from_pixel = object_from_cam_rotation * k_inv;
  cv::Mat mask(rig.intrinsics.height_px, rig.intrinsics.width_px, CV_8UC1, cv::Scalar(0));
  for (int v = 0; v < mask.rows; ++v) {
    auto* row = mask.ptr<std::uint8_t>(v);
    for (int u = 0; u < mask.cols; ++u) {
      const Eigen::Vector3d d = (ray_from_pixel * Eigen::Vector3d(u, v, 1.0)).normalized();
      for (const Sphere& s : spheres) {
        const Eigen::Vector3d to_centre = s.centre_mm - camera_centre;
        const double along = to_centre.dot(d);
        if (along <= 0.0) continue;
        if ((to_centre - along * d).squaredNorm() < s.radius_mm * s.radius_mm) {
          row[u] = 255;
          break;
        }
      }
    }
  }
  return mask;
}

inline cv::Mat SphereMask(const Rig& rig, double plate_angle_deg, const Sphere& sphere) {
  return SphereMask(rig, plate_angle_deg, std::vector<Sphere>{sphere});
}

}  // namespace revolve::reconstruct::testing
