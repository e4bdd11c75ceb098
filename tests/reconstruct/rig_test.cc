// Projection geometry of base/rig.h as the reconstruction core relies on it.
#include <gtest/gtest.h>

#include "base/rig.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

using testing::StationRig;
using testing::ViewOf;

TEST(RigGeometry, AxisProjectsOntoMiddleColumnAtEveryAngle) {
  const Rig rig = StationRig();
  const double middle = 0.5 * (rig.intrinsics.width_px - 1);
  for (double angle : {0.0, 10.0, 37.0, 90.0, 180.0, 275.0, 350.0}) {
    const View view = ViewOf(rig, angle);
    for (double z : {0.0, 25.0, 40.0, 80.0, 120.0}) {
      Eigen::Vector2d pixel;
      ASSERT_TRUE(view.Project(Eigen::Vector3d(0.0, 0.0, z), &pixel));
      EXPECT_NEAR(pixel.x(), middle, 1e-9) << "angle " << angle << " z " << z;
    }
  }
}

TEST(RigGeometry, AimPointProjectsToImageCentre) {
  const Rig rig = StationRig();
  Eigen::Vector2d pixel;
  ASSERT_TRUE(ViewOf(rig, 0.0).Project(Eigen::Vector3d(0.0, 0.0, 40.0), &pixel));
  EXPECT_NEAR(pixel.x(), rig.intrinsics.cx_px, 1e-9);
  EXPECT_NEAR(pixel.y(), rig.intrinsics.cy_px, 1e-9);
}

TEST(RigGeometry, PlusXAppearsRightAndPlusZUp) {
  const Rig rig = StationRig();
  const View view = ViewOf(rig, 0.0);
  Eigen::Vector2d centre, right, up;
  ASSERT_TRUE(view.Project(Eigen::Vector3d(0.0, 0.0, 40.0), &centre));
  ASSERT_TRUE(view.Project(Eigen::Vector3d(10.0, 0.0, 40.0), &right));
  ASSERT_TRUE(view.Project(Eigen::Vector3d(0.0, 0.0, 50.0), &up));
  EXPECT_GT(right.x(), centre.x() + 20.0);  // 10 mm at 450 mm with f = 1433 px: ~32 px
  EXPECT_NEAR(right.y(), centre.y(), 1e-9);
  EXPECT_LT(up.y(), centre.y() - 20.0);
  EXPECT_NEAR(up.x(), centre.x(), 1e-9);
}

TEST(RigGeometry, PlateTurnsCounterClockwise) {
  // At 90 deg, object +x has turned to table +y (away from the camera on the -y side), and
  // object -y has turned to table +x, which appears right of centre.
  const Rig rig = StationRig();
  const View view = ViewOf(rig, 90.0);
  const double middle = 0.5 * (rig.intrinsics.width_px - 1);
  Eigen::Vector2d px, minus_y;
  ASSERT_TRUE(view.Project(Eigen::Vector3d(10.0, 0.0, 40.0), &px));
  ASSERT_TRUE(view.Project(Eigen::Vector3d(0.0, -10.0, 40.0), &minus_y));
  EXPECT_NEAR(px.x(), middle, 1e-9);
  EXPECT_GT(minus_y.x(), middle + 20.0);
}

TEST(RigGeometry, DirectionToCameraPinhole) {
  const Rig rig = StationRig();
  const Eigen::Vector3d aim(0.0, 0.0, 40.0);
  EXPECT_TRUE(ViewOf(rig, 0.0).DirectionToCamera(aim).isApprox(Eigen::Vector3d(0, -1, 0), 1e-12));
  // At 90 deg the camera, fixed on the table's -y side, sits on the object's -x side.
  EXPECT_TRUE(ViewOf(rig, 90.0).DirectionToCamera(aim).isApprox(Eigen::Vector3d(-1, 0, 0), 1e-12));
  // From a point off the aim point the direction points at the camera centre (0, -450, 40).
  const Eigen::Vector3d p(30.0, 10.0, 0.0);
  const Eigen::Vector3d expected = (Eigen::Vector3d(0.0, -450.0, 40.0) - p).normalized();
  EXPECT_TRUE(ViewOf(rig, 0.0).DirectionToCamera(p).isApprox(expected, 1e-12));
  EXPECT_FALSE(ViewOf(rig, 0.0).IsAffine());
}

TEST(RigGeometry, DirectionToCameraAffine) {
  const Rig rig = StationRig(450.0, 20.0, 40.0);
  const Eigen::Isometry3d cam_from_object = rig.CamFromObject(30.0);
  View view;
  view.width_px = 768;
  view.height_px = 576;
  // Orthographic: pixel = s * (R x + t) on the first two rows, last row [0 0 0 1].
  view.pixel_from_object.topRows<2>() =
      5.0 * cam_from_object.matrix().topRows<2>() +
      (Eigen::Matrix<double, 2, 4>() << 0, 0, 0, 383.5, 0, 0, 0, 287.5).finished();
  view.pixel_from_object.row(2) << 0, 0, 0, 1;
  ASSERT_TRUE(view.IsAffine());
  const Eigen::Vector3d forward = cam_from_object.linear().row(2).transpose();
  EXPECT_TRUE(view.DirectionToCamera(Eigen::Vector3d(1, 2, 3)).isApprox(-forward, 1e-12));
  // It agrees with the pinhole camera of the same pose.
  EXPECT_TRUE(ViewOf(rig, 30.0)
                  .DirectionToCamera(Eigen::Vector3d(0.0, 0.0, 40.0))
                  .isApprox(-forward, 1e-9));
}

TEST(RigGeometry, PointsBehindTheCameraDoNotProject) {
  const View view = ViewOf(StationRig(), 0.0);
  Eigen::Vector2d pixel;
  EXPECT_FALSE(view.Project(Eigen::Vector3d(0.0, -460.0, 40.0), &pixel));
  EXPECT_FALSE(view.Project(Eigen::Vector3d(0.0, -450.0, 40.0), &pixel));  // the centre itself
  EXPECT_TRUE(view.Project(Eigen::Vector3d(0.0, -440.0, 40.0), &pixel));
}

}  // namespace
}  // namespace revolve::reconstruct
