// The hierarchical carver against the per-voxel reference, and the point-test contract; the
// consensus's cut.
#include "reconstruct/hull/visual_hull.h"

#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "reconstruct/cameras/views.h"
#include "reconstruct/hull/silhouette_consensus.h"
#include "reconstruct/metrics/metrics.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

using testing::Sphere;
using testing::SphereMask;
using testing::StationRig;
using testing::ViewOf;

VoxelGrid Grid(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int resolution) {
  Expected<VoxelGrid> grid = VoxelGrid::FromBox(lo, hi, resolution);
  EXPECT_TRUE(grid.has_value());
  return *grid;
}

// A silhouette with holes, bumps and thin parts: two spheres plus random discs drawn in and
// punched out.
cv::Mat IrregularMask(const Rig& rig, double angle_deg, std::mt19937* rng) {
  cv::Mat mask = SphereMask(rig, angle_deg,
                            {Sphere{{0.0, 0.0, 40.0}, 35.0}, Sphere{{20.0, 15.0, 75.0}, 18.0}});
  std::uniform_int_distribution<int> u(0, mask.cols - 1);
  std::uniform_int_distribution<int> v(0, mask.rows - 1);
  std::uniform_int_distribution<int> r(1, std::max(2, mask.cols / 12));
  for (int i = 0; i < 25; ++i) {
    cv::circle(mask, cv::Point(u(*rng), v(*rng)), r(*rng), cv::Scalar(i % 2 ? 255 : 0), cv::FILLED);
  }
  return mask;
}

void ExpectSameOccupancy(const VisualHull& a, const VisualHull& b) {
  ASSERT_EQ(a.grid().dims, b.grid().dims);
  ASSERT_EQ(a.OccupiedCount(), b.OccupiedCount());
  const Eigen::Vector3i d = a.grid().dims;
  std::int64_t differences = 0;
  for (int k = 0; k < d.z(); ++k) {
    for (int j = 0; j < d.y(); ++j) {
      for (int i = 0; i < d.x(); ++i) differences += a.Occupied(i, j, k) != b.Occupied(i, j, k);
    }
  }
  EXPECT_EQ(differences, 0);
}

struct Scenario {
  const char* name;
  Rig rig;
  Eigen::Vector3d lo, hi;
  int resolution;
  std::vector<double> angles_deg;
};

TEST(VisualHull, GridFromBox) {
  VoxelGrid g = Grid({-60, -60, 0}, {60, 60, 120}, 192);
  EXPECT_EQ(g.dims, Eigen::Vector3i(192, 192, 192));
  EXPECT_DOUBLE_EQ(g.voxel_mm, 120.0 / 192);
  g = Grid({0, 0, 0}, {100, 61, 30}, 50);  // voxel 2 mm; 61 mm needs 31 voxels
  EXPECT_EQ(g.dims, Eigen::Vector3i(50, 31, 15));
  EXPECT_TRUE(g.Centre(0, 0, 0).isApprox(Eigen::Vector3d(1, 1, 1)));
  EXPECT_FALSE(VoxelGrid::FromBox({0, 0, 0}, {0, 1, 1}, 10).has_value());
  EXPECT_FALSE(VoxelGrid::FromBox({0, 0, 0}, {1, 1, 1}, 0).has_value());
  EXPECT_EQ(VoxelGrid::FromBox({1, 0, 0}, {0, 1, 1}, 10).error().code, ErrorCode::kBadInput);
}

