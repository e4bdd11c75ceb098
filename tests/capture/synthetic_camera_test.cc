// The synthetic camera: silhouette geometry, the object turning with the plate, rendering,
// capture timing.
#include "capture/synthetic/synthetic_camera.h"

#include <chrono>
#include <cmath>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "capture/camera.h"

namespace revolve::capture {
namespace {

using std::chrono::milliseconds;

std::unique_ptr<SyntheticCamera> MakeCamera(const SyntheticOptions& options,
                                            std::shared_ptr<SimulatedPlate> plate = nullptr) {
  if (plate == nullptr) plate = std::make_shared<SimulatedPlate>();
  auto camera = SyntheticCamera::Create(options, std::move(plate));
  EXPECT_TRUE(camera.has_value()) << (camera ? "" : camera.error().ToString());
  return camera ? std::move(*camera) : nullptr;
}

SyntheticOptions Options(const std::string& object, double elevation_deg = 0.0) {
  SyntheticOptions options;
  options.object = object;
  options.elevation_deg = elevation_deg;
  return options;
}

cv::Point2d Centroid(const cv::Mat& mask) {
  const cv::Moments m = cv::moments(mask, /*binaryImage=*/true);
  return {m.m10 / m.m00, m.m01 / m.m00};
}

// The sphere's silhouette is the conic of its tangent cone: with c the sphere's centre in the
// camera frame, pixel p is inside when p^T M p > 0, M = K^-T (c c^T - (|c|^2 - r^2) I) K^-1.
Eigen::Matrix3d SphereConic(const Rig& rig, double plate_angle_deg, double radius_mm) {
  const Eigen::Vector3d c = rig.CamFromObject(plate_angle_deg) * Eigen::Vector3d(0, 0, radius_mm);
  const Eigen::Matrix3d q =
      c * c.transpose() - (c.squaredNorm() - radius_mm * radius_mm) * Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d k_inv = rig.intrinsics.K().inverse();
  return k_inv.transpose() * q * k_inv;
}

class SphereSilhouetteTest : public ::testing::TestWithParam<double> {};

TEST_P(SphereSilhouetteTest, IsTheTangentConeConicCentredOnTheMiddleColumn) {
  const double elevation_deg = GetParam();
  auto camera = MakeCamera(Options("sphere", elevation_deg));
  const Rig& rig = camera->rig();
  const double cx = rig.intrinsics.cx_px;
  for (double angle_deg : {0.0, 37.0, 90.0, 200.0, -45.5}) {
    const cv::Mat mask = camera->TrueMask(angle_deg);
    ASSERT_EQ(mask.type(), CV_8UC1);
    ASSERT_EQ(mask.size(), cv::Size(768, 576));
    const double area = cv::countNonZero(mask);
    // Centroid on the middle column (the axis projects there).
    EXPECT_NEAR(Centroid(mask).x, cx, 0.5) << angle_deg;
    // Area of the ellipse p^T M p = 0: pi |det M| / det(M_2x2)^(3/2).
    const Eigen::Matrix3d conic = SphereConic(rig, angle_deg, 40.0);
    const double det2 = conic.topLeftCorner<2, 2>().determinant();
    ASSERT_GT(det2, 0.0);
    const double conic_area =
        std::numbers::pi * std::abs(conic.determinant()) / std::pow(det2, 1.5);
    EXPECT_NEAR(area, conic_area, 0.005 * conic_area) << angle_deg;
    // Pixel by pixel, the mask is the conic's inside (up to pixels the boundary passes through).
    int mismatches = 0;
    for (int v = 0; v < mask.rows; ++v) {
      for (int u = 0; u < mask.cols; ++u) {
        const Eigen::Vector3d p(u, v, 1.0);
        const bool inside = p.dot(conic * p) > 0.0;
        mismatches += inside != (mask.at<std::uint8_t>(v, u) != 0);
      }
    }
    EXPECT_LE(mismatches, 2) << angle_deg;
  }
}

INSTANTIATE_TEST_SUITE_P(Elevations, SphereSilhouetteTest, ::testing::Values(0.0, 20.0));

TEST(SphereSilhouette, OnTheOpticalAxisIsACircleOfRadiusFrOverSqrtD2MinusR2) {
  SyntheticOptions options = Options("sphere");
  options.target_height_mm = options.radius_mm;  // the centre on the optical axis
  auto camera = MakeCamera(options);
  const double f = camera->rig().intrinsics.fx_px;
  const double d = options.distance_mm, r = options.radius_mm;
  const double expected_radius_px = f * r / std::sqrt(d * d - r * r);
  const cv::Mat mask = camera->TrueMask(123.0);
  const double radius_px = std::sqrt(cv::countNonZero(mask) / std::numbers::pi);
  EXPECT_NEAR(radius_px, expected_radius_px, 0.005 * expected_radius_px);
  const cv::Point2d centroid = Centroid(mask);
  EXPECT_NEAR(centroid.x, camera->rig().intrinsics.cx_px, 0.05);
  EXPECT_NEAR(centroid.y, camera->rig().intrinsics.cy_px, 0.05);
}

// Pixels of the magenta marker (object +x side at mid-height).
cv::Mat MarkerPixels(const cv::Mat& bgr) {
  cv::Mat channels[3];
  cv::split(bgr, channels);
  cv::Mat g2;
  channels[1].convertTo(g2, CV_8U, 2.0);  // saturates
  return (channels[0] > 120) & (channels[2] > 120) & (g2 < channels[0]) & (g2 < channels[2]);
}

TEST(SyntheticCamera, ObjectTurnsWithThePlate) {
  // The camera stands on the table's -y side; the marker at object +x faces it at -90 deg and
  // appears right of the axis at -60 deg and left of it at -120 deg.
  SyntheticOptions options = Options("vase", 10.0);
  options.noise_sigma = 0.0;
  auto camera = MakeCamera(options);
  const double cx = camera->rig().intrinsics.cx_px;
  for (const auto& [angle_deg, side] :
       {std::pair{-90.0, 0}, std::pair{-60.0, 1}, std::pair{-120.0, -1}, std::pair{90.0, 2}}) {
    const cv::Mat marker = MarkerPixels(camera->Render(angle_deg, 0));
    const int count = cv::countNonZero(marker);
    if (side == 2) {  // facing away: hidden
      EXPECT_EQ(count, 0);
      continue;
    }
    ASSERT_GT(count, 100) << angle_deg;
    const cv::Point2d centroid = Centroid(marker);
    // The marker's centre projects near the centroid of its pixels.
    Eigen::Vector2d projected;
    View view{camera->rig().PixelFromObject(angle_deg), 768, 576};
    ASSERT_TRUE(view.Project(MarkerCenter(camera->scene()), &projected));
    EXPECT_NEAR(centroid.x, projected.x(), 4.0) << angle_deg;
    EXPECT_NEAR(centroid.y, projected.y(), 4.0) << angle_deg;
    if (side == 0) {
      EXPECT_NEAR(centroid.x, cx, 1.0);
    } else if (side == 1) {
      EXPECT_GT(centroid.x, cx + 40.0);
    } else {
      EXPECT_LT(centroid.x, cx - 40.0);
    }
  }
}

TEST(SyntheticCamera, TrueMaskFollowsThePlateForAnOffAxisDetail) {
  // The vase is symmetric; its marker is not. The marker's projected centre moves from the
  // right to the left of the axis as the plate turns from -60 to -120 deg, and the rendered
  // marker follows (above); the true mask itself is the same at every angle.
  auto camera = MakeCamera(Options("vase"));
  const cv::Mat a = camera->TrueMask(-60.0), b = camera->TrueMask(-120.0);
  EXPECT_EQ(cv::countNonZero(a != b), 0);
  const Matrix34d p_right = camera->rig().PixelFromObject(-60.0);
  const Matrix34d p_left = camera->rig().PixelFromObject(-120.0);
  const Eigen::Vector4d marker = MarkerCenter(camera->scene()).homogeneous();
  const Eigen::Vector3d right = p_right * marker, left = p_left * marker;
  EXPECT_GT(right.x() / right.z(), camera->rig().intrinsics.cx_px);
  EXPECT_LT(left.x() / left.z(), camera->rig().intrinsics.cx_px);
}

TEST(SyntheticCamera, RenderedFrameLooksLikeAPhoto) {
  SyntheticOptions options = Options("cylinder");
  auto camera = MakeCamera(options);
  const cv::Mat frame = camera->Render(0.0, 0);
  ASSERT_EQ(frame.type(), CV_8UC3);
  const cv::Mat truth = camera->TrueMask(0.0);
  cv::Mat grey;
  cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
  // Backdrop: its grey level with the requested noise; object: much brighter everywhere.
  cv::Mat backdrop;
  cv::erode(truth == 0, backdrop, cv::Mat(), cv::Point(-1, -1), 2);
  cv::Scalar mean, stddev;
  cv::meanStdDev(frame, mean, stddev, backdrop);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(mean[c], options.backdrop_grey, 0.2);
    EXPECT_NEAR(stddev[c], options.noise_sigma, 0.2);
  }
  cv::Mat object;
  cv::erode(truth, object, cv::Mat(), cv::Point(-1, -1), 2);
  double min_object = 0.0;
  cv::minMaxLoc(grey, &min_object, nullptr, nullptr, nullptr, object);
  EXPECT_GT(min_object, 3.0 * options.backdrop_grey);
  // Edge pixels blend object and backdrop (anti-aliasing): some levels lie in between.
  cv::Mat edge;
  cv::morphologyEx(truth, edge, cv::MORPH_GRADIENT, cv::Mat());
  cv::Mat between = (grey > options.backdrop_grey + 20) & (grey < min_object - 10) & edge;
  EXPECT_GT(cv::countNonZero(between), 50);
}

TEST(SyntheticCamera, SilhouetteEdgeIsAntiAliasedAtItsSubPixelPosition) {
  // At elevation 0 the cylinder's sides project to the vertical lines
  // u = cx -/+ f r / sqrt(d^2 - r^2). An edge pixel's level, relative to the backdrop and to the
  // object next to it, is the fraction of the pixel the object covers. The distances put the
  // edges at several sub-pixel positions (coverage 0.89, 0.20, 0.37, 0.55, 0.74).
  for (double distance_mm : {450.0, 456.0, 459.0, 462.0, 465.0}) {
    SyntheticOptions options = Options("cylinder");
    options.noise_sigma = 0.0;
    options.distance_mm = distance_mm;
    auto camera = MakeCamera(options);
    const Intrinsics& k = camera->rig().intrinsics;
    const double r = options.radius_mm;
    const double half_width_px = k.fx_px * r / std::sqrt(distance_mm * distance_mm - r * r);
    const double left_edge = k.cx_px - half_width_px, right_edge = k.cx_px + half_width_px;
    cv::Mat grey, grey_f;
    // At 90 deg the marker faces away and no texture boundary falls between the limb pixels.
    cv::cvtColor(camera->Render(90.0, 0), grey, cv::COLOR_BGR2GRAY);
    grey.convertTo(grey_f, CV_64F);
    const double backdrop = options.backdrop_grey;
    const int u_left = static_cast<int>(std::lround(left_edge));
    const int u_right = static_cast<int>(std::lround(right_edge));
    const double left_expected = std::clamp(u_left + 0.5 - left_edge, 0.0, 1.0);
    const double right_expected = std::clamp(right_edge - (u_right - 0.5), 0.0, 1.0);
    std::vector<double> left_coverage, right_coverage;
    for (int v = 250; v < 330; ++v) {  // the middle of the cylinder's height
      const auto* row = grey_f.ptr<double>(v);
      left_coverage.push_back((row[u_left] - backdrop) / (row[u_left + 1] - backdrop));
      right_coverage.push_back((row[u_right] - backdrop) / (row[u_right - 1] - backdrop));
    }
    auto median = [](std::vector<double> x) {
      std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
      return x[x.size() / 2];
    };
    // 4 x 4 supersampling resolves coverage to 1/8; shading adds a little.
    EXPECT_NEAR(median(left_coverage), left_expected, 0.15) << distance_mm;
    EXPECT_NEAR(median(right_coverage), right_expected, 0.15) << distance_mm;
    // The pixels beyond the edge pixels are pure backdrop.
    EXPECT_NEAR(grey_f.at<double>(290, u_left - 1), backdrop, 1.0);
    EXPECT_NEAR(grey_f.at<double>(290, u_right + 1), backdrop, 1.0);
  }
}

TEST(SyntheticCamera, NoiseIsSeededBySeedAndSequence) {
  SyntheticOptions options = Options("sphere");
  auto a = MakeCamera(options), b = MakeCamera(options);
  options.seed = 2;
  auto c = MakeCamera(options);
  const cv::Mat frame_a = a->Render(10.0, 3);
  EXPECT_EQ(cv::norm(frame_a, b->Render(10.0, 3), cv::NORM_INF), 0.0);  // reproducible
  EXPECT_GT(cv::norm(frame_a, a->Render(10.0, 4), cv::NORM_INF), 0.0);  // next frame differs
  EXPECT_GT(cv::norm(frame_a, c->Render(10.0, 3), cv::NORM_INF), 0.0);  // other seed differs
}

TEST(SyntheticCamera, KnowsItsRigAndScene) {
  SyntheticOptions options = Options("sphere", 15.0);
  auto camera = MakeCamera(options);
  const std::optional<Rig> rig = camera->KnownRig();
  ASSERT_TRUE(rig.has_value());
  const Rig expected = RigFromOptions(options);
  EXPECT_TRUE(rig->cam_from_table.isApprox(expected.cam_from_table));
  EXPECT_DOUBLE_EQ(rig->intrinsics.fx_px, 384.0 / std::tan(15.0 * std::numbers::pi / 180.0));
  const std::optional<SceneTruth> truth = camera->KnownScene();
  ASSERT_TRUE(truth.has_value());
  EXPECT_EQ(truth->description, "sphere r=40 mm");
  EXPECT_NEAR(truth->volume_mm3, 4.0 / 3.0 * std::numbers::pi * 64000.0, 1e-6);
  EXPECT_NEAR(truth->distance_mm(Eigen::Vector3d(0, 0, 90)), 10.0, 1e-12);
  EXPECT_EQ(*truth->sphere_center_mm, Eigen::Vector3d(0, 0, 40));
  EXPECT_NE(camera->Describe().find("sphere r=40 mm"), std::string::npos);
}

TEST(SyntheticCamera, CreateRejectsBadSetups) {
  EXPECT_EQ(SyntheticCamera::Create(SyntheticOptions{}, nullptr).error().code,
            ErrorCode::kBadInput);
  SyntheticOptions inside;
  inside.distance_mm = 30.0;  // within the 40 mm radius
  auto error = SyntheticCamera::Create(inside, std::make_shared<SimulatedPlate>()).error();
  EXPECT_EQ(error.code, ErrorCode::kBadInput);
  EXPECT_NE(error.message.find("distance_mm"), std::string::npos) << error.message;
  SyntheticOptions cube;
  cube.object = "cube";
  EXPECT_FALSE(SyntheticCamera::Create(cube, std::make_shared<SimulatedPlate>()).has_value());
  SyntheticOptions tiny;
  tiny.width_px = 4;
  error = SyntheticCamera::Create(tiny, std::make_shared<SimulatedPlate>()).error();
  EXPECT_NE(error.message.find("width_px"), std::string::npos) << error.message;
}

TEST(Capture, FactoryMakesTheSyntheticCameraOnly) {
  CameraOptions options;
  auto camera = Create(options, std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(camera.has_value());
  EXPECT_TRUE((*camera)->KnownRig().has_value());
  options.backend = "kinect";
  auto error = Create(options, std::make_shared<SimulatedPlate>()).error();
  EXPECT_EQ(error.code, ErrorCode::kUnsupported);
  EXPECT_NE(error.message.find("[camera].backend"), std::string::npos) << error.message;
  EXPECT_NE(error.message.find("synthetic"), std::string::npos) << error.message;
}

TEST(Capture, RendersThePlatesAngleAtExposure) {
  auto plate = std::make_shared<SimulatedPlate>();
  SyntheticOptions options = Options("vase");
  auto camera = MakeCamera(options, plate);
  auto format = camera->Start();
  ASSERT_TRUE(format.has_value());
  EXPECT_EQ(format->width_px, 768);
  EXPECT_EQ(format->height_px, 576);
  EXPECT_EQ(format->pixel_format, "BGR3");
  plate->angle_deg = -90.0;
  auto first = camera->Capture(Clock::now(), milliseconds(1000));
  ASSERT_TRUE(first.has_value());
  plate->angle_deg = 47.0;
  auto second = camera->Capture(Clock::now(), milliseconds(1000));
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(first->sequence, 0u);
  EXPECT_EQ(second->sequence, 1u);
  EXPECT_GT(first->exposure_us, 0.0);
  EXPECT_EQ(cv::norm(first->image, camera->Render(-90.0, 0), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(second->image, camera->Render(47.0, 1), cv::NORM_INF), 0.0);
  camera->Stop();
}

TEST(Capture, HonoursNotBefore) {
  auto camera = MakeCamera(Options("sphere"));
  ASSERT_TRUE(camera->Start().has_value());
  const Clock::time_point start = Clock::now();
  const Clock::time_point not_before = start + milliseconds(80);
  auto frame = camera->Capture(not_before, milliseconds(2000));
  ASSERT_TRUE(frame.has_value());
  EXPECT_GE(frame->exposed, not_before);
  // A past not_before exposes now.
  const Clock::time_point before = Clock::now();
  frame = camera->Capture(before - milliseconds(500), milliseconds(2000));
  ASSERT_TRUE(frame.has_value());
  EXPECT_GE(frame->exposed, before);
}

TEST(Capture, TimesOutAtOnceWhenNotBeforeIsBeyondTheTimeout) {
  auto camera = MakeCamera(Options("sphere"));
  ASSERT_TRUE(camera->Start().has_value());
  const Clock::time_point start = Clock::now();
  auto frame = camera->Capture(start + milliseconds(3000), milliseconds(100));
  ASSERT_FALSE(frame.has_value());
  EXPECT_EQ(frame.error().code, ErrorCode::kTimeout);
  EXPECT_LT(Clock::now() - start, milliseconds(1000));  // did not sleep
}

TEST(Capture, FailsWhenNotStartedAndAbortsOnStop) {
  auto camera = MakeCamera(Options("sphere"));
  EXPECT_EQ(camera->Capture(Clock::now(), milliseconds(100)).error().code, ErrorCode::kInternal);
  ASSERT_TRUE(camera->Start().has_value());
  const Clock::time_point start = Clock::now();
  std::thread stopper([&] {
    std::this_thread::sleep_for(milliseconds(50));
    camera->Stop();
  });
  auto frame = camera->Capture(start + milliseconds(5000), milliseconds(10000));
  stopper.join();
  ASSERT_FALSE(frame.has_value());
  EXPECT_EQ(frame.error().code, ErrorCode::kAborted);
  EXPECT_LT(Clock::now() - start, milliseconds(3000));
}

}  // namespace
}  // namespace revolve::capture
