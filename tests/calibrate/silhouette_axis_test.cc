// The board-free fallback: the axis's image line from the silhouettes of a scan, on synthetic
// masks of a non-symmetric object (two boxes) seen by the thesis's orthographic camera and by a
// pinhole camera off the thesis's assumptions.
#include "calibrate/silhouette_axis.h"

#include <cstdio>
#include <functional>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "sim_rigs.h"

namespace revolve::calibrate {
namespace {

using Projection = std::function<Eigen::Vector2d(const Eigen::Vector3d& table_mm)>;

struct Box {
  Eigen::Vector3d min;
  Eigen::Vector3d max;
};

// An object that looks different from every side: a block off the axis and a tall post.
const std::vector<Box> kObject = {{{-30.0, -15.0, 0.0}, {20.0, 25.0, 60.0}},
                                  {{5.0, -35.0, 0.0}, {25.0, -5.0, 100.0}}};

// The silhouette of the object at `angle_deg`: each box's projected outline is the convex hull
// of its projected corners (exact for orthographic and pinhole cameras).
cv::Mat Mask(const Projection& project, double angle_deg, cv::Size size) {
  cv::Mat mask = cv::Mat::zeros(size, CV_8UC1);
  const Eigen::Matrix3d turn = sim::Rz(angle_deg);
  for (const Box& box : kObject) {
    std::vector<cv::Point> corners;
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d p((i & 1) ? box.max.x() : box.min.x(),
                              (i & 2) ? box.max.y() : box.min.y(),
                              (i & 4) ? box.max.z() : box.min.z());
      const Eigen::Vector2d px = project(turn * p);
      constexpr int kShift = 8;  // sub-pixel vertices
      corners.emplace_back(static_cast<int>(std::lround(px.x() * (1 << kShift))),
                           static_cast<int>(std::lround(px.y() * (1 << kShift))));
    }
    std::vector<cv::Point> hull;
    cv::convexHull(corners, hull);
    cv::fillConvexPoly(mask, hull, cv::Scalar(255), cv::LINE_8, 8);
  }
  return mask;
}

std::vector<cv::Mat> Scan(const Projection& project, int stops, cv::Size size) {
  std::vector<cv::Mat> masks;
  for (int k = 0; k < stops; ++k) masks.push_back(Mask(project, 360.0 * k / stops, size));
  return masks;
}

std::vector<double> Angles(int stops) { return sim::StopAngles(stops, 360.0 / stops); }

// The thesis's camera: orthographic, looking along +y, 2.5 px per mm, the axis on column
// `axis_column_px` at the middle row, the image turned by `roll_deg` about that point.
Projection Orthographic(double axis_column_px, double roll_deg) {
  return [=](const Eigen::Vector3d& p) {
    const double row0 = 287.5;
    const double x = 2.5 * p.x();  // relative to the pivot
    const double y = 2.5 * (60.0 - p.z());
    const double c = std::cos(sim::Radians(-roll_deg));
    const double s = std::sin(sim::Radians(-roll_deg));
    return Eigen::Vector2d(axis_column_px + c * x - s * y, row0 + s * x + c * y);
  };
}

TEST(SilhouetteAxis, OrthographicAxisFifteenPixelsOffCentre) {
  const double truth = 383.5 + 15.0;
  const std::vector<cv::Mat> masks = Scan(Orthographic(truth, 0.0), 36, cv::Size(768, 576));
  Expected<SilhouetteAxis> axis = AxisFromSilhouettes(masks, Angles(36));
  ASSERT_TRUE(axis) << axis.error().ToString();
  std::printf(
      "orthographic: axis column %.3f px (true %.3f), offset from the middle %.3f px, tilt "
      "%.3f deg, fit %.3f px RMS over %d samples from %d pairs, mirrored IoU %.4f\n",
      axis->column_px, truth, axis->OffsetFromMiddlePx(768), axis->tilt_deg, axis->rms_px,
      axis->samples, axis->pairs, axis->mirror_iou);
  EXPECT_NEAR(axis->column_px, truth, 0.25);
  EXPECT_NEAR(axis->OffsetFromMiddlePx(768), 15.0, 0.25);
  EXPECT_NEAR(axis->tilt_deg, 0.0, 0.05);
  EXPECT_EQ(axis->pairs, 18);
  EXPECT_GT(axis->mirror_iou, 0.98);
  EXPECT_LT(axis->rms_px, 0.5);
}

TEST(SilhouetteAxis, RolledCameraGivesATiltedLine) {
  const double truth = 383.5 + 15.0;
  const std::vector<cv::Mat> masks = Scan(Orthographic(truth, 2.0), 36, cv::Size(768, 576));
  Expected<SilhouetteAxis> axis = AxisFromSilhouettes(masks, Angles(36));
  ASSERT_TRUE(axis) << axis.error().ToString();
  std::printf(
      "orthographic, rolled 2 deg: axis column %.3f px (true %.3f), tilt %.3f deg (true "
      "2), mirrored IoU %.4f\n",
      axis->column_px, truth, axis->tilt_deg, axis->mirror_iou);
  EXPECT_NEAR(axis->column_px, truth, 1.0);
  EXPECT_NEAR(axis->tilt_deg, 2.0, 0.3);
}

TEST(SilhouetteAxis, PinholeRigOffTheThesisAssumptions) {
  // The rig: the axis 15 px right of the principal point, the camera tilted 3 deg down.
  Rig rig;
  rig.intrinsics = Intrinsics::FromFieldOfView(768, 576, 30.0);
  Eigen::Isometry3d yaw = Eigen::Isometry3d::Identity();
  yaw.linear() = sim::Ry(sim::Degrees(std::atan(15.0 / rig.intrinsics.fx_px)));
  rig.cam_from_table = yaw * CamFromTableLookingAtAxis(450.0, 3.0, 50.0);
  const Projection pinhole = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d h = rig.intrinsics.K() * (rig.cam_from_table * p);
    return Eigen::Vector2d(h.head<2>() / h.z());
  };
  const SilhouetteAxis truth = ProjectedAxisLine(rig);
  const std::vector<cv::Mat> masks = Scan(pinhole, 36, cv::Size(768, 576));
  Expected<SilhouetteAxis> axis = AxisFromSilhouettes(masks, Angles(36));
  ASSERT_TRUE(axis) << axis.error().ToString();
  std::printf(
      "pinhole: axis column %.3f px (true %.3f), tilt %.3f deg (true %.3f), fit %.3f px "
      "RMS, mirrored IoU %.4f\n",
      axis->column_px, truth.column_px, axis->tilt_deg, truth.tilt_deg, axis->rms_px,
      axis->mirror_iou);
  EXPECT_NEAR(truth.column_px - 383.5, 15.0, 0.01);
  EXPECT_NEAR(axis->column_px, truth.column_px, 1.0);
  EXPECT_NEAR(axis->tilt_deg, truth.tilt_deg, 0.5);
}