TEST(VisualHull, HierarchicalEqualsNaive) {
  std::vector<Scenario> scenarios = {
      {"station, odd resolution, non-cubic box",
       StationRig(),
       {-50, -50, 0},
       {50, 50, 90},
       45,
       {0, 30, 60, 90, 120, 150, 180, 210, 240, 270, 300, 330}},
      // The camera stands inside the volume: voxels behind it and beside the frame.
      {"camera inside the volume",
       StationRig(50.0, 0.0, 40.0),
       {-60, -60, 0},
       {60, 60, 120},
       37,
       {0, 45, 90, 135, 180, 225, 270, 315}},
      // The object leaves the frame (narrow field of view, close camera).
      {"object leaves the frame",
       StationRig(160.0, 10.0, 60.0, 320, 240, 25.0),
       {-60, -60, 0},
       {60, 60, 120},
       63,
       {0, 17, 41, 90, 133, 200, 287}},
      {"elevated, tiny image",
       StationRig(300.0, 35.0, 40.0, 64, 48, 40.0),
       {-55, -45, 0},
       {55, 45, 100},
       33,
       {0, 20, 40, 100, 170, 250, 330}},
  };
  std::mt19937 rng(7);
  for (const Scenario& s : scenarios) {
    SCOPED_TRACE(s.name);
    const VoxelGrid grid = Grid(s.lo, s.hi, s.resolution);
    VisualHull hierarchical(grid);
    VisualHull naive(grid);
    for (double angle : s.angles_deg) {
      const cv::Mat mask = IrregularMask(s.rig, angle, &rng);
      const View view = ViewOf(s.rig, angle);
      ASSERT_TRUE(hierarchical.Integrate(mask, view).has_value());
      ASSERT_TRUE(naive.IntegrateNaive(mask, view).has_value());
      ExpectSameOccupancy(hierarchical, naive);
    }
    // Non-trivial: something carved, something left.
    EXPECT_GT(naive.OccupiedCount(), 0);
    EXPECT_LT(naive.OccupiedCount(), grid.VoxelCount());
  }
}

TEST(VisualHull, HierarchicalEqualsNaiveForAnyProjection) {
  // Matrices as datasets ship them: skew, mirrored frames, arbitrary scale, affine cameras.
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const VoxelGrid grid = Grid({-40, -30, 0}, {40, 30, 70}, 51);
  VisualHull hierarchical(grid);
  VisualHull naive(grid);
  for (int k = 0; k < 10; ++k) {
    const Eigen::Matrix3d rotation =
        Eigen::AngleAxisd(M_PI * unit(rng),
                          Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized())
            .matrix();
    Eigen::Matrix3d intrinsics;
    intrinsics << 900.0 + 200.0 * unit(rng), 30.0 * unit(rng), 320.0, 0.0, 900.0, 240.0, 0.0, 0.0,
        1.0;
    View view;
    view.width_px = 640;
    view.height_px = 480;
    const Eigen::Vector3d centre(0.0, 0.0, 35.0);
    const Eigen::Vector3d t =
        Eigen::Vector3d(0.0, 0.0, 250.0 + 100.0 * unit(rng)) - rotation * centre;
    if (k % 3 == 2) {
      // Affine: orthographic rows, last row [0 0 0 s].
      view.pixel_from_object.topLeftCorner<2, 3>() = 4.0 * rotation.topRows<2>();
      view.pixel_from_object(0, 3) = 320.0 + 4.0 * t.x();
      view.pixel_from_object(1, 3) = 240.0 + 4.0 * t.y();
      view.pixel_from_object.row(2) << 0.0, 0.0, 0.0, 1.0;
    } else {
      view.pixel_from_object << intrinsics * rotation, intrinsics * t;
      if (k % 2 == 1) view.pixel_from_object.row(0) *= -1.0;  // a mirrored image
    }
    view.pixel_from_object *= 0.5 + std::abs(unit(rng));  // any positive scale
    cv::Mat mask(480, 640, CV_8UC1, cv::Scalar(0));
    cv::circle(mask, cv::Point(320, 240), 170, cv::Scalar(255), cv::FILLED);
    for (int i = 0; i < 20; ++i) {
      cv::circle(mask, cv::Point(320 + 250 * unit(rng), 240 + 200 * unit(rng)),
                 5 + 40 * std::abs(unit(rng)), cv::Scalar(i % 2 ? 255 : 0), cv::FILLED);
    }
    ASSERT_TRUE(hierarchical.Integrate(mask, view).has_value());
    ASSERT_TRUE(naive.IntegrateNaive(mask, view).has_value());
    ExpectSameOccupancy(hierarchical, naive);
  }
  EXPECT_GT(naive.OccupiedCount(), 0);
  EXPECT_LT(naive.OccupiedCount(), grid.VoxelCount());
}

