// Quality gates on simulated stops: each gate fires on its defect and stays quiet on a good
// stop.
#include "capture/quality.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "capture/segmenter.h"
#include "capture/synthetic/synthetic_camera.h"

namespace revolve::capture {
namespace {

std::unique_ptr<SyntheticCamera> Camera(SyntheticOptions o = {}) {
  auto camera = SyntheticCamera::Create(o, std::make_shared<SimulatedPlate>());
  EXPECT_TRUE(camera.has_value()) << camera.error().ToString();
  return std::move(*camera);
}

cv::Mat Segment(const cv::Mat& image) {
  auto mask = (*CreateSegmenter(SegmentOptions{}))->Segment(image, cv::Mat());
  EXPECT_TRUE(mask.has_value());
  return *mask;
}

std::vector<std::string> Codes(const StopAssessment& a) {
  std::vector<std::string> codes;
  for (const auto& w : a.warnings) codes.push_back(w.code);
  return codes;
}

bool Has(const StopAssessment& a, const std::string& code) {
  const auto codes = Codes(a);
  return std::find(codes.begin(), codes.end(), code) != codes.end();
}

TEST(Quality, AGoodStopPasses) {
  auto camera = Camera();
  const cv::Mat frame = camera->Render(0.0, 1);
  const StopAssessment a = AssessStop(frame, Segment(frame), {}, QualityOptions{});
  EXPECT_TRUE(a.ok()) << (a.ok() ? "" : a.warnings[0].message);
  EXPECT_GT(a.stats.area_px, 10000);
  EXPECT_GT(a.stats.edge_width_px, 1.0);
  EXPECT_LT(a.stats.edge_width_px, 3.0);
  // The next stop (10 degrees on) is a good neighbour.
  const cv::Mat next = camera->Render(10.0, 2);
  const StopAssessment b =
      AssessStop(next, Segment(next), std::span(&a.stats, 1), QualityOptions{});
  EXPECT_TRUE(b.ok());
}

TEST(Quality, AnEmptyMaskIsReported) {
  const cv::Mat frame(240, 320, CV_8UC3, cv::Scalar::all(20));
  const StopAssessment a =
      AssessStop(frame, cv::Mat::zeros(frame.size(), CV_8UC1), {}, QualityOptions{});
  EXPECT_EQ(Codes(a), std::vector<std::string>{"empty_mask"});
  EXPECT_NE(a.warnings[0].message.find("no object"), std::string::npos);
}

TEST(Quality, AnObjectTouchingTheBorderIsReported) {
  SyntheticOptions o;
  o.distance_mm = 200.0;  // too close: the vase fills the frame's height
  auto camera = Camera(o);
  const cv::Mat frame = camera->Render(0.0, 1);
  const StopAssessment a = AssessStop(frame, Segment(frame), {}, QualityOptions{});
  ASSERT_TRUE(Has(a, "touches_border"));
  EXPECT_NE(a.warnings[0].message.find("top"), std::string::npos) << a.warnings[0].message;
}

TEST(Quality, ClippedExposureIsReported) {
  auto camera = Camera();
  cv::Mat frame = camera->Render(0.0, 1);
  const cv::Mat mask = Segment(frame);
  cv::Mat bright = frame.clone();
  bright.setTo(cv::Scalar(255, 255, 255), mask);  // blown out
  EXPECT_TRUE(Has(AssessStop(bright, mask, {}, QualityOptions{}), "overexposed"));
  cv::Mat dark = frame.clone();
  dark.setTo(cv::Scalar(0, 0, 0), mask);
  EXPECT_TRUE(Has(AssessStop(dark, mask, {}, QualityOptions{}), "underexposed"));
}

TEST(Quality, ABinarySilhouetteImageIsNotAnExposureProblem) {
  // The thesis's input: a white silhouette on black, served as the frame.
  auto camera = Camera();
  const cv::Mat mask = Segment(camera->Render(0.0, 1));
  cv::Mat silhouette;
  cv::cvtColor(mask, silhouette, cv::COLOR_GRAY2BGR);
  EXPECT_TRUE(IsBinaryImage(silhouette));
  const StopAssessment a = AssessStop(silhouette, mask, {}, QualityOptions{});
  EXPECT_TRUE(a.ok()) << (a.ok() ? "" : a.warnings[0].message);
  // The same frame with one grey pixel is a photo again, and a blown-out one.
  silhouette.at<cv::Vec3b>(0, 0) = cv::Vec3b(20, 20, 20);
  EXPECT_FALSE(IsBinaryImage(silhouette));
  EXPECT_TRUE(Has(AssessStop(silhouette, mask, {}, QualityOptions{}), "overexposed"));
}

TEST(Quality, ABlurredFrameIsReported) {
  SyntheticOptions o;
  o.blur_sigma_px = 2.5;
  auto camera = Camera(o);
  const cv::Mat frame = camera->Render(0.0, 1);
  const StopAssessment a = AssessStop(frame, Segment(frame), {}, QualityOptions{});
  EXPECT_TRUE(Has(a, "blurred"));
  EXPECT_GT(a.stats.edge_width_px, 5.0);
}

TEST(Quality, AreaAndCentroidJumpsAgainstANeighbourAreReported) {
  auto camera = Camera();
  const cv::Mat frame = camera->Render(0.0, 1);
  const cv::Mat mask = Segment(frame);
  StopStats neighbour = MeasureStop(frame, mask);
  neighbour.area_px *= 2;
  EXPECT_TRUE(
      Has(AssessStop(frame, mask, std::span(&neighbour, 1), QualityOptions{}), "area_jump"));
  neighbour = MeasureStop(frame, mask);
  neighbour.centroid_px.x += 80.0;
  const StopAssessment a = AssessStop(frame, mask, std::span(&neighbour, 1), QualityOptions{});
  EXPECT_TRUE(Has(a, "centroid_jump"));
  EXPECT_FALSE(Has(a, "area_jump"));
  QualityOptions off;
  off.enabled = false;
  EXPECT_TRUE(AssessStop(frame, mask, std::span(&neighbour, 1), off).ok());
}

TEST(Quality, ParsesItsSection) {
  auto document = config::Parse("[quality]\nrecaptures = 3\nmax_edge_width_px = 5.5\n", "q.toml");
  ASSERT_TRUE(document.has_value());
  auto section = config::Section::Root(*document).Child("quality");
  auto options = ParseQualityOptions(*section);
  ASSERT_TRUE(options.has_value());
  EXPECT_EQ(options->recaptures, 3);
  EXPECT_DOUBLE_EQ(options->max_edge_width_px, 5.5);
  auto bad = config::Parse("[quality]\nrecapture = 3\n", "q.toml");
  auto error = ParseQualityOptions(*config::Section::Root(*bad).Child("quality"));
  ASSERT_FALSE(error.has_value());
  EXPECT_NE(error.error().message.find("q.toml:2:"), std::string::npos);
}

}  // namespace
}  // namespace revolve::capture
