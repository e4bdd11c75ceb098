// Every segmentation method on simulated frames with noise, on its own backdrop, with the
// table's plate (its rim a different colour) and a fixture in view: the mask matches the true
// mask (IoU >= 0.99) and neither the rim nor the fixture leaks into it.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "capture/segmenter.h"
#include "capture/synthetic/synthetic_camera.h"

namespace revolve::capture {
namespace {

double IoU(const cv::Mat& a, const cv::Mat& b) {
  const double inter = cv::countNonZero(a & b);
  const double uni = cv::countNonZero(a | b);
  return uni > 0 ? inter / uni : 1.0;
}

enum class Backdrop { kDark, kLight, kGreen };

constexpr double kPlateRadiusMm = 60.0;
// A post standing on the table to the right of the plate (table frame, mm).
constexpr double kFixtureMm[6] = {85.0, -6.0, -8.0, 97.0, 6.0, 80.0};

SyntheticOptions StageOptions(Backdrop backdrop, const std::string& object, double elevation_deg) {
  SyntheticOptions o;
  o.object = object;
  o.elevation_deg = elevation_deg;
  o.noise_sigma = 3.0;
  o.plate_radius_mm = kPlateRadiusMm;
  o.fixture_mm.assign(std::begin(kFixtureMm), std::end(kFixtureMm));
  switch (backdrop) {
    case Backdrop::kDark:  // black velvet; an aluminium rim and a bright post
      o.backdrop_bgr = {20, 20, 20};
      o.plate_rim_bgr = {150, 150, 150};
      o.fixture_bgr = {200, 200, 200};
      break;
    case Backdrop::kLight:  // a white light box; a dark rim and a dark post; a darker object
      o.backdrop_bgr = {230, 232, 235};
      o.object_albedo = 0.45;
      o.plate_rim_bgr = {60, 60, 60};
      o.fixture_bgr = {40, 40, 45};
      break;
    case Backdrop::kGreen:  // a green screen; the plate top covered in the same cloth
      o.backdrop_bgr = {40, 170, 40};
      o.plate_rim_bgr = {150, 150, 150};
      o.fixture_bgr = {120, 120, 200};
      break;
  }
  return o;
}

Eigen::Vector2d Project(const SyntheticCamera& camera, const Eigen::Vector3d& table_point) {
  Eigen::Vector2d pixel;
  EXPECT_TRUE(camera.KnownView(0.0)->Project(table_point, &pixel));
  return pixel;
}

// The region of interest a user would draw on a snapshot: everything above the plate's near rim
// (the plate's top stays in; its rim and the table below go), minus a box around the fixture.
SegmentOptions RoiFor(const SyntheticCamera& camera) {
  SegmentOptions s;
  const int width = camera.rig().intrinsics.width_px;
  const int height = camera.rig().intrinsics.height_px;
  s.roi_polygon_px = {0, 0, width, 0};
  // Along the near half of the plate's top edge, 2 px above it, right to left.
  for (int i = 0; i <= 36; ++i) {
    const double phi = -std::numbers::pi * i / 36.0;
    const Eigen::Vector2d p = Project(camera, Eigen::Vector3d(kPlateRadiusMm * std::cos(phi),
                                                              kPlateRadiusMm * std::sin(phi), 0.0));
    s.roi_polygon_px.push_back(static_cast<int>(std::floor(p.x())));
    s.roi_polygon_px.push_back(std::min(height, static_cast<int>(std::floor(p.y())) - 2));
  }
  s.roi_polygon_px.insert(s.roi_polygon_px.end(), {0, height});
  // The fixture's projected box, 3 px wider.
  double u0 = 1e9, v0 = 1e9, u1 = -1e9, v1 = -1e9;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector2d p =
        Project(camera, Eigen::Vector3d(kFixtureMm[(c & 1) ? 3 : 0], kFixtureMm[(c & 2) ? 4 : 1],
                                        kFixtureMm[(c & 4) ? 5 : 2]));
    u0 = std::min(u0, p.x()), u1 = std::max(u1, p.x());
    v0 = std::min(v0, p.y()), v1 = std::max(v1, p.y());
  }
  s.exclude_px = {static_cast<int>(u0) - 3, static_cast<int>(v0) - 3, static_cast<int>(u1) + 4,
                  static_cast<int>(v1) + 4};
  return s;
}

struct MethodCase {
  Backdrop backdrop;
  std::string method;
  std::string object;
  double elevation_deg;
  double angle_deg;
  std::string name;
};

void PrintTo(const MethodCase& c, std::ostream* os) { *os << c.name; }

class SegmentMethodTest : public ::testing::TestWithParam<MethodCase> {};

TEST_P(SegmentMethodTest, MatchesTheTrueMaskAndExcludesThePlateAndFixture) {
  const MethodCase& c = GetParam();
  auto camera = SyntheticCamera::Create(StageOptions(c.backdrop, c.object, c.elevation_deg),
                                        std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(camera.has_value()) << camera.error().ToString();
  const RenderOutput frame = (*camera)->RenderWithTruth(c.angle_deg, 7);
  const cv::Mat background = (*camera)->RenderWithTruth(0.0, 1000, false).image;

  SegmentOptions options = RoiFor(**camera);
  options.method = c.method;
  options.backdrop = c.backdrop == Backdrop::kLight ? "light" : "dark";
  options.threshold = c.backdrop == Backdrop::kLight ? 170 : 60;
  auto segmenter = CreateSegmenter(options);
  ASSERT_TRUE(segmenter.has_value()) << segmenter.error().ToString();
  auto mask = (*segmenter)->Segment(frame.image, background);
  ASSERT_TRUE(mask.has_value()) << mask.error().ToString();

  const double iou = IoU(*mask, frame.true_mask);
  std::printf("IoU %-40s %.4f\n", c.name.c_str(), iou);
  EXPECT_GE(iou, 0.99);
  // Nothing of the rim, the table or the fixture.
  const cv::Mat stage = (frame.surface == kPlateRimSurface) | (frame.surface >= kFixtureSurface);
  EXPECT_EQ(cv::countNonZero(*mask & stage), 0);
  // The scene is a real test: the rim and the fixture are in view...
  EXPECT_GT(cv::countNonZero(frame.surface == kPlateRimSurface), 500);
  EXPECT_GT(cv::countNonZero(frame.surface >= kFixtureSurface), 500);
}

std::vector<MethodCase> Cases() {
  std::vector<MethodCase> cases;
  const std::pair<Backdrop, std::vector<std::string>> methods[] = {
      {Backdrop::kDark, {"otsu", "fixed", "background"}},
      {Backdrop::kLight, {"otsu", "fixed", "background"}},
      {Backdrop::kGreen, {"chroma", "background"}},
  };
  const std::tuple<std::string, double, double> views[] = {
      {"vase", 0.0, 30.0}, {"cylinder", 20.0, 0.0}, {"sphere", 10.0, 0.0}, {"cone", 25.0, 45.0}};
  for (const auto& [backdrop, names] : methods) {
    const std::string backdrop_name = backdrop == Backdrop::kDark    ? "dark"
                                      : backdrop == Backdrop::kLight ? "light"
                                                                     : "green";
    for (const std::string& method : names) {
      for (const auto& [object, elevation, angle] : views) {
        cases.push_back({backdrop, method, object, elevation, angle,
                         backdrop_name + "_" + method + "_" + object + "_e" +
                             std::to_string(static_cast<int>(elevation))});
      }
    }
  }
  return cases;
}

INSTANTIATE_TEST_SUITE_P(Backdrops, SegmentMethodTest, ::testing::ValuesIn(Cases()),
                         [](const auto& p) { return p.param.name; });

TEST(SegmentMethods, WithoutTheRegionOfInterestTheRimAndFixtureLeak) {
  auto camera = SyntheticCamera::Create(StageOptions(Backdrop::kDark, "vase", 20.0),
                                        std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(camera.has_value());
  const RenderOutput frame = (*camera)->RenderWithTruth(0.0, 3);
  SegmentOptions options;
  options.keep_largest = false;
  auto mask = (*CreateSegmenter(options))->Segment(frame.image, cv::Mat());
  ASSERT_TRUE(mask.has_value());
  const cv::Mat stage = (frame.surface == kPlateRimSurface) | (frame.surface >= kFixtureSurface);
  EXPECT_GT(cv::countNonZero(*mask & stage), 1000);
}

TEST(SegmentMethods, ChromaUsesAGivenKeyAndRejectsAGreyOne) {
  auto camera = SyntheticCamera::Create(StageOptions(Backdrop::kGreen, "vase", 0.0),
                                        std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(camera.has_value());
  const RenderOutput frame = (*camera)->RenderWithTruth(0.0, 3);
  SegmentOptions options = RoiFor(**camera);
  options.method = "chroma";
  options.chroma_key_bgr = {40, 170, 40};
  auto mask = (*CreateSegmenter(options))->Segment(frame.image, cv::Mat());
  ASSERT_TRUE(mask.has_value());
  EXPECT_GE(IoU(*mask, frame.true_mask), 0.99);
  options.chroma_key_bgr = {128, 128, 128};
  auto grey = (*CreateSegmenter(options))->Segment(frame.image, cv::Mat());
  ASSERT_FALSE(grey.has_value());
  EXPECT_EQ(grey.error().code, ErrorCode::kBadInput);
  EXPECT_NE(grey.error().message.find("too grey"), std::string::npos);
}

TEST(SegmentMethods, BackgroundDifferenceNeedsAMatchingBackground) {
  SegmentOptions options;
  options.method = "background";
  auto segmenter = CreateSegmenter(options);
  ASSERT_TRUE(segmenter.has_value());
  EXPECT_TRUE((*segmenter)->NeedsBackground());
  const cv::Mat image(40, 60, CV_8UC3, cv::Scalar::all(20));
  auto missing = (*segmenter)->Segment(image, cv::Mat());
  ASSERT_FALSE(missing.has_value());
  EXPECT_NE(missing.error().message.find("empty scene"), std::string::npos);
  auto wrong = (*segmenter)->Segment(image, cv::Mat(40, 61, CV_8UC3, cv::Scalar::all(20)));
  ASSERT_FALSE(wrong.has_value());
  EXPECT_EQ(wrong.error().code, ErrorCode::kBadInput);
  // The empty scene against itself (other noise): an empty mask.
  cv::Mat noisy = image.clone(), noise(image.size(), CV_8UC3);
  cv::randn(noise, cv::Scalar::all(0), cv::Scalar::all(3));
  noisy += noise;
  auto empty = (*segmenter)->Segment(noisy, image);
  ASSERT_TRUE(empty.has_value());
  EXPECT_EQ(cv::countNonZero(*empty), 0);
}

TEST(SegmentMethods, LargeHolesStayOpenWhenAsked) {
  // A flat torus seen from above-ish shows its hole.
  SyntheticOptions o;
  o.object = "torus";
  o.radius_mm = 45.0;
  o.height_mm = 24.0;
  o.elevation_deg = 50.0;
  o.target_height_mm = 12.0;
  auto camera = SyntheticCamera::Create(o, std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(camera.has_value()) << camera.error().ToString();
  const RenderOutput frame = (*camera)->RenderWithTruth(0.0, 1);
  SegmentOptions options;
  options.max_hole_area_px = 200;
  auto mask = (*CreateSegmenter(options))->Segment(frame.image, cv::Mat());
  ASSERT_TRUE(mask.has_value());
  EXPECT_GE(IoU(*mask, frame.true_mask), 0.99);
  options.max_hole_area_px = 0;  // fill every hole: the torus's hole is lost
  auto filled = (*CreateSegmenter(options))->Segment(frame.image, cv::Mat());
  EXPECT_LT(IoU(*filled, frame.true_mask), 0.95);
}

TEST(SegmentMethods, RegionOfInterestMask) {
  SegmentOptions options;
  options.roi_px = {10, 5, 30, 25};
  options.exclude_px = {12, 7, 14, 9, 100, 100, 120, 120};
  const cv::Mat roi = RegionOfInterestMask(options, cv::Size(40, 30));
  EXPECT_EQ(cv::countNonZero(roi), 20 * 20 - 4);
  EXPECT_EQ(roi.at<std::uint8_t>(5, 10), 255);
  EXPECT_EQ(roi.at<std::uint8_t>(25, 29), 0);
  EXPECT_EQ(roi.at<std::uint8_t>(7, 12), 0);
  options.roi_px.clear();
  options.exclude_px.clear();
  options.roi_polygon_px = {0, 0, 39, 0, 0, 29};  // a triangle
  const cv::Mat triangle = RegionOfInterestMask(options, cv::Size(40, 30));
  EXPECT_EQ(triangle.at<std::uint8_t>(1, 1), 255);
  EXPECT_EQ(triangle.at<std::uint8_t>(28, 38), 0);
}

}  // namespace
}  // namespace revolve::capture