TEST(VisualHull, HierarchicalEqualsNaiveOnSphere36Views) {
  const Rig rig = StationRig();
  const VoxelGrid grid = Grid({-50, -50, 0}, {50, 50, 90}, 97);
  VisualHull hierarchical(grid);
  VisualHull naive(grid);
  for (int k = 0; k < 36; ++k) {
    const cv::Mat mask = SphereMask(rig, 10.0 * k, Sphere{});
    ASSERT_TRUE(hierarchical.Integrate(mask, ViewOf(rig, 10.0 * k)).has_value());
    ASSERT_TRUE(naive.IntegrateNaive(mask, ViewOf(rig, 10.0 * k)).has_value());
  }
  ExpectSameOccupancy(hierarchical, naive);
  // The hull of a sphere of radius 40 mm: roughly (4/3) pi 40^3 / voxel^3 voxels.
  const double expected = 4.0 / 3.0 * M_PI * std::pow(40.0 / grid.voxel_mm, 3);
  EXPECT_NEAR(hierarchical.OccupiedCount(), expected, 0.02 * expected);
}

// The silhouette consensus's hulls: each from one carve per view, equal to integrating every
// other view in order (occupancy and surface), on irregular masks, a view that sees only part
// of the grid, and a grid whose sides are not multiples of a brick.
TEST(VisualHull, LeaveOneOutEqualsIntegratingTheOtherViews) {
  std::mt19937 rng(11);
  const Rig rig = StationRig(300.0, 25.0, 40.0, 200, 150);
  const VoxelGrid grid = Grid({-50, -50, 0}, {50, 50, 90}, 38);
  std::vector<cv::Mat> masks;
  std::vector<View> views;
  std::vector<VisualHull::PreparedView> prepared;
  for (int k = 0; k < 7; ++k) {
    masks.push_back(IrregularMask(rig, 51.0 * k, &rng));
    views.push_back(ViewOf(rig, 51.0 * k));
    prepared.push_back(*VisualHull::PrepareView(masks.back(), views.back()));
  }
  views[3] = ViewOf(StationRig(90.0, 10.0, 40.0, 200, 150), 153.0);  // close: sees part
  prepared[3] = *VisualHull::PrepareView(masks[3], views[3]);
  const VisualHull::LeaveOneOut hulls(grid, prepared);
  ASSERT_EQ(hulls.size(), 7u);
  for (std::size_t i = 0; i < masks.size(); ++i) {
    VisualHull expected(grid);
    for (std::size_t j = 0; j < masks.size(); ++j) {
      if (j != i) {
        ASSERT_TRUE(expected.Integrate(masks[j], views[j]));
      }
    }
    ASSERT_GT(expected.OccupiedCount(), 1000);
    const VisualHull got = hulls.Without(i);
    ExpectSameOccupancy(got, expected);
    EXPECT_EQ(got.view_count(), 6);
    const Mesh a = got.ExtractSurface();
    const Mesh b = expected.ExtractSurface();
    EXPECT_EQ(a.vertices, b.vertices) << "view " << i;
    EXPECT_EQ(a.faces, b.faces) << "view " << i;
    ExpectSameOccupancy(hulls.Without(i, /*keep_views=*/false), expected);
  }
}