TEST(SilhouetteAxis, NeedsOppositeViews) {
  const std::vector<cv::Mat> masks = Scan(Orthographic(390.0, 0.0), 9, cv::Size(768, 576));
  Expected<SilhouetteAxis> axis = AxisFromSilhouettes(masks, Angles(9));  // 40 deg steps
  ASSERT_FALSE(axis);
  EXPECT_NE(axis.error().message.find("half a turn apart"), std::string::npos)
      << axis.error().message;
}

TEST(SilhouetteAxis, BadInput) {
  std::vector<cv::Mat> masks = Scan(Orthographic(390.0, 0.0), 4, cv::Size(768, 576));
  EXPECT_FALSE(AxisFromSilhouettes(masks, {0.0, 90.0}));
  masks[2] = cv::Mat::zeros(576, 768, CV_8UC1);
  Expected<SilhouetteAxis> empty = AxisFromSilhouettes(masks, Angles(4));
  ASSERT_FALSE(empty);
  EXPECT_NE(empty.error().message.find("empty"), std::string::npos) << empty.error().message;
  masks[2] = cv::Mat::zeros(100, 100, CV_8UC1);
  EXPECT_FALSE(AxisFromSilhouettes(masks, Angles(4)));
}

TEST(SilhouetteAxis, ProjectedAxisLineOfTheThesisRig) {
  Rig rig;
  rig.intrinsics = Intrinsics::FromFieldOfView(768, 576, 30.0);
  rig.cam_from_table = CamFromTableLookingAtAxis(450.0, 20.0, 50.0);
  const SilhouetteAxis line = ProjectedAxisLine(rig);
  EXPECT_NEAR(line.column_px, 383.5, 1e-9);
  EXPECT_NEAR(line.tilt_deg, 0.0, 1e-9);
  EXPECT_NEAR(line.ColumnAt(0.0), 383.5, 1e-9);
}

}  // namespace
}  // namespace revolve::calibrate
