// Posed cameras as COLMAP and nerfstudio text (reconstruct/cameras/camera_export.h): a pinhole
// view split back into K, R, t; the written numbers in each format's conventions.
#include <sstream>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "base/rig.h"
#include "reconstruct/cameras/camera_export.h"
#include "reconstruct/cameras/views.h"

namespace revolve::reconstruct {
namespace {

Rig TestRig() {
  Rig rig;
  rig.intrinsics = Intrinsics{1234.5, 1230.25, 401.75, 287.125, 800, 600};
  rig.cam_from_table = CamFromTableLookingAtAxis(420.0, 25.0, 45.0);
  return rig;
}

View ViewOf(const Rig& rig, double angle_deg, double scale = 1.0) {
  View view;
  view.pixel_from_object = scale * rig.PixelFromObject(angle_deg);
  view.width_px = rig.intrinsics.width_px;
  view.height_px = rig.intrinsics.height_px;
  return view;
}

TEST(CameraExport, DecomposeViewRecoversTheRig) {
  const Rig rig = TestRig();
  for (const double angle : {0.0, 37.0, 190.0, 355.0}) {
    for (const double scale : {1.0, 0.002, 40.0}) {
      const Expected<PinholeView> split = DecomposeView(ViewOf(rig, angle, scale));
      ASSERT_TRUE(split.has_value()) << split.error().ToString();
      EXPECT_NEAR(split->intrinsics.fx_px, rig.intrinsics.fx_px, 1e-7);
      EXPECT_NEAR(split->intrinsics.fy_px, rig.intrinsics.fy_px, 1e-7);
      EXPECT_NEAR(split->intrinsics.cx_px, rig.intrinsics.cx_px, 1e-7);
      EXPECT_NEAR(split->intrinsics.cy_px, rig.intrinsics.cy_px, 1e-7);
      EXPECT_EQ(split->intrinsics.width_px, 800);
      const Eigen::Isometry3d truth = rig.CamFromObject(angle);
      EXPECT_LT((split->cam_from_object.linear() - truth.linear()).norm(), 1e-12);
      EXPECT_LT((split->cam_from_object.translation() - truth.translation()).norm(), 1e-9);
    }
  }
}

TEST(CameraExport, DecomposeViewRefusesWhatCamerasCannotHold) {
  EXPECT_FALSE(DecomposeView(ThesisView(640, 480, 30.0)).has_value()) << "orthographic";
  View mirrored = ViewOf(TestRig(), 10.0);
  mirrored.pixel_from_object.col(0) *= -1.0;
  const Expected<PinholeView> m = DecomposeView(mirrored);
  ASSERT_FALSE(m.has_value());
  EXPECT_NE(m.error().message.find("mirrored"), std::string::npos);
  View skewed = ViewOf(TestRig(), 10.0);
  Eigen::Matrix3d skew = Eigen::Matrix3d::Identity();
  skew(0, 1) = 0.01;
  skewed.pixel_from_object = skew * skewed.pixel_from_object;
  const Expected<PinholeView> s = DecomposeView(skewed);
  ASSERT_FALSE(s.has_value());
  EXPECT_NE(s.error().message.find("skew"), std::string::npos);
}

TEST(CameraExport, ColmapCamerasPutThePixelCornerAtZero) {
  PinholeCamera camera;
  camera.intrinsics = TestRig().intrinsics;
  const std::string pinhole = ColmapCamerasText(camera);
  EXPECT_NE(pinhole.find("\n1 PINHOLE 800 600 1234.5 1230.25 402.25 287.625\n"), std::string::npos)
      << pinhole;
  camera.k1 = -0.125;
  camera.p2 = 0.001;
  const std::string opencv = ColmapCamerasText(camera);
  EXPECT_NE(opencv.find("\n1 OPENCV 800 600 1234.5 1230.25 402.25 287.625 -0.125 0 0 0.001\n"),
            std::string::npos)
      << opencv;
  EXPECT_EQ(ColmapMaskName("stop_003.png"), "stop_003.png.png");
}

TEST(CameraExport, ColmapImagesHoldWorldToCameraQuaternions) {
  const Rig rig = TestRig();
  std::vector<PosedImage> images;
  for (int k = 0; k < 4; ++k) {
    images.push_back(
        PosedImage{"stop_00" + std::to_string(k) + ".png", "", rig.CamFromObject(95.0 * k)});
  }
  std::istringstream in(ColmapImagesText(images));
  std::string line;
  int read = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    int id = 0, camera = 0;
    double qw, qx, qy, qz, tx, ty, tz;
    std::string name;
    ASSERT_TRUE(fields >> id >> qw >> qx >> qy >> qz >> tx >> ty >> tz >> camera >> name) << line;
    ASSERT_EQ(id, read + 1);
    EXPECT_EQ(camera, 1);
    EXPECT_EQ(name, images[read].name);
    EXPECT_GE(qw, 0.0);
    const Eigen::Quaterniond q(qw, qx, qy, qz);
    EXPECT_LT((q.toRotationMatrix() - images[read].cam_from_object.linear()).norm(), 1e-12);
    EXPECT_LT((Eigen::Vector3d(tx, ty, tz) - images[read].cam_from_object.translation()).norm(),
              1e-9);
    ASSERT_TRUE(std::getline(in, line));  // the 2D points: none
    EXPECT_TRUE(line.empty());
    ++read;
  }
  EXPECT_EQ(read, 4);
}

TEST(CameraExport, NerfstudioFramesAreOpenGlCameraToWorld) {
  const Rig rig = TestRig();
  PinholeCamera camera;
  camera.intrinsics = rig.intrinsics;
  const Eigen::Isometry3d cam_from_object = rig.CamFromObject(60.0);
  const nlohmann::json t =
      NerfstudioTransforms(camera, {PosedImage{"a.png", "a.png.png", cam_from_object}});
  EXPECT_EQ(t["cx"].get<double>(), 402.25);
  EXPECT_EQ(t["cy"].get<double>(), 287.625);
  EXPECT_EQ(t["w"].get<int>(), 800);
  EXPECT_EQ(t["frames"][0]["file_path"], "images/a.png");
  EXPECT_EQ(t["frames"][0]["mask_path"], "masks/a.png.png");
  Eigen::Matrix4d c2w;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) c2w(i, j) = t["frames"][0]["transform_matrix"][i][j];
  }
  // A point in front of the camera has negative z in the OpenGL camera frame, and a point
  // above the axis (object +z) has positive y there.
  const Eigen::Matrix4d w2c = c2w.inverse();
  const Eigen::Vector4d centre = w2c * Eigen::Vector4d(0, 0, 45, 1);
  EXPECT_LT(centre.z(), -400.0);
  EXPECT_NEAR(centre.x(), 0.0, 1e-9);
  EXPECT_NEAR(centre.y(), 0.0, 1e-9);
  const Eigen::Vector4d above = w2c * Eigen::Vector4d(0, 0, 80, 1);
  EXPECT_GT(above.y(), 0.0);
  // The same camera centre as the OpenCV pose's.
  EXPECT_LT((c2w.topRightCorner<3, 1>() - cam_from_object.inverse().translation()).norm(), 1e-9);
}

}  // namespace
}  // namespace revolve::reconstruct