// A view prepared from a window of its mask is the view its whole mask gives: the same hulls and
// the same surfaces (placed on the silhouettes' edges), for windows tight around the mask,
// loose, the whole image, against the image's edges, and for an empty mask; a window past the
// image is refused.
TEST(VisualHull, AViewPreparedFromAWindowIsItsWholeMasks) {
  std::mt19937 rng(17);
  const Rig rig = StationRig(300.0, 25.0, 40.0, 200, 150);
  const VoxelGrid grid = Grid({-50, -50, 0}, {50, 50, 90}, 40);
  std::vector<cv::Mat> masks;
  std::vector<View> views;
  std::vector<VisualHull::PreparedView> windows;
  for (int k = 0; k < 6; ++k) {
    cv::Mat mask = IrregularMask(rig, 60.0 * k, &rng);
    if (k == 2) cv::rectangle(mask, cv::Rect(0, 100, 30, 50), cv::Scalar(255), cv::FILLED);
    if (k == 5) mask.setTo(0);  // left out of the hulls below: it would carve them all away
    const cv::Rect image(0, 0, mask.cols, mask.rows);
    const cv::Rect tight = cv::boundingRect(mask);
    cv::Rect window = tight;  // k 0, 2, 5 (empty: 0 x 0 at the origin)
    if (k == 1)
      window = cv::Rect(tight.x - 5, tight.y - 3, tight.width + 9, tight.height + 7) & image;
    if (k == 3) window = image;
    if (k == 4) window = cv::Rect(tight.x, 0, tight.width, mask.rows);
    masks.push_back(mask);
    views.push_back(ViewOf(rig, 60.0 * k));
    Expected<VisualHull::PreparedView> prepared =
        VisualHull::PrepareView(mask(window).clone(), window.tl(), views.back());
    ASSERT_TRUE(prepared) << k;
    EXPECT_EQ(prepared->mask_rect(), tight) << k;
    windows.push_back(*prepared);
  }
  const VisualHull::LeaveOneOut hulls(
      grid, std::vector<VisualHull::PreparedView>(windows.begin(), windows.end() - 1));
  for (std::size_t i = 0; i + 1 < masks.size(); ++i) {
    VisualHull expected(grid);
    for (std::size_t j = 0; j + 1 < masks.size(); ++j) {
      if (j != i) {
        ASSERT_TRUE(expected.Integrate(masks[j], views[j]));
      }
    }
    const VisualHull got = hulls.Without(i);
    ExpectSameOccupancy(got, expected);
    ASSERT_GT(expected.OccupiedCount(), 100) << i;
    const Mesh a = got.ExtractSurface();
    const Mesh b = expected.ExtractSurface();
    EXPECT_EQ(a.vertices, b.vertices) << "view " << i;
    EXPECT_EQ(a.faces, b.faces) << "view " << i;
  }
  // The empty mask's view alone: it carves what it sees.
  VisualHull empty(grid);
  ASSERT_TRUE(empty.Integrate(masks[5], views[5]));
  ExpectSameOccupancy(VisualHull::LeaveOneOut(grid, {windows[5], windows[0]}).Without(1), empty);
  const Expected<VisualHull::PreparedView> past = VisualHull::PrepareView(
      cv::Mat(20, 20, CV_8UC1, cv::Scalar(255)), cv::Point(190, 10), views[0]);
  ASSERT_FALSE(past);
  EXPECT_EQ(past.error().code, ErrorCode::kBadInput);
}

// Tolerating one carve: a voxel of hull i survives when at most one of the other views carves it
// (each view's own carve counted voxel by voxel), however many views there are.
TEST(VisualHull, LeaveOneOutToleratingOneKeepsWhatOnlyOneOtherViewCarves) {
  std::mt19937 rng(5);
  const Rig rig = StationRig(300.0, 25.0, 40.0, 200, 150);
  const VoxelGrid grid = Grid({-50, -50, 0}, {50, 50, 90}, 30);
  std::vector<VisualHull> alone;
  std::vector<VisualHull::PreparedView> prepared;
  for (int k = 0; k < 9; ++k) {
    const cv::Mat mask = IrregularMask(rig, 40.0 * k, &rng);
    const View view = ViewOf(rig, 40.0 * k);
    alone.emplace_back(grid);
    ASSERT_TRUE(alone.back().Integrate(mask, view));
    prepared.push_back(*VisualHull::PrepareView(mask, view));
  }
  const VisualHull::LeaveOneOut hulls(grid, prepared);
  for (std::size_t i : {std::size_t{0}, std::size_t{4}}) {
    const VisualHull got = hulls.Without(i, /*keep_views=*/false, /*tolerated=*/1);
    std::int64_t differences = 0;
    std::int64_t kept_against_one = 0;
    for (int z = 0; z < grid.dims.z(); ++z) {
      for (int y = 0; y < grid.dims.y(); ++y) {
        for (int x = 0; x < grid.dims.x(); ++x) {
          int carves = 0;
          for (std::size_t j = 0; j < alone.size(); ++j)
            carves += j != i && !alone[j].Occupied(x, y, z);
          differences += got.Occupied(x, y, z) != (carves <= 1);
          kept_against_one += carves == 1;
        }
      }
    }
    EXPECT_EQ(differences, 0) << "view " << i;
    EXPECT_GT(kept_against_one, 100) << "view " << i;  // the tolerance keeps something
  }
}

