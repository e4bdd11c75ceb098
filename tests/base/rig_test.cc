// The rig's frame conventions (base/rig.h), which the synthetic camera and the reconstruction
// core both rely on. Projection geometry of views is tested in reconstruct.
#include "base/rig.h"

#include <cmath>

#include <gtest/gtest.h>

namespace revolve {
namespace {

Eigen::Vector2d ProjectAt(const Rig& rig, double plate_angle_deg, const Eigen::Vector3d& point) {
  const Eigen::Vector3d h = rig.PixelFromObject(plate_angle_deg) * point.homogeneous();
  EXPECT_GT(h.z(), 0.0);
  return h.head<2>() / h.z();
}

Rig DefaultRig(double elevation_deg) {
  Rig rig;
  rig.intrinsics = Intrinsics::FromFieldOfView(768, 576, 30.0);
  rig.cam_from_table = CamFromTableLookingAtAxis(450.0, elevation_deg, 50.0);
  return rig;
}

TEST(Rig, FieldOfViewIntrinsics) {
  const Intrinsics in = Intrinsics::FromFieldOfView(768, 576, 30.0);
  EXPECT_DOUBLE_EQ(in.cx_px, 383.5);
  EXPECT_DOUBLE_EQ(in.cy_px, 287.5);
  EXPECT_DOUBLE_EQ(in.fx_px, in.fy_px);
  // A ray at half the field of view lands on the image's outer edge (x = width / 2 from the
  // centre, in pixel-edge terms).
  EXPECT_NEAR(in.fx_px * std::tan(15.0 * M_PI / 180.0), 384.0, 1e-9);
  const Eigen::Matrix3d k = in.K();
  EXPECT_EQ(k(0, 2), in.cx_px);
  EXPECT_EQ(k(2, 2), 1.0);
}

TEST(Rig, TableFromObjectTurnsCounterClockwiseAboutZ) {
  const Eigen::Vector3d x = TableFromObject(90.0) * Eigen::Vector3d::UnitX();
  EXPECT_TRUE(x.isApprox(Eigen::Vector3d::UnitY(), 1e-12)) << x.transpose();
  const Eigen::Vector3d z = TableFromObject(37.0) * Eigen::Vector3d(0, 0, 5);
  EXPECT_TRUE(z.isApprox(Eigen::Vector3d(0, 0, 5), 1e-12));
  EXPECT_TRUE(TableFromObject(360.0).isApprox(TableFromObject(0.0), 1e-12));
}

TEST(Rig, CameraLooksAtTheAxisWithXRightAndZUp) {
  for (double elevation_deg : {0.0, 20.0}) {
    const Rig rig = DefaultRig(elevation_deg);
    const Eigen::Vector2d aim = ProjectAt(rig, 0.0, {0, 0, 50});
    EXPECT_NEAR(aim.x(), rig.intrinsics.cx_px, 1e-9);
    EXPECT_NEAR(aim.y(), rig.intrinsics.cy_px, 1e-9);
    // Any point on the axis lands on the middle column, whatever the plate angle.
    for (double angle_deg : {0.0, 90.0, 215.0}) {
      EXPECT_NEAR(ProjectAt(rig, angle_deg, {0, 0, 0}).x(), rig.intrinsics.cx_px, 1e-9);
      EXPECT_NEAR(ProjectAt(rig, angle_deg, {0, 0, 100}).x(), rig.intrinsics.cx_px, 1e-9);
    }
    // At 0 deg, object +x appears to the right and +z up.
    EXPECT_GT(ProjectAt(rig, 0.0, {10, 0, 50}).x(), aim.x());
    EXPECT_LT(ProjectAt(rig, 0.0, {0, 0, 60}).y(), aim.y());
    // The camera stands on the -y side: a point toward it is closer (larger in the image).
    const Eigen::Vector3d near_cam = rig.CamFromObject(0.0) * Eigen::Vector3d(0, -10, 50);
    const Eigen::Vector3d far_cam = rig.CamFromObject(0.0) * Eigen::Vector3d(0, 10, 50);
    EXPECT_LT(near_cam.z(), far_cam.z());
  }
  const Eigen::Vector3d center = DefaultRig(0.0).cam_from_table.inverse().translation();
  EXPECT_TRUE(center.isApprox(Eigen::Vector3d(0, -450, 50), 1e-9)) << center.transpose();
}

}  // namespace
}  // namespace revolve
