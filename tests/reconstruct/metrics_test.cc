// Mesh statistics, distances to a truth, sphere fit.
#include "reconstruct/metrics/metrics.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace revolve::reconstruct {
namespace {

// An axis-aligned cube [0, a]^3, 12 triangles, outward.
Mesh Cube(float a) {
  Mesh mesh;
  for (int c = 0; c < 8; ++c) {
    mesh.vertices.emplace_back(a * (c & 1), a * ((c >> 1) & 1), a * ((c >> 2) & 1));
  }
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    mesh.faces.emplace_back(q[0], q[1], q[2]);
    mesh.faces.emplace_back(q[0], q[2], q[3]);
  }
  return mesh;
}

TEST(Metrics, CubeStats) {
  const MeshStats stats = ComputeStats(Cube(2.0f));
  EXPECT_EQ(stats.vertex_count, 8);
  EXPECT_EQ(stats.triangle_count, 12);
  EXPECT_NEAR(stats.area_mm2, 24.0, 1e-9);
  EXPECT_NEAR(stats.volume_mm3, 8.0, 1e-9);
  EXPECT_TRUE(stats.closed);
  EXPECT_TRUE(stats.oriented);
  EXPECT_TRUE(stats.bbox_min_mm.isZero());
  EXPECT_TRUE(stats.bbox_max_mm.isApprox(Eigen::Vector3d(2, 2, 2)));
}

TEST(Metrics, DetectsOpenAndMisorientedMeshes) {
  Mesh flipped = Cube(1.0f);
  std::swap(flipped.faces[3][1], flipped.faces[3][2]);
  MeshStats stats = ComputeStats(flipped);
  EXPECT_TRUE(stats.closed);
  EXPECT_FALSE(stats.oriented);

  Mesh open = Cube(1.0f);
  open.faces.pop_back();
  stats = ComputeStats(open);
  EXPECT_FALSE(stats.closed);
  EXPECT_TRUE(stats.oriented);

  Mesh doubled = Cube(1.0f);
  doubled.faces.push_back(doubled.faces[0]);
  EXPECT_FALSE(ComputeStats(doubled).closed);
  EXPECT_FALSE(ComputeStats(doubled).oriented);

  Mesh inside_out = Cube(1.0f);
  for (Eigen::Vector3i& f : inside_out.faces) std::swap(f[1], f[2]);
  stats = ComputeStats(inside_out);
  EXPECT_TRUE(stats.closed && stats.oriented);
  EXPECT_NEAR(stats.volume_mm3, -1.0, 1e-9);

  EXPECT_FALSE(ComputeStats(Mesh{}).closed);
}

// A torus of u x v quads (two triangles each), closed and outward-oriented: large enough that
// its vertices' edges are checked in many chunks.
Mesh Torus(int u, int v) {
  Mesh mesh;
  for (int i = 0; i < u; ++i) {
    for (int j = 0; j < v; ++j) {
      const double a = 2.0 * M_PI * i / u;
      const double b = 2.0 * M_PI * j / v;
      mesh.vertices.emplace_back(static_cast<float>((3.0 + std::cos(b)) * std::cos(a)),
                                 static_cast<float>((3.0 + std::cos(b)) * std::sin(a)),
                                 static_cast<float>(std::sin(b)));
    }
  }
  const auto at = [&](int i, int j) { return (i % u) * v + (j % v); };
  for (int i = 0; i < u; ++i) {
    for (int j = 0; j < v; ++j) {
      mesh.faces.emplace_back(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      mesh.faces.emplace_back(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
  }
  return mesh;
}

TEST(Metrics, FindsOneFlawAnywhereInALargeMesh) {
  const Mesh torus = Torus(300, 200);  // 60000 vertices
  MeshStats stats = ComputeStats(torus);
  EXPECT_TRUE(stats.closed && stats.oriented);
  EXPECT_NEAR(stats.volume_mm3, 2.0 * M_PI * M_PI * 3.0, 0.05);  // 2 pi^2 R r^2
  for (const std::size_t face : {std::size_t{0}, torus.faces.size() / 2, torus.faces.size() - 1}) {
    Mesh flipped = torus;
    std::swap(flipped.faces[face][1], flipped.faces[face][2]);
    stats = ComputeStats(flipped);
    EXPECT_TRUE(stats.closed) << face;
    EXPECT_FALSE(stats.oriented) << face;
    Mesh open = torus;
    open.faces.erase(open.faces.begin() + static_cast<std::ptrdiff_t>(face));
    stats = ComputeStats(open);
    EXPECT_FALSE(stats.closed) << face;
    EXPECT_TRUE(stats.oriented) << face;
  }
}

TEST(Metrics, DistanceToAPlane) {
  // The top face of the cube at z = 2 lies 0.5 above the plane z = 1.5; its bottom face 1.5
  // below. Vertices: half at each.
  const Mesh cube = Cube(2.0f);
  const DistanceToTruth plane = [](const Eigen::Vector3d& p) { return std::abs(p.z() - 1.5); };
  const DistanceStats v = VertexDistance(cube, plane);
  EXPECT_EQ(v.samples, 8);
  EXPECT_NEAR(v.mean_mm, 1.0, 1e-9);
  EXPECT_NEAR(v.max_mm, 1.5, 1e-9);
  EXPECT_NEAR(v.rms_mm, std::sqrt((0.25 + 2.25) / 2.0), 1e-9);
  EXPECT_NEAR(v.p90_mm, 1.5, 1e-9);
  // By area: the mean of |z - 1.5| over the cube's surface: top 0.5 (area 4), bottom 1.5 (4),
  // sides: mean of |z - 1.5| for z uniform in [0, 2] = (1.5^2 + 0.5^2) / 4 = 0.625 (area 16).
  const DistanceStats s = SurfaceDistance(cube, plane, 200000, 42);
  EXPECT_NEAR(s.mean_mm, (4 * 0.5 + 4 * 1.5 + 16 * 0.625) / 24.0, 0.01);
  EXPECT_LE(s.max_mm, 1.5 + 1e-9);
  EXPECT_EQ(SurfaceDistance(cube, plane, 1000, 7).mean_mm,
            SurfaceDistance(cube, plane, 1000, 7).mean_mm);  // deterministic
}

TEST(Metrics, SphereFitRecoversAKnownSphere) {
  Mesh mesh;
  std::mt19937 rng(2);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector3d centre(3.0, -7.0, 41.0);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector3d d = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
    mesh.vertices.push_back((centre + 25.0 * d).cast<float>());
  }
  const SphereFit fit = FitSphere(mesh);
  ASSERT_TRUE(fit.ok);
  EXPECT_NEAR(fit.radius_mm, 25.0, 1e-4);
  EXPECT_LT((fit.centre_mm - centre).norm(), 1e-4);
  EXPECT_LT(fit.rms_residual_mm, 1e-4);

  Mesh few;
  few.vertices = {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(1, 0, 0), Eigen::Vector3f(0, 1, 0)};
  EXPECT_FALSE(FitSphere(few).ok);
  Mesh planar = few;
  planar.vertices.emplace_back(1, 1, 0);
  planar.vertices.emplace_back(2, 1, 0);
  EXPECT_FALSE(FitSphere(planar).ok);
}

}  // namespace
}  // namespace revolve::reconstruct