TEST(VisualHull, AViewDoesNotCarveWhatItCannotSee) {
  const VoxelGrid grid = Grid({-60, -60, 0}, {60, 60, 120}, 40);
  const Rig rig = StationRig();
  const cv::Mat empty(576, 768, CV_8UC1, cv::Scalar(0));

  // Looking away from the volume: everything is behind the camera.
  {
    Rig away = rig;
    away.cam_from_table.prerotate(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()));
    VisualHull hull(grid);
    ASSERT_TRUE(hull.Integrate(empty, ViewOf(away, 0.0)).has_value());
    EXPECT_EQ(hull.OccupiedCount(), grid.VoxelCount());
  }
  // Looking beside the volume: everything projects outside the image.
  {
    View view = ViewOf(rig, 0.0);
    view.pixel_from_object.row(0) += 5000.0 * view.pixel_from_object.row(2);  // u += 5000
    VisualHull hull(grid);
    ASSERT_TRUE(hull.Integrate(empty, view).has_value());
    EXPECT_EQ(hull.OccupiedCount(), grid.VoxelCount());
  }
  // A close camera sees part of the volume: exactly the voxels whose centre projects outside
  // the image (or lies behind the camera) survive an empty mask.
  {
    const Rig close = StationRig(80.0, 0.0, 60.0);
    const View view = ViewOf(close, 0.0);
    VisualHull hull(grid);
    ASSERT_TRUE(hull.Integrate(empty, view).has_value());
    std::int64_t unseen = 0;
    for (int k = 0; k < grid.dims.z(); ++k) {
      for (int j = 0; j < grid.dims.y(); ++j) {
        for (int i = 0; i < grid.dims.x(); ++i) {
          Eigen::Vector2d px;
          const bool seen = view.Project(grid.Centre(i, j, k), &px) &&
                            std::floor(px.x() + 0.5) >= 0 && std::floor(px.x() + 0.5) < 768 &&
                            std::floor(px.y() + 0.5) >= 0 && std::floor(px.y() + 0.5) < 576;
          unseen += !seen;
          ASSERT_EQ(hull.Occupied(i, j, k), !seen) << i << " " << j << " " << k;
        }
      }
    }
    EXPECT_GT(unseen, 0);
    EXPECT_LT(unseen, grid.VoxelCount());
  }
  // Seeing everything, an empty silhouette carves everything.
  {
    VisualHull hull(grid);
    ASSERT_TRUE(hull.Integrate(empty, ViewOf(StationRig(1000.0, 0.0, 60.0), 0.0)).has_value());
    EXPECT_EQ(hull.OccupiedCount(), 0);
  }
}

TEST(VisualHull, RejectsMasksThatDoNotMatchTheView) {
  VisualHull hull(Grid({-60, -60, 0}, {60, 60, 120}, 16));
  const View view = ViewOf(StationRig(), 0.0);
  Expected<void> result = hull.Integrate(cv::Mat(576, 767, CV_8UC1, cv::Scalar(0)), view);
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kBadInput);
  result = hull.Integrate(cv::Mat(576, 768, CV_8UC3, cv::Scalar(0)), view);
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kBadInput);
  EXPECT_EQ(hull.view_count(), 0);
  EXPECT_EQ(hull.OccupiedCount(), 16 * 16 * 16);
}

TEST(VisualHull, ContainsAgreesWithOccupancyAtVoxelCentres) {
  const Rig rig = StationRig();
  const VoxelGrid grid = Grid({-50, -50, 0}, {50, 50, 90}, 41);
  VisualHull hull(grid);
  std::mt19937 rng(3);
  for (double angle : {0.0, 50.0, 100.0, 160.0, 230.0}) {
    ASSERT_TRUE(hull.Integrate(IrregularMask(rig, angle, &rng), ViewOf(rig, angle)).has_value());
  }
  for (int k = 0; k < grid.dims.z(); ++k) {
    for (int j = 0; j < grid.dims.y(); ++j) {
      for (int i = 0; i < grid.dims.x(); ++i) {
        ASSERT_EQ(hull.Contains(grid.Centre(i, j, k)), hull.Occupied(i, j, k));
      }
    }
  }
  EXPECT_FALSE(hull.Contains(Eigen::Vector3d(0.0, 0.0, -0.1)));  // below the plate
}

