// A hull coloured from windows of its frames (Reconstructor::FrameWindow, IntegrateWindow, which
// `reconstruct --images` uses to hold a fifth of each photo) is the hull coloured from the whole
// frames: the same colours, uvs and atlas, byte for byte.
#include <cmath>
#include <memory>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "reconstruct/cameras/views.h"
#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/reconstructor.h"
#include "reconstruct/texture/texture.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

// A sphere (r = 40 mm) seen from 20 degrees above by 18 cameras, 320 x 240, with frames of
// coloured stripes and noise (every pixel differs from its neighbours).
struct Scan {
  std::vector<cv::Mat> images, masks;
  std::vector<View> views;
};

Scan SphereScan() {
  Scan scan;
  const Rig rig = testing::StationRig(450.0, 20.0, 40.0, 320, 240);
  cv::RNG rng(7);
  for (int k = 0; k < 18; ++k) {
    const double angle = 20.0 * k;
    scan.masks.push_back(testing::SphereMask(rig, angle, testing::Sphere{}));
    cv::Mat image(240, 320, CV_8UC3);
    rng.fill(image, cv::RNG::UNIFORM, 0, 256);
    scan.images.push_back(image);
    scan.views.push_back(testing::ViewOf(rig, angle));
  }
  return scan;
}

ReconstructOptions Options(int resolution) {
  ReconstructOptions options;
  options.resolution = resolution;
  options.bbox_min_mm = Eigen::Vector3d(-45, -45, -5);
  options.bbox_max_mm = Eigen::Vector3d(45, 45, 85);
  options.flat_bottom = false;
  options.texture_size_px = 2048;
  return options;
}

// Colours the scan's hull with whole frames, or with each frame's FrameWindow only.
Mesh Coloured(const Scan& scan, int resolution, bool windows, double* window_share = nullptr) {
  std::unique_ptr<Reconstructor> reconstructor = Create(Options(resolution)).value();
  double window_px = 0.0;
  double frame_px = 0.0;
  for (std::size_t k = 0; k < scan.views.size(); ++k) {
    if (!windows) {
      EXPECT_TRUE(reconstructor->Integrate(scan.masks[k], scan.images[k], scan.views[k]));
      continue;
    }
    const cv::Rect window = reconstructor->FrameWindow(scan.masks[k], scan.views[k]);
    window_px += window.area();
    frame_px += scan.images[k].total();
    EXPECT_TRUE(reconstructor->IntegrateWindow(scan.masks[k], scan.images[k](window).clone(),
                                               window.tl(), scan.views[k]));
  }
  if (window_share != nullptr) *window_share = window_px / frame_px;
  return reconstructor->Finish().value();
}

TEST(FrameWindow, ColoursFromWindowsAreColoursFromWholeFrames) {
  const Scan scan = SphereScan();
  for (const int resolution : {24, 96}) {
    const Mesh whole = Coloured(scan, resolution, false);
    double share = 1.0;
    const Mesh windowed = Coloured(scan, resolution, true, &share);
    // The windows hold a fraction of the frames (else the test proves nothing).
    EXPECT_LT(share, 0.5) << resolution;
    ASSERT_FALSE(whole.colors.empty());
    EXPECT_EQ(windowed.colors, whole.colors) << resolution;
    EXPECT_EQ(windowed.uvs, whole.uvs) << resolution;
    EXPECT_EQ(windowed.uv_faces, whole.uv_faces) << resolution;
    ASSERT_EQ(windowed.texture.size(), whole.texture.size()) << resolution;
    EXPECT_EQ(cv::norm(windowed.texture, whole.texture, cv::NORM_INF), 0.0) << resolution;
  }
}

// What FrameWindow rests on: every vertex of the surface projects within one voxel's step
// (VoxelStepBoundPx) and half a pixel of its silhouette's bounding rectangle.
TEST(FrameWindow, SurfaceVerticesProjectWithinAVoxelStepOfTheSilhouette) {
  const Scan scan = SphereScan();
  for (const int resolution : {16, 40, 128}) {
    const ReconstructOptions options = Options(resolution);
    const VoxelGrid grid =
        VoxelGrid::FromBox(options.bbox_min_mm, options.bbox_max_mm, resolution).value();
    VisualHull hull(grid);
    for (std::size_t k = 0; k < scan.views.size(); ++k) {
      ASSERT_TRUE(hull.Integrate(scan.masks[k], scan.views[k]));
    }
    const Mesh mesh = hull.ExtractSurface();
    ASSERT_FALSE(mesh.vertices.empty());
    for (std::size_t k = 0; k < scan.views.size(); ++k) {
      const std::optional<double> step = VoxelStepBoundPx(grid, scan.views[k]);
      ASSERT_TRUE(step);
      const cv::Rect roi = cv::boundingRect(scan.masks[k]);
      double worst = 0.0;  // px beyond the rectangle, less half a pixel
      for (const Eigen::Vector3f& vertex : mesh.vertices) {
        Eigen::Vector2d p;
        ASSERT_TRUE(scan.views[k].Project(vertex.cast<double>(), &p));
        worst = std::max({worst, roi.x - 0.5 - p.x(), p.x() - (roi.x + roi.width - 0.5),
                          roi.y - 0.5 - p.y(), p.y() - (roi.y + roi.height - 0.5)});
      }
      EXPECT_LE(worst, *step) << "resolution " << resolution << ", view " << k;
    }
  }
}

TEST(FrameWindow, VoxelStepBoundOfAThesisViewIsTheVoxel) {
  const VoxelGrid grid = VoxelGrid::FromBox({-50, -50, 10}, {50, 50, 200}, 64).value();
  for (const double angle : {0.0, 30.0, 135.0}) {
    const std::optional<double> step = VoxelStepBoundPx(grid, ThesisView(400, 300, angle));
    ASSERT_TRUE(step);
    EXPECT_NEAR(*step, grid.voxel_mm, 1e-9) << angle;
  }
  // Part of the box out of the image, or behind a camera: no bound (the view keeps that part).
  EXPECT_FALSE(VoxelStepBoundPx(grid, ThesisView(80, 300, 0.0)));
  View behind = ThesisView(400, 300, 0.0);
  behind.pixel_from_object.row(2) << 0.0, 0.0, 1.0, -100.0;  // depth z - 100: some z < 100
  EXPECT_FALSE(VoxelStepBoundPx(grid, behind));
}

TEST(FrameWindow, AWindowMissingPixelsTheTextureMayReadIsRefused) {
  const Scan scan = SphereScan();
  std::unique_ptr<Reconstructor> reconstructor = Create(Options(48)).value();
  const cv::Rect window = reconstructor->FrameWindow(scan.masks[0], scan.views[0]);
  ASSERT_LT(window.area(), scan.images[0].total());
  const cv::Rect short_by_one(window.x + 1, window.y, window.width - 1, window.height);
  const Expected<void> refused = reconstructor->IntegrateWindow(
      scan.masks[0], scan.images[0](short_by_one).clone(), short_by_one.tl(), scan.views[0]);
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().code, ErrorCode::kBadInput);
  // The meridian method takes whole frames only.
  ReconstructOptions meridian = Options(48);
  meridian.method = "meridian";
  EXPECT_FALSE(Create(meridian).value()->IntegrateWindow(
      scan.masks[0], scan.images[0](window).clone(), window.tl(), scan.views[0]));
}

}  // namespace
}  // namespace revolve::reconstruct
