// Ground truth without a renderer: analytic silhouettes of a sphere, 36 views at 10 degrees,
// through the public Reconstructor.
#include <gtest/gtest.h>

#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/metrics/metrics.h"
#include "reconstruct/reconstructor.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

using testing::Sphere;
using testing::SphereMask;
using testing::StationRig;
using testing::ViewOf;

TEST(SphereGroundTruth, ThirtySixViewsAtTenDegrees) {
  const Rig rig = StationRig(450.0, 0.0, 40.0);
  const Sphere sphere;  // r = 40 mm at (0, 0, 40): it touches the plate
  ReconstructOptions options;
  options.resolution = 160;
  options.bbox_min_mm = Eigen::Vector3d(-50.0, -50.0, 0.0);
  options.bbox_max_mm = Eigen::Vector3d(50.0, 50.0, 90.0);
  Expected<std::unique_ptr<Reconstructor>> reconstructor = Create(options);
  ASSERT_TRUE(reconstructor.has_value()) << reconstructor.error().ToString();
  for (int k = 0; k < 36; ++k) {
    const double angle = 10.0 * k;
    const Expected<void> integrated =
        (*reconstructor)->Integrate(SphereMask(rig, angle, sphere), cv::Mat(), ViewOf(rig, angle));
    ASSERT_TRUE(integrated.has_value()) << integrated.error().ToString();
  }
  const Expected<Mesh> mesh = (*reconstructor)->Finish();
  ASSERT_TRUE(mesh.has_value()) << mesh.error().ToString();

  const MeshStats stats = ComputeStats(*mesh);
  EXPECT_TRUE(stats.closed);
  EXPECT_TRUE(stats.oriented);
  EXPECT_EQ(stats.degenerate_triangles, 0);

  const double r = sphere.radius_mm;
  const SphereFit fit = FitSphere(*mesh);
  ASSERT_TRUE(fit.ok);
  EXPECT_NEAR(fit.radius_mm, r, 0.005 * r);
  EXPECT_LT((fit.centre_mm - sphere.centre_mm).norm(), 0.005 * r);

  // The exact hull of 36 views is +0.10% over the sphere at this D/R (carving notes 2.3); the
  // mesh is a chordal approximation of it (-0.02% here) and the silhouettes are pixelised
  // (0.31 mm pixels at the sphere, averaging out over the contour).
  const double volume = 4.0 / 3.0 * M_PI * r * r * r;
  EXPECT_NEAR(stats.volume_mm3, volume, 0.01 * volume);
  // The silhouettes' pixel staircase (+-0.16 mm) ripples the hull at the scale of the 0.6 mm
  // triangles; the tilted facets add ~3% of area (measured +3.1%).
  const double area = 4.0 * M_PI * r * r;
  EXPECT_NEAR(stats.area_mm2, area, 0.05 * area);

  const DistanceStats distance = SurfaceDistance(
      *mesh, [&](const Eigen::Vector3d& p) { return std::abs((p - sphere.centre_mm).norm() - r); },
      20000);
  // Sub-voxel vertices: the mean error is a small fraction of a 0.625 mm voxel.
  EXPECT_LT(distance.mean_mm, 0.1);
  EXPECT_LT(distance.max_mm, 0.625);
  RecordProperty("fitted_radius_mm", std::to_string(fit.radius_mm));
  RecordProperty("volume_ratio", std::to_string(stats.volume_mm3 / volume));
  std::printf(
      "fit r = %.4f mm (%.3f%%), centre off %.4f mm, volume %+.3f%%, area %+.3f%%, "
      "distance mean %.4f p90 %.4f max %.4f mm, %lld triangles\n",
      fit.radius_mm, 100.0 * (fit.radius_mm / r - 1.0), (fit.centre_mm - sphere.centre_mm).norm(),
      100.0 * (stats.volume_mm3 / volume - 1.0), 100.0 * (stats.area_mm2 / area - 1.0),
      distance.mean_mm, distance.p90_mm, distance.max_mm,
      static_cast<long long>(stats.triangle_count));
}