TEST(VisualHull, SurfaceIsClosedAndLiesWithinTheGrid) {
  const Rig rig = StationRig();
  const VoxelGrid grid = Grid({-50, -50, 0}, {50, 50, 90}, 48);
  VisualHull hull(grid);
  // A sphere sunk 5 mm into the plate, and a blob above it.
  const std::vector<Sphere> spheres = {Sphere{{0.0, 0.0, 30.0}, 35.0},
                                       Sphere{{10.0, 5.0, 70.0}, 12.0}};
  for (double angle : {0.0, 40.0, 80.0, 120.0, 160.0}) {
    ASSERT_TRUE(hull.Integrate(SphereMask(rig, angle, spheres), ViewOf(rig, angle)).has_value());
  }
  const Mesh mesh = hull.ExtractSurface();
  ASSERT_FALSE(mesh.faces.empty());
  const MeshStats stats = ComputeStats(mesh);
  EXPECT_TRUE(stats.closed);
  EXPECT_TRUE(stats.oriented);
  EXPECT_GT(stats.volume_mm3, 0.0);
  // Vertices on edges leaving the grid sit exactly on the box (float rounding aside): the
  // base on the plate is flat at z = 0.
  for (const Eigen::Vector3f& v : mesh.vertices) {
    ASSERT_TRUE((v.cast<double>().array() >= grid.origin_mm.array() - 1e-5).all());
    ASSERT_TRUE((v.cast<double>().array() <= grid.MaxCorner().array() + 1e-5).all());
  }
  EXPECT_NEAR(stats.bbox_min_mm.z(), 0.0, 1e-6);
}

// ExtractSurface walks only the views that can cut each edge, in closed form; sampling every
// edge finely against every view, then bisecting the first step that leaves the hull, must
// place every vertex at the same position (to the bisection's precision), with and without a
// clip plane at `clip_z`.
void ExpectVerticesAtBruteForceFirstExit(const VisualHull& hull, double clip_z) {
  const VoxelGrid& grid = hull.grid();
  for (const bool clip : {false, true}) {
    SCOPED_TRACE(clip ? "clipped" : "not clipped");
    HullSurfaceOptions options;
    options.keep_largest_component = false;
    if (clip) options.clip_below_z_mm = clip_z;
    const Mesh mesh = hull.ExtractSurface(options);

    BitVolume field(grid.dims);
    for (int k = 0; k < grid.dims.z(); ++k) {
      for (int j = 0; j < grid.dims.y(); ++j) {
        for (int i = 0; i < grid.dims.x(); ++i) {
          field.Set(i, j, k,
                    hull.Occupied(i, j, k) && (!clip || grid.Centre(i, j, k).z() >= clip_z));
        }
      }
    }
    const EdgeCrossings brute_force = [&](const std::vector<GridEdge>& edges) {
      std::vector<double> ts;
      for (const GridEdge& e : edges) {
        const Eigen::Vector3d a = grid.Centre(e.inside.x(), e.inside.y(), e.inside.z());
        const Eigen::Vector3d d = grid.Centre(e.outside.x(), e.outside.y(), e.outside.z()) - a;
        const bool leaves =
            ((e.outside.array() < 0) || (e.outside.array() >= grid.dims.array())).any();
        double t_max = leaves ? 0.5 : 1.0;
        if (clip && d.z() < 0.0) t_max = std::min(t_max, (clip_z - a.z()) / d.z());
        constexpr int kSamples = 512;
        double t = t_max;
        for (int s = 1; s <= kSamples; ++s) {
          const double hi = t_max * s / kSamples;
          if (hull.SurvivesAllViews(a + hi * d)) continue;
          double lo = t_max * (s - 1) / kSamples;
          double h = hi;
          for (int step = 0; step < 40; ++step) {
            const double mid = 0.5 * (lo + h);
            (hull.SurvivesAllViews(a + mid * d) ? lo : h) = mid;
          }
          t = h;
          break;
        }
        ts.push_back(t);
      }
      return ts;
    };
    MarchingCubesOptions mc;
    mc.keep_largest_component = false;
    const Mesh expected =
        MarchingCubes(field, grid.Centre(0, 0, 0), grid.voxel_mm, brute_force, mc);
    ASSERT_EQ(mesh.vertices.size(), expected.vertices.size());
    ASSERT_EQ(mesh.faces, expected.faces);
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
      ASSERT_LT((mesh.vertices[v] - expected.vertices[v]).norm(), 1e-5 * grid.voxel_mm + 1e-5)
          << "vertex " << v;
    }
    EXPECT_GT(mesh.vertices.size(), 1000u);  // a non-trivial surface
    if (clip) {
      const MeshStats stats = ComputeStats(mesh);
      EXPECT_TRUE(stats.closed);
      EXPECT_TRUE(stats.oriented);
      EXPECT_NEAR(stats.bbox_min_mm.z(), clip_z, 1e-5);
    }
  }
}

