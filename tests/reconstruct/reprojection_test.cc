// Silhouette reprojection and volume IoU (reconstruct/metrics/reprojection.h) on meshes whose
// silhouettes and volumes are known.
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "reconstruct/cameras/views.h"
#include "reconstruct/metrics/reprojection.h"

namespace revolve::reconstruct {
namespace {

// An axis-aligned box as 12 outward triangles.
Mesh BoxMesh(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  Mesh mesh;
  for (int i = 0; i < 8; ++i) {
    mesh.vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(),
                               i & 4 ? hi.z() : lo.z());
  }
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    mesh.faces.emplace_back(q[0], q[1], q[2]);
    mesh.faces.emplace_back(q[0], q[2], q[3]);
  }
  return mesh;
}

// Any non-zero value is set, in views into larger images too: the pixel counts of the two masks'
// intersection and union.
TEST(MaskIoU, CountsTheNonZeroPixelsOfBothAndEither) {
  cv::Mat a(61, 203, CV_8UC1);
  cv::Mat b(61, 203, CV_8UC1);
  cv::randu(a, cv::Scalar(0), cv::Scalar(4));  // 0..3: a quarter of it zero
  cv::randu(b, cv::Scalar(0), cv::Scalar(2));  // 0..1: half of it zero
  for (const cv::Rect part : {cv::Rect(0, 0, 203, 61), cv::Rect(3, 5, 131, 40)}) {
    cv::Mat both, either;
    cv::min(a(part), b(part), both);
    cv::max(a(part), b(part), either);
    const double expected =
        static_cast<double>(cv::countNonZero(both)) / static_cast<double>(cv::countNonZero(either));
    EXPECT_EQ(MaskIoU(a(part), b(part)), expected) << part;
    EXPECT_GT(expected, 0.3);
    EXPECT_LT(expected, 0.45);
  }
}

TEST(Reprojection, BoxSilhouetteInTheThesisView) {
  const Mesh box = BoxMesh({-20.0f, -20.0f, 10.0f}, {20.0f, 20.0f, 50.0f});
  const View view = ThesisView(200, 100, 0.0);
  const cv::Mat silhouette = RenderSilhouette(box, view);
  // u in [99.5 - 20, 99.5 + 20] -> pixels 80..119; v = 99 - z for z in [10, 50] -> 49..89.
  EXPECT_EQ(cv::countNonZero(silhouette), 40 * 41);
  EXPECT_EQ(silhouette.at<std::uint8_t>(49, 80), 255);
  EXPECT_EQ(silhouette.at<std::uint8_t>(48, 80), 0);
  EXPECT_EQ(silhouette.at<std::uint8_t>(49, 79), 0);
  EXPECT_DOUBLE_EQ(MaskIoU(silhouette, silhouette), 1.0);
  cv::Mat half = silhouette.clone();
  half(cv::Rect(0, 0, 100, 100)).setTo(0);
  EXPECT_NEAR(MaskIoU(silhouette, half), 0.5, 1e-12);
  const cv::Mat none(100, 200, CV_8UC1, cv::Scalar(0));
  EXPECT_DOUBLE_EQ(MaskIoU(none, none), 1.0);
  const ReprojectionStats stats = SilhouetteReprojection(box, {view, view}, {silhouette, half});
  EXPECT_NEAR(stats.mean, 0.75, 1e-12);
  EXPECT_EQ(stats.worst_view, 1);
}

// Masks held as windows (their bounding rectangles, or any rectangle holding them) give the IoUs
// of the whole masks: a closed box (filled from its outline) and an open one (drawn face by face),
// the windows overlapping the silhouette in part, wholly or not at all.
TEST(Reprojection, MasksAsWindowsGiveTheIoUsOfTheWholeMasks) {
  Mesh open = BoxMesh({-20.0f, -20.0f, 10.0f}, {20.0f, 20.0f, 50.0f});
  const Mesh closed = open;
  open.faces.pop_back();
  std::vector<View> views;
  std::vector<cv::Mat> masks;
  for (const double angle : {0.0, 25.0, 70.0, 140.0}) {
    views.push_back(ThesisView(200, 100, angle));
    cv::Mat mask(100, 200, CV_8UC1, cv::Scalar(0));
    const int shift = static_cast<int>(angle) / 2;
    cv::rectangle(mask, cv::Rect(60 + shift, 30, 50, 40), cv::Scalar(255), cv::FILLED);
    cv::circle(mask, cv::Point(150, 20 + shift / 4), 8, cv::Scalar(255), cv::FILLED);
    masks.push_back(mask);
  }
  masks.back().setTo(0);
  masks.back()(cv::Rect(170, 80, 20, 15)).setTo(255);  // off the silhouette
  for (const Mesh* mesh : {&closed, static_cast<const Mesh*>(&open)}) {
    const ReprojectionStats whole = SilhouetteReprojection(*mesh, views, masks);
    for (const int margin : {0, 3}) {
      std::vector<cv::Mat> windows;
      std::vector<cv::Point> origins;
      for (const cv::Mat& mask : masks) {
        const cv::Rect roi = cv::boundingRect(mask);
        const cv::Rect window = cv::Rect(roi.x - margin, roi.y - margin, roi.width + 2 * margin,
                                         roi.height + 2 * margin) &
                                cv::Rect(0, 0, mask.cols, mask.rows);
        windows.push_back(mask(window).clone());
        origins.push_back(window.tl());
      }
      const ReprojectionStats windowed = SilhouetteReprojection(*mesh, views, windows, origins);
      EXPECT_EQ(windowed.iou, whole.iou) << (mesh == &open ? "open" : "closed") << " " << margin;
    }
  }
}

TEST(Reprojection, VolumeIoUOfTwoBoxes) {
  const Mesh a = BoxMesh({0.0f, 0.0f, 0.0f}, {2.0f, 2.0f, 2.0f});
  const Mesh b = BoxMesh({1.0f, 0.0f, 0.0f}, {3.0f, 2.0f, 2.0f});
  const InsideTest in_a = MeshInsideTest(a);
  const InsideTest in_b = MeshInsideTest(b);
  EXPECT_TRUE(in_a(Eigen::Vector3d(1.0, 1.0, 1.0)));
  EXPECT_FALSE(in_a(Eigen::Vector3d(1.0, 1.0, 2.5)));
  EXPECT_FALSE(in_a(Eigen::Vector3d(2.5, 1.0, 1.0)));
  // Overlap 1x2x2 over a union of 3x2x2.
  EXPECT_NEAR(
      VolumeIoU(in_a, in_b, Eigen::Vector3d(-0.5, -0.5, -0.5), Eigen::Vector3d(3.5, 2.5, 2.5), 80),
      1.0 / 3.0, 0.01);
  EXPECT_NEAR(VolumeIoU(in_a, in_a, Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(2.0), 16),
              1.0, 1e-12);
}

}  // namespace
}  // namespace revolve::reconstruct