// The target: 36 views, 768x576 pinhole at 0 deg elevation, 256^3 over the station's
// default volume (0.47 mm voxels): volume within +0.3% of the truth, mean surface distance at
// most 0.25 voxel, and the hierarchical occupancy equal to the per-voxel reference.
TEST(SphereGroundTruth, Station256Targets) {
  const Rig rig = StationRig(450.0, 0.0, 40.0);
  const Sphere sphere;
  const Expected<VoxelGrid> grid = VoxelGrid::FromBox({-60, -60, 0}, {60, 60, 120}, 256);
  ASSERT_TRUE(grid.has_value());
  VisualHull hull(*grid);
  VisualHull naive(*grid);
  for (int k = 0; k < 36; ++k) {
    const cv::Mat mask = SphereMask(rig, 10.0 * k, sphere);
    ASSERT_TRUE(hull.Integrate(mask, ViewOf(rig, 10.0 * k)).has_value());
    ASSERT_TRUE(naive.IntegrateNaive(mask, ViewOf(rig, 10.0 * k)).has_value());
  }
  ASSERT_EQ(hull.OccupiedCount(), naive.OccupiedCount());
  for (int k = 0; k < grid->dims.z(); ++k) {
    for (int j = 0; j < grid->dims.y(); ++j) {
      for (int i = 0; i < grid->dims.x(); ++i) {
        ASSERT_EQ(hull.Occupied(i, j, k), naive.Occupied(i, j, k)) << i << " " << j << " " << k;
      }
    }
  }
  HullSurfaceOptions surface;
  surface.clip_below_z_mm = 0.0;
  const Mesh mesh = hull.ExtractSurface(surface);
  const MeshStats stats = ComputeStats(mesh);
  EXPECT_TRUE(stats.closed);
  EXPECT_TRUE(stats.oriented);
  const double r = sphere.radius_mm;
  const double volume = 4.0 / 3.0 * M_PI * r * r * r;
  const DistanceStats distance = SurfaceDistance(
      mesh, [&](const Eigen::Vector3d& p) { return std::abs((p - sphere.centre_mm).norm() - r); },
      50000);
  const double excess = stats.volume_mm3 / volume - 1.0;
  std::printf(
      "256^3: volume %+.3f%%, distance mean %.4f mm = %.3f voxel, p90 %.4f, max %.4f mm, "
      "%lld triangles\n",
      100.0 * excess, distance.mean_mm, distance.mean_mm / grid->voxel_mm, distance.p90_mm,
      distance.max_mm, static_cast<long long>(stats.triangle_count));
  EXPECT_GE(excess, -0.003);
  EXPECT_LE(excess, 0.003);
  EXPECT_LE(distance.mean_mm, 0.25 * grid->voxel_mm);
}

TEST(SphereGroundTruth, EmptySilhouettesAreAnError) {
  ReconstructOptions options;
  options.resolution = 32;
  Expected<std::unique_ptr<Reconstructor>> reconstructor = Create(options);
  ASSERT_TRUE(reconstructor.has_value());
  const Rig rig = StationRig(450.0, 0.0, 60.0);
  const cv::Mat empty(576, 768, CV_8UC1, cv::Scalar(0));
  for (double angle : {0.0, 90.0}) {
    ASSERT_TRUE((*reconstructor)->Integrate(empty, cv::Mat(), ViewOf(rig, angle)).has_value());
  }
  const Expected<Mesh> mesh = (*reconstructor)->Finish();
  ASSERT_FALSE(mesh.has_value());
  EXPECT_EQ(mesh.error().code, ErrorCode::kBadInput);
}

TEST(SphereGroundTruth, IntegrateRejectsAMaskOfTheWrongSize) {
  Expected<std::unique_ptr<Reconstructor>> reconstructor = Create(ReconstructOptions{});
  ASSERT_TRUE(reconstructor.has_value());
  const Expected<void> result = (*reconstructor)
                                    ->Integrate(cv::Mat(100, 100, CV_8UC1, cv::Scalar(0)),
                                                cv::Mat(), ViewOf(StationRig(), 0.0));
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kBadInput);
}

}  // namespace
}  // namespace revolve::reconstruct
