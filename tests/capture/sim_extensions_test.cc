// The simulated camera's extensions: more analytic shapes, meshes from the shared data,
// orthographic projection, axis offset, backdrop / plate / fixtures, blur, the empty scene and
// the ground truth exported with each frame.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "capture/segmenter.h"
#include "capture/synthetic/mesh.h"
#include "capture/synthetic/synthetic_camera.h"

namespace revolve::capture {
namespace {

constexpr double kPi = std::numbers::pi;
const std::string kMeshes = std::string(REVOLVE_SHARED_DIR) + "/data/meshes/";

double IoU(const cv::Mat& a, const cv::Mat& b) {
  const double inter = cv::countNonZero(a & b);
  const double uni = cv::countNonZero(a | b);
  return uni > 0 ? inter / uni : 1.0;
}

struct ShapeCase {
  Shape shape;
  double radius_mm, height_mm;
};

class NewShapeTest : public ::testing::TestWithParam<ShapeCase> {};

TEST_P(NewShapeTest, IntersectAgreesWithContainsAndTheDistanceVanishesOnHits) {
  const ShapeCase c = GetParam();
  auto scene = Scene::Create(c.shape, c.radius_mm, c.height_mm);
  ASSERT_TRUE(scene.has_value()) << scene.error().ToString();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int hits = 0, disagreements = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Eigen::Vector3d origin =
        Eigen::Vector3d(unit(rng), unit(rng), 0.5 * unit(rng)).normalized() * 300.0 +
        Eigen::Vector3d(0, 0, 50);
    const Eigen::Vector3d aim(50 * unit(rng), 50 * unit(rng), 55 + 55 * unit(rng));
    const Eigen::Vector3d direction = (aim - origin).normalized();
    const auto hit = scene->Intersect(origin, direction);
    EXPECT_EQ(hit.has_value(), scene->Hits(origin, direction));
    std::optional<double> first_inside;
    for (double t = 150.0; t < 450.0; t += 0.01) {
      if (scene->Contains(origin + t * direction)) {
        first_inside = t;
        break;
      }
    }
    if (hit.has_value() != first_inside.has_value()) {
      ++disagreements;  // grazing
      continue;
    }
    if (!hit) continue;
    ++hits;
    EXPECT_NEAR(hit->t, *first_inside, 0.011);
    EXPECT_NEAR(scene->DistanceMm(hit->point), 0.0, 1e-4);
    EXPECT_LE(hit->normal.dot(direction), 1e-9);
    EXPECT_FALSE(scene->Contains(hit->point + 1e-3 * hit->normal));
  }
  EXPECT_GT(hits, 50);
  EXPECT_LE(disagreements, 3);
}

TEST_P(NewShapeTest, VolumeMatchesMonteCarloAndTheTessellation) {
  const ShapeCase c = GetParam();
  auto scene = Scene::Create(c.shape, c.radius_mm, c.height_mm);
  ASSERT_TRUE(scene.has_value());
  std::mt19937 rng(9);
  const double r = scene->bounding_radius_mm(), h = scene->height_mm();
  std::uniform_real_distribution<double> x(-r, r), z(0.0, h);
  int inside = 0;
  const int samples = 200000;
  for (int i = 0; i < samples; ++i) inside += scene->Contains({x(rng), x(rng), z(rng)});
  const double box = 4.0 * r * r * h;
  EXPECT_NEAR(scene->VolumeMm3(), box * inside / samples, 0.01 * box);
  const TriangleMesh surface = scene->Tessellate(128);
  EXPECT_NEAR(MeshVolume(surface), scene->VolumeMm3(), 0.01 * scene->VolumeMm3());
  // Every tessellation vertex lies on the surface.
  for (std::size_t i = 0; i < surface.vertices.size(); i += 97) {
    EXPECT_NEAR(scene->DistanceMm(surface.vertices[i]), 0.0, 1e-6);
  }
}

INSTANTIATE_TEST_SUITE_P(Shapes, NewShapeTest,
                         ::testing::Values(ShapeCase{Shape::kCone, 40.0, 100.0},
                                           ShapeCase{Shape::kBox, 30.0, 80.0},
                                           ShapeCase{Shape::kTorus, 45.0, 24.0}),
                         [](const auto& p) { return std::string(ToString(p.param.shape)); });

TEST(Mesh, ReadsTheSharedMeshes) {
  auto spot = ReadMesh(kMeshes + "spot.obj");
  ASSERT_TRUE(spot.has_value()) << spot.error().ToString();
  EXPECT_GT(spot->triangles.size(), 5000u);
  EXPECT_GT(MeshVolume(*spot), 0.0);  // closed and outward
  auto bunny = ReadMesh(kMeshes + "bun_zipper_res4.ply");
  ASSERT_TRUE(bunny.has_value()) << bunny.error().ToString();
  EXPECT_EQ(bunny->vertices.size(), 453u);
  EXPECT_EQ(bunny->triangles.size(), 948u);
  EXPECT_EQ(ReadMesh(kMeshes + "nothing.obj").error().code, ErrorCode::kNotFound);
}

TEST(Mesh, ReadsAsciiAndBinaryPlyAlikeAndWritesPly) {
  auto ascii = ReadMesh(kMeshes + "bun_zipper_res4.ply");
  ASSERT_TRUE(ascii.has_value());
  const auto dir = std::filesystem::temp_directory_path() / "revolve_mesh_test";
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(WritePlyAscii(*ascii, dir / "copy.ply").has_value());
  auto copy = ReadMesh(dir / "copy.ply");
  ASSERT_TRUE(copy.has_value());
  EXPECT_EQ(copy->triangles, ascii->triangles);
  // A binary little-endian PLY of one triangle with an extra property.
  std::string binary =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float "
      "y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int "
      "vertex_indices\nend_header\n";
  auto put = [&](const void* p, std::size_t n) { binary.append(static_cast<const char*>(p), n); };
  const float v[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  for (const auto& vertex : v) {
    put(vertex, sizeof(vertex));
    const unsigned char red = 200;
    put(&red, 1);
  }
  const unsigned char count = 3;
  const int indices[3] = {0, 1, 2};
  put(&count, 1);
  put(indices, sizeof(indices));
  {
    std::ofstream out(dir / "tri.ply", std::ios::binary);
    out << binary;
  }
  auto triangle = ReadMesh(dir / "tri.ply");
  ASSERT_TRUE(triangle.has_value()) << triangle.error().ToString();
  EXPECT_EQ(triangle->vertices[1], Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(triangle->triangles.size(), 1u);
  std::filesystem::remove_all(dir);
}

TEST(Mesh, DistanceGridAgreesWithBruteForce) {
  auto spot = ReadMesh(kMeshes + "spot.obj");
  ASSERT_TRUE(spot.has_value());
  auto shared = std::make_shared<const TriangleMesh>(*spot);
  const MeshGrid grid(shared);
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    double best = 1e9;
    for (const auto& t : spot->triangles) {
      best = std::min(best, PointTriangleDistance(p, spot->vertices[t[0]], spot->vertices[t[1]],
                                                  spot->vertices[t[2]]));
    }
    EXPECT_NEAR(grid.Distance(p), best, 1e-12);
  }
}

struct MeshCase {
  std::string file;
  std::string method;
  double elevation_deg;
};

class MeshSegmentTest : public ::testing::TestWithParam<MeshCase> {};

// Meshes render through the z-buffer and segment like any object.
TEST_P(MeshSegmentTest, SegmentsToTheTrueMask) {
  const MeshCase c = GetParam();
  SyntheticOptions o;
  o.object = "mesh";
  o.mesh_path = kMeshes + c.file;
  o.height_mm = 90.0;
  o.elevation_deg = c.elevation_deg;
  auto camera = SyntheticCamera::Create(o, std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(camera.has_value()) << camera.error().ToString();
  const auto truth = (*camera)->KnownScene();
  ASSERT_TRUE(truth.has_value());
  EXPECT_GT(truth->mesh_triangles.size(), 900u);
  EXPECT_NEAR(truth->distance_mm(truth->mesh_vertices_mm[10]), 0.0, 1e-9);
  const auto ply = std::filesystem::temp_directory_path() / ("revolve_truth_" + c.method + ".ply");
  ASSERT_TRUE(WriteTruthMeshPly(*truth, ply).has_value());
  auto reread = ReadMesh(ply);
  ASSERT_TRUE(reread.has_value());
  EXPECT_EQ(reread->triangles.size(), truth->mesh_triangles.size());
  std::filesystem::remove(ply);
  for (double angle : {0.0, 135.0}) {
    const RenderOutput frame = (*camera)->RenderWithTruth(angle, 2);
    EXPECT_GT(cv::countNonZero(frame.true_mask), 10000);
    SegmentOptions s;
    s.method = c.method;
    const cv::Mat background = (*camera)->RenderWithTruth(angle, 99, false).image;
    auto mask = (*CreateSegmenter(s))->Segment(frame.image, background);
    ASSERT_TRUE(mask.has_value());
    const double iou = IoU(*mask, frame.true_mask);
    std::printf("IoU mesh %-22s %-10s %5.1f deg: %.4f\n", c.file.c_str(), c.method.c_str(), angle,
                iou);
    EXPECT_GE(iou, 0.99);
  }
}

INSTANTIATE_TEST_SUITE_P(Meshes, MeshSegmentTest,
                         ::testing::Values(MeshCase{"spot.obj", "otsu", 15.0},
                                           MeshCase{"bun_zipper_res2.ply", "otsu", 0.0},
                                           MeshCase{"bun_zipper_res4.ply", "background", 25.0}),
                         [](const auto& p) {
                           std::string name = p.param.file.substr(0, p.param.file.find('.'));
                           return name + "_" + p.param.method;
                         });

TEST(Orthographic, ASphereIsACircleOfTheTrueRadiusAndTheViewIsAffine) {
  SyntheticOptions o;
  o.object = "sphere";
  o.projection = "orthographic";
  o.elevation_deg = 30.0;
  o.target_height_mm = 40.0;
  o.noise_sigma = 0.0;
  auto camera = SyntheticCamera::Create(o, std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(camera.has_value());
  EXPECT_FALSE((*camera)->KnownRig().has_value());  // not a pinhole
  const auto view = (*camera)->KnownView(20.0);
  ASSERT_TRUE(view.has_value());
  EXPECT_TRUE(view->IsAffine());
  const double m = (*camera)->projection().px_per_mm;
  const cv::Mat mask = (*camera)->TrueMask(20.0);
  // Area of a circle of radius m r (a perspective view would be larger and elliptical).
  const double r_px = m * o.radius_mm;
  EXPECT_NEAR(cv::countNonZero(mask), kPi * r_px * r_px, 2.0 * kPi * r_px);
  // The centre (0, 0, r) projects where the view says.
  Eigen::Vector2d centre;
  ASSERT_TRUE(view->Project(Eigen::Vector3d(0, 0, o.radius_mm), &centre));
  const cv::Moments mo = cv::moments(mask, true);
  EXPECT_NEAR(mo.m10 / mo.m00, centre.x(), 0.05);
  EXPECT_NEAR(mo.m01 / mo.m00, centre.y(), 0.05);
}

TEST(AxisOffset, MovesTheAxisOffTheMiddleColumn) {
  SyntheticOptions o;
  o.object = "cylinder";
  o.axis_offset_px = 37.0;
  o.noise_sigma = 0.0;
  auto camera = SyntheticCamera::Create(o, std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(camera.has_value());
  const cv::Mat mask = (*camera)->TrueMask(0.0);
  const cv::Moments mo = cv::moments(mask, true);
  EXPECT_NEAR(mo.m10 / mo.m00, (o.width_px - 1) / 2.0 + 37.0, 0.1);
}

TEST(Stage, BackgroundFrameHasNoObjectAndFramesCarryTheirTruth) {
  SyntheticOptions o;
  o.plate_radius_mm = 60.0;
  o.fixture_mm = {85.0, -6.0, -8.0, 97.0, 6.0, 80.0};
  o.elevation_deg = 15.0;
  auto plate = std::make_shared<SimulatedPlate>();
  auto camera = SyntheticCamera::Create(o, plate);
  ASSERT_TRUE(camera.has_value());
  ASSERT_TRUE((*camera)->Start().has_value());
  plate->angle_deg = 40.0;
  auto frame = (*camera)->Capture(Clock::now(), std::chrono::seconds(1));
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->plate_angle_deg, 40.0);
  EXPECT_EQ(cv::norm(frame->true_mask, (*camera)->TrueMask(40.0), cv::NORM_INF), 0.0);
  auto background = (*camera)->CaptureBackground(Clock::now(), std::chrono::seconds(1));
  ASSERT_TRUE(background.has_value());
  EXPECT_EQ(cv::countNonZero(background->true_mask), 0);
  // Where the object was, the background frame shows backdrop or plate; elsewhere the two
  // frames agree up to noise.
  cv::Mat diff;
  cv::absdiff(frame->image, background->image, diff);
  cv::Mat grey;
  cv::cvtColor(diff, grey, cv::COLOR_BGR2GRAY);
  cv::Mat outside;
  cv::dilate(frame->true_mask, outside, cv::Mat(), cv::Point(-1, -1), 2);
  outside = outside == 0;
  double max_outside = 0;
  cv::minMaxLoc(grey, nullptr, &max_outside, nullptr, nullptr, outside);
  EXPECT_LT(max_outside, 30.0);
  EXPECT_GT(cv::mean(grey, frame->true_mask)[0], 60.0);
}

TEST(Stage, BlurSoftensEdges) {
  SyntheticOptions sharp_options;
  sharp_options.noise_sigma = 0.0;
  SyntheticOptions blurred_options = sharp_options;
  blurred_options.blur_sigma_px = 2.0;
  auto sharp = SyntheticCamera::Create(sharp_options, std::make_shared<SimulatedPlate>());
  auto blurred = SyntheticCamera::Create(blurred_options, std::make_shared<SimulatedPlate>());
  auto gradient = [](const cv::Mat& image) {
    cv::Mat grey, gx;
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
    cv::Sobel(grey, gx, CV_32F, 1, 0);
    double max = 0;
    cv::minMaxLoc(cv::abs(gx), nullptr, &max);
    return max;
  };
  EXPECT_LT(gradient((*blurred)->Render(0.0, 0)), 0.5 * gradient((*sharp)->Render(0.0, 0)));
}

TEST(RenderSpeed, FramesRenderQuickly) {
  // Not asserted (speed is for benchmarks): printed for the record.
  for (const std::string object : {"vase", "torus", "mesh"}) {
    SyntheticOptions o;
    o.object = object;
    if (object == "torus") o.radius_mm = 45.0, o.height_mm = 30.0;
    if (object == "mesh") o.mesh_path = kMeshes + "spot.obj";
    o.plate_radius_mm = 60.0;
    auto camera = SyntheticCamera::Create(o, std::make_shared<SimulatedPlate>());
    ASSERT_TRUE(camera.has_value());
    const auto start = std::chrono::steady_clock::now();
    (void)(*camera)->Render(30.0, 0);
    std::printf("render 768x576 %s: %.1f ms\n", object.c_str(),
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                    .count());
  }
}

}  // namespace
}  // namespace revolve::capture