TEST(VisualHull, SurfaceVerticesEqualBruteForceFirstExit) {
  const Rig rig = StationRig();
  const VoxelGrid grid = Grid({-50, -50, 0}, {50, 50, 90}, 40);
  VisualHull hull(grid);
  std::mt19937 rng(5);
  for (double angle : {0.0, 35.0, 70.0, 105.0, 140.0, 175.0, 210.0}) {
    ASSERT_TRUE(hull.Integrate(IrregularMask(rig, angle, &rng), ViewOf(rig, angle)).has_value());
  }
  ExpectVerticesAtBruteForceFirstExit(hull, 10.3);
}

TEST(VisualHull, SurfaceVerticesEqualBruteForceFirstExitWithThesisViews) {
  // The thesis's orthographic views (affine: w = 1 everywhere, lengths in pixels), silhouettes
  // with holes and bumps drawn in the image.
  constexpr int kWidth = 200;
  constexpr int kHeight = 150;
  const VoxelGrid grid = Grid({-70, -70, 0}, {70, 70, 140}, 44);
  VisualHull hull(grid);
  std::mt19937 rng(9);
  std::uniform_int_distribution<int> u(30, kWidth - 30);
  std::uniform_int_distribution<int> v(15, kHeight - 15);
  std::uniform_int_distribution<int> r(2, 12);
  for (double angle : {0.0, 30.0, 65.0, 100.0, 150.0, 220.0, 300.0}) {
    cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
    cv::ellipse(mask, cv::Point(kWidth / 2, kHeight / 2), cv::Size(45, 60), angle / 10.0, 0, 360,
                cv::Scalar(255), cv::FILLED);
    for (int i = 0; i < 14; ++i) {
      cv::circle(mask, cv::Point(u(rng), v(rng)), r(rng), cv::Scalar(i % 2 ? 255 : 0), cv::FILLED);
    }
    ASSERT_TRUE(hull.Integrate(mask, ThesisView(kWidth, kHeight, angle)).has_value());
  }
  ExpectVerticesAtBruteForceFirstExit(hull, 20.3);
}

}  // namespace
}  // namespace revolve::reconstruct

namespace revolve::reconstruct {
namespace {

// The consensus's cut (issue 17) without the dilation is the dilation's: random blobs, shifted
// against each other, near the borders, radii 0 to 7.
TEST(CutToDilated, IsTheMaskAndTheDilatedOthers) {
  cv::RNG rng(5);
  int differing = 0;
  for (int k = 0; k < 40; ++k) {
    cv::Mat mask(150, 200, CV_8UC1, cv::Scalar(0));
    cv::Mat others(150, 200, CV_8UC1, cv::Scalar(0));
    for (int b = 0; b < 3; ++b) {
      const cv::Point centre(rng.uniform(0, 200), rng.uniform(0, 150));
      const cv::Size axes(rng.uniform(3, 60), rng.uniform(3, 50));
      cv::ellipse(others, centre, axes, rng.uniform(0.0, 180.0), 0, 360, cv::Scalar(255),
                  cv::FILLED);
      cv::ellipse(mask, centre + cv::Point(rng.uniform(-9, 10), rng.uniform(-9, 10)),
                  axes + cv::Size(rng.uniform(0, 8), rng.uniform(0, 8)), rng.uniform(0.0, 180.0), 0,
                  360, cv::Scalar(k % 2 == 0 ? 255 : 1), cv::FILLED);
    }
    const int radius = k % 8;
    cv::Mat dilated;
    cv::dilate(
        others, dilated,
        cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1)));
    cv::Mat expected;
    cv::bitwise_and(mask, dilated, expected);
    const cv::Mat cut = CutToDilated(mask, others, radius);
    EXPECT_EQ(cv::countNonZero(cut != expected), 0) << k;
    differing += cv::countNonZero(expected != mask) > 0;
  }
  EXPECT_GT(differing, 20);  // the cut removed pixels in most cases
}

}  // namespace
}  // namespace revolve::reconstruct
