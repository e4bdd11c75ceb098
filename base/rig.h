// Rig geometry shared by the simulated camera (capture), the reconstruction core and calibration.
//
// Frames (all right-handed, lengths in millimetres unless a name says otherwise):
//  - table:  fixed to the turntable's base; it does not rotate. Origin where the rotation axis
//            meets the top of the plate, +z up along the axis, x and y horizontal.
//  - object: fixed to the plate and turning with it. It equals the table frame when the plate is
//            at 0 deg; at plate angle theta (degrees, counter-clockwise seen from above)
//            table_from_object = Rz(theta).
//  - cam:    OpenCV camera frame: +x right, +y down, +z forward along the optical axis.
// Pixels: (0, 0) is the centre of the top-left pixel; u grows right, v grows down.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace revolve {

using Matrix34d = Eigen::Matrix<double, 3, 4>;

// Pinhole intrinsics (no distortion) and the image size they belong to.
struct Intrinsics {
  double fx_px = 1000.0;
  double fy_px = 1000.0;
  double cx_px = 383.5;
  double cy_px = 287.5;
  int width_px = 768;
  int height_px = 576;

  Eigen::Matrix3d K() const;

  // A camera whose principal point is the image centre and whose focal length gives the
  // horizontal field of view `hfov_deg`.
  static Intrinsics FromFieldOfView(int width_px, int height_px, double hfov_deg);
};

// A camera looking at the point (0, 0, target_height_mm) on the rotation axis from
// `distance_mm` away, raised `elevation_deg` above the horizontal plane through that point.
// With the plate at 0 deg the camera stands on the table's -y side, so object +x appears to the
// right of the image and +z up; the axis projects onto the image's middle column.
Eigen::Isometry3d CamFromTableLookingAtAxis(double distance_mm, double elevation_deg,
                                            double target_height_mm);

// table_from_object for a plate at `plate_angle_deg`.
Eigen::Isometry3d TableFromObject(double plate_angle_deg);

// A calibrated turntable rig: fixed camera, plate turning about the table's z axis.
struct Rig {
  Intrinsics intrinsics;
  Eigen::Isometry3d cam_from_table = Eigen::Isometry3d::Identity();

  Eigen::Isometry3d CamFromObject(double plate_angle_deg) const;
  // K * [R | t] of CamFromObject: maps homogeneous object points to homogeneous pixels.
  Matrix34d PixelFromObject(double plate_angle_deg) const;
};

// One view for reconstruction: any 3x4 projection of object-frame points to pixels (pinhole,
// affine/orthographic, or a matrix imported from a dataset) and the size of its image.
// Contract: `pixel_from_object` is scaled so that the third coordinate of P * [X; 1] is positive
// for points in front of the camera (affine cameras: the last row is [0 0 0 s], s > 0).
struct View {
  Matrix34d pixel_from_object = Matrix34d::Zero();
  int width_px = 0;
  int height_px = 0;

  // Projects an object point; false when it lies on or behind the camera plane.
  bool Project(const Eigen::Vector3d& point_object, Eigen::Vector2d* pixel) const;

  // Unit vector from `point_object` toward the camera (constant for an affine camera).
  Eigen::Vector3d DirectionToCamera(const Eigen::Vector3d& point_object) const;

  // True when the camera is affine (orthographic): the last row of P is [0 0 0 s].
  bool IsAffine() const;
};

}  // namespace revolve
