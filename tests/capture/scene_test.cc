// The synthetic scene's pure geometry: profile, volume, distance, ray intersection.
#include "capture/synthetic/scene.h"

#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

namespace revolve::capture {
namespace {

constexpr double kPi = std::numbers::pi;

Scene MakeScene(Shape shape, double radius_mm = 40.0, double height_mm = 100.0) {
  auto scene = Scene::Create(shape, radius_mm, height_mm);
  EXPECT_TRUE(scene.has_value());
  return *scene;
}

TEST(Shape, ParsesNamesAndRejectsOthers) {
  EXPECT_EQ(ParseShape("sphere").value(), Shape::kSphere);
  EXPECT_EQ(ParseShape("cylinder").value(), Shape::kCylinder);
  EXPECT_EQ(ParseShape("vase").value(), Shape::kVase);
  auto cube = ParseShape("cube");
  ASSERT_FALSE(cube.has_value());
  EXPECT_EQ(cube.error().code, ErrorCode::kBadInput);
  EXPECT_NE(cube.error().message.find("cube"), std::string::npos);
}

TEST(Scene, RejectsNonPositiveSizes) {
  EXPECT_FALSE(Scene::Create(Shape::kSphere, 0.0, 10.0).has_value());
  EXPECT_FALSE(Scene::Create(Shape::kCylinder, 10.0, -1.0).has_value());
  EXPECT_FALSE(Scene::Create(Shape::kVase, NAN, 10.0).has_value());
  // The sphere ignores the height.
  EXPECT_TRUE(Scene::Create(Shape::kSphere, 10.0, 0.0).has_value());
}

TEST(VaseProfile, HasItsDocumentedBellyNeckAndLip) {
  const double r = 40.0, h = 100.0;
  double max_r = 0.0, min_r = 1e9, z_max = 0.0, z_min = 0.0;
  for (int i = 0; i <= 10000; ++i) {
    const double z = h * i / 10000.0;
    const double radius = VaseRadiusMm(z, r, h);
    if (radius > max_r) max_r = radius, z_max = z;
    if (radius < min_r) min_r = radius, z_min = z;
    // The slope matches a central difference.
    if (i > 0 && i < 10000) {
      const double dz = 1e-5;
      const double numeric = (VaseRadiusMm(z + dz, r, h) - VaseRadiusMm(z - dz, r, h)) / (2 * dz);
      EXPECT_NEAR(VaseRadiusSlope(z, r, h), numeric, 1e-6);
    }
  }
  EXPECT_NEAR(max_r, r, 1e-9);                 // the belly is the largest radius
  EXPECT_NEAR(z_max, kVaseBellyAt * h, 0.01);  // at 0.35 h
  EXPECT_NEAR(min_r, 0.32 * r, 1e-6);          // the neck, >= 0.3 r
  EXPECT_NEAR(z_min, 0.85 * h, 0.01);
  EXPECT_GT(min_r, 0.3 * r);
  EXPECT_NEAR(VaseRadiusMm(0.0, r, h), VaseRadiusMm(h, r, h), 1e-9);  // foot = lip
  EXPECT_GT(VaseRadiusMm(h, r, h), VaseRadiusMm(0.95 * h, r, h));     // the lip flares out
}

TEST(Scene, VolumesMatchClosedFormsAndIntegration) {
  EXPECT_NEAR(MakeScene(Shape::kSphere, 40.0).VolumeMm3(), 4.0 / 3.0 * kPi * 64000.0, 1e-6);
  EXPECT_NEAR(MakeScene(Shape::kCylinder, 40.0, 100.0).VolumeMm3(), kPi * 1600.0 * 100.0, 1e-6);
  for (const auto& [r, h] : {std::pair{40.0, 100.0}, std::pair{25.0, 180.0}}) {
    // Simpson's rule on pi r(z)^2.
    const int n = 2000;
    double sum = 0.0;
    for (int i = 0; i <= n; ++i) {
      const double z = h * i / n;
      const double w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
      sum += w * kPi * std::pow(VaseRadiusMm(z, r, h), 2);
    }
    const double integral = sum * (h / n) / 3.0;
    EXPECT_NEAR(MakeScene(Shape::kVase, r, h).VolumeMm3(), integral, 1e-9 * integral);
  }
}

TEST(Scene, ContainsAgreesWithTheVolume) {
  // Count the centres of 1 mm cells inside each solid.
  for (Shape shape : {Shape::kSphere, Shape::kCylinder, Shape::kVase}) {
    const Scene scene = MakeScene(shape, 30.0, 70.0);
    const double r = scene.radius_mm();
    int inside = 0;
    for (double z = 0.5; z < scene.height_mm(); z += 1.0) {
      for (double y = -r + 0.5; y < r; y += 1.0) {
        for (double x = -r + 0.5; x < r; x += 1.0) inside += scene.Contains({x, y, z});
      }
    }
    EXPECT_NEAR(inside, scene.VolumeMm3(), 0.01 * scene.VolumeMm3()) << ToString(shape);
  }
}

TEST(Scene, SphereDistanceIsExact) {
  const Scene sphere = MakeScene(Shape::kSphere, 40.0);
  EXPECT_DOUBLE_EQ(sphere.DistanceMm({0, 0, 40}), 40.0);  // centre
  EXPECT_NEAR(sphere.DistanceMm({0, 0, 0}), 0.0, 1e-12);  // bottom pole
  EXPECT_NEAR(sphere.DistanceMm({30, 40, 40}), 10.0, 1e-12);
  EXPECT_NEAR(sphere.DistanceMm({0, -10, 40}), 30.0, 1e-12);
  const SceneTruth truth = sphere.Truth();
  ASSERT_TRUE(truth.sphere_center_mm.has_value() && truth.sphere_radius_mm.has_value());
  EXPECT_EQ(*truth.sphere_center_mm, Eigen::Vector3d(0, 0, 40));
  EXPECT_EQ(*truth.sphere_radius_mm, 40.0);
  EXPECT_EQ(truth.description, "sphere r=40 mm");
  EXPECT_DOUBLE_EQ(truth.volume_mm3, sphere.VolumeMm3());
  EXPECT_DOUBLE_EQ(truth.distance_mm(Eigen::Vector3d(0, 0, 95)), 15.0);
}

TEST(Scene, CylinderDistanceIsExact) {
  const Scene cylinder = MakeScene(Shape::kCylinder, 40.0, 100.0);
  EXPECT_NEAR(cylinder.DistanceMm({0, 0, 50}), 40.0, 1e-12);   // axis, mid-height: the side
  EXPECT_NEAR(cylinder.DistanceMm({0, 0, 90}), 10.0, 1e-12);   // near the top cap
  EXPECT_NEAR(cylinder.DistanceMm({0, 0, 103}), 3.0, 1e-12);   // above the top
  EXPECT_NEAR(cylinder.DistanceMm({0, 45, 50}), 5.0, 1e-12);   // beside
  EXPECT_NEAR(cylinder.DistanceMm({43, 0, 104}), 5.0, 1e-12);  // beyond the rim: 3-4-5
  EXPECT_NEAR(cylinder.DistanceMm({0, 38, -2}), 2.0, 1e-12);   // below the bottom
  EXPECT_NEAR(cylinder.DistanceMm({24, 32, 20}), 0.0, 1e-12);  // on the side
  const SceneTruth truth = cylinder.Truth();
  EXPECT_FALSE(truth.sphere_center_mm.has_value());
  EXPECT_EQ(truth.description, "cylinder r=40 mm h=100 mm");
}

TEST(Scene, VaseDistanceMatchesOffsetsAndBruteForce) {
  const double r = 40.0, h = 100.0;
  const Scene vase = MakeScene(Shape::kVase, r, h);
  // Points offset along the profile's normal by delta are |delta| away (delta below the radius
  // of curvature).
  for (double z = 1.0; z < h; z += 3.7) {
    const double radius = VaseRadiusMm(z, r, h);
    Eigen::Vector2d normal(1.0, -VaseRadiusSlope(z, r, h));  // (rho, z)
    normal.normalize();
    for (double delta : {-1.0, 0.0, 0.5, 2.0}) {
      const Eigen::Vector2d q = Eigen::Vector2d(radius, z) + delta * normal;
      if (q.y() < std::abs(delta) + 0.1 || q.y() > h - std::abs(delta) - 0.1) continue;
      const double phi = 0.37 * z;
      const Eigen::Vector3d p(q.x() * std::cos(phi), q.x() * std::sin(phi), q.y());
      EXPECT_NEAR(vase.DistanceMm(p), std::abs(delta), 1e-4) << "z=" << z << " delta=" << delta;
    }
  }
  EXPECT_NEAR(vase.DistanceMm({0, 0, -3}), 3.0, 1e-9);     // below the foot's cap
  EXPECT_NEAR(vase.DistanceMm({0, 0, h + 2}), 2.0, 1e-9);  // above the lip's cap
  // Against a brute-force minimum over a dense sampling of the meridian boundary.
  std::vector<Eigen::Vector2d> boundary;
  const int n = 200000;
  for (int i = 0; i <= n; ++i) {
    const double z = h * i / n;
    boundary.emplace_back(VaseRadiusMm(z, r, h), z);
  }
  for (int i = 0; i <= 2000; ++i) {
    boundary.emplace_back(VaseRadiusMm(0, r, h) * i / 2000, 0.0);
    boundary.emplace_back(VaseRadiusMm(h, r, h) * i / 2000, h);
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> xy(-60.0, 60.0), zs(-20.0, 120.0);
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::Vector3d p(xy(rng), xy(rng), zs(rng));
    const Eigen::Vector2d q(p.head<2>().norm(), p.z());
    double best = 1e9;
    for (const auto& b : boundary) best = std::min(best, (b - q).norm());
    EXPECT_NEAR(vase.DistanceMm(p), best, 2e-3) << p.transpose();
  }
}

// A ray through the solid's region, checked against dense sampling of Contains.
class IntersectTest : public ::testing::TestWithParam<Shape> {};

TEST_P(IntersectTest, AgreesWithSamplingAndLandsOnTheSurface) {
  const Scene scene = MakeScene(GetParam(), 40.0, 100.0);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int rays = 0, hits = 0, disagreements = 0;
  for (int trial = 0; trial < 600; ++trial) {
    // From a point 300 mm away toward a random point near the solid.
    const Eigen::Vector3d origin =
        Eigen::Vector3d(unit(rng), unit(rng), 0.5 * unit(rng)).normalized() * 300.0 +
        Eigen::Vector3d(0, 0, 50);
    const Eigen::Vector3d aim(45 * unit(rng), 45 * unit(rng), 55 + 55 * unit(rng));
    const Eigen::Vector3d direction = (aim - origin).normalized();
    const std::optional<RayHit> hit = scene.Intersect(origin, direction);
    EXPECT_EQ(hit.has_value(), scene.Hits(origin, direction));
    // First sample inside, at a 0.01 mm step.
    std::optional<double> first_inside;
    for (double t = 150.0; t < 450.0; t += 0.01) {
      if (scene.Contains(origin + t * direction)) {
        first_inside = t;
        break;
      }
    }
    ++rays;
    if (hit.has_value() != first_inside.has_value()) {
      // Only a grazing ray may disagree with sampling: one passing within a hair of the surface.
      double closest = 1e9;
      for (double t = 150.0; t < 450.0; t += 0.01) {
        closest = std::min(closest, scene.DistanceMm(origin + t * direction));
      }
      EXPECT_LT(closest, 0.01);
      ++disagreements;
      continue;
    }
    if (!hit) continue;
    ++hits;
    EXPECT_NEAR(hit->t, *first_inside, 0.011);
    EXPECT_NEAR(scene.DistanceMm(hit->point), 0.0, 1e-4);
    EXPECT_NEAR(hit->normal.norm(), 1.0, 1e-9);
    EXPECT_LE(hit->normal.dot(direction), 1e-9);  // the ray enters against the normal
    // Just outside along the normal is outside; just inside is inside.
    EXPECT_FALSE(scene.Contains(hit->point + 1e-3 * hit->normal));
    EXPECT_TRUE(scene.Contains(hit->point - 1e-3 * hit->normal));
  }
  EXPECT_GT(hits, rays / 4);
  EXPECT_LE(disagreements, 3);
}

INSTANTIATE_TEST_SUITE_P(Shapes, IntersectTest,
                         ::testing::Values(Shape::kSphere, Shape::kCylinder, Shape::kVase),
                         [](const auto& p) { return std::string(ToString(p.param)); });

}  // namespace
}  // namespace revolve::capture
