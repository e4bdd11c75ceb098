// Lens calibration from rendered boards at known poses: the recovered intrinsics match the true
// ones, and poor inputs are refused with the reason.
#include "calibrate/intrinsics.h"

#include <cstdio>

#include <gtest/gtest.h>

#include "calibrate/board_render.h"
#include "sim_rigs.h"

namespace revolve::calibrate {
namespace {

std::vector<ViewDetection> RenderAndDetect(const CameraModel& camera, const Board& board,
                                           const std::vector<Eigen::Isometry3d>& poses,
                                           double noise_sigma = 2.0) {
  std::vector<ViewDetection> views;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    BoardRenderOptions options;
    options.noise_sigma = noise_sigma;
    options.blur_sigma_px = 0.6;
    options.seed = i + 1;
    Expected<cv::Mat> image = RenderBoard(camera, poses[i], board, options);
    EXPECT_TRUE(image) << image.error().ToString();
    if (!image) continue;
    views.push_back({"view " + std::to_string(i), DetectBoard(*image, board)});
  }
  return views;
}

class IntrinsicsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    truth_ = new CameraModel(sim::TrueLens());
    views_ = new std::vector<ViewDetection>(RenderAndDetect(
        *truth_, sim::TestBoard(), sim::HandHeldPoses(*truth_, sim::TestBoard(), 15)));
  }
  static void TearDownTestSuite() {
    delete views_;
    delete truth_;
  }
  static CameraModel* truth_;
  static std::vector<ViewDetection>* views_;
};
CameraModel* IntrinsicsTest::truth_ = nullptr;
std::vector<ViewDetection>* IntrinsicsTest::views_ = nullptr;

TEST_F(IntrinsicsTest, RecoversTheLens) {
  for (const ViewDetection& v : *views_) {
    EXPECT_TRUE(v.detection) << v.name << ": " << v.detection.error().message;
  }
  Expected<IntrinsicsResult> result = CalibrateIntrinsics(*views_, 768, 576);
  ASSERT_TRUE(result) << result.error().ToString();
  const Intrinsics& got = result->camera.intrinsics;
  const Intrinsics& want = truth_->intrinsics;
  std::printf(
      "focal %.2f / %.2f px (true %.2f), principal point (%.2f, %.2f) (true %.2f, %.2f), "
      "k1 %.4f (true %.4f), k2 %.4f (true %.4f), RMS %.3f px, coverage %.2f, tilt "
      "spread %.1f deg, %d views\n",
      got.fx_px, got.fy_px, want.fx_px, got.cx_px, got.cy_px, want.cx_px, want.cy_px,
      result->camera.distortion[0], truth_->distortion[0], result->camera.distortion[1],
      truth_->distortion[1], result->rms_px, result->coverage, result->tilt_spread_deg,
      result->views_used);
  EXPECT_NEAR(got.fx_px / want.fx_px, 1.0, 0.005);
  EXPECT_NEAR(got.fy_px / want.fy_px, 1.0, 0.005);
  EXPECT_NEAR(got.cx_px, want.cx_px, 2.0);
  EXPECT_NEAR(got.cy_px, want.cy_px, 2.0);
  EXPECT_LT(result->rms_px, 0.3);
  EXPECT_EQ(result->views_used, 15);
  EXPECT_GT(result->fx_std_px, 0.0);
  // The lens model undistorts like the true one over the whole image (corners included).
  double worst = 0.0;
  for (double u : {0.0, 200.0, 383.5, 600.0, 767.0}) {
    for (double v : {0.0, 150.0, 287.5, 420.0, 575.0}) {
      const Eigen::Vector2d ideal(u, v);
      const Eigen::Vector2d raw = truth_->DistortPixel(ideal);
      const std::vector<cv::Point2f> back = result->camera.UndistortPixels(
          {cv::Point2f(static_cast<float>(raw.x()), static_cast<float>(raw.y()))});
      // Compare in the true camera's ideal pixels (the intrinsics differ slightly).
      const Eigen::Vector2d n((back[0].x - got.cx_px) / got.fx_px,
                              (back[0].y - got.cy_px) / got.fy_px);
      const Eigen::Vector2d mapped(want.cx_px + want.fx_px * n.x(),
                                   want.cy_px + want.fy_px * n.y());
      worst = std::max(worst, (mapped - ideal).norm());
    }
  }
  std::printf("undistortion error over the image: %.3f px max\n", worst);
  EXPECT_LT(worst, 1.5);
}

TEST_F(IntrinsicsTest, TooFewViewsAreRefused) {
  const std::vector<ViewDetection> few(views_->begin(), views_->begin() + 4);
  Expected<IntrinsicsResult> result = CalibrateIntrinsics(few, 768, 576);
  ASSERT_FALSE(result);
  EXPECT_EQ(result.error().code, ErrorCode::kBadInput);
  EXPECT_NE(result.error().message.find("found in only 4 of 4 views (need 10"), std::string::npos)
      << result.error().message;
}

TEST_F(IntrinsicsTest, NoBoardAnywhereListsTheProblems) {
  const cv::Mat blank(576, 768, CV_8UC3, cv::Scalar(60, 60, 60));
  Expected<IntrinsicsResult> result = CalibrateIntrinsicsFromImages(
      {blank, blank, blank}, {"a.png", "b.png", "c.png"}, sim::TestBoard());
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("found in 0 of 3 views"), std::string::npos)
      << result.error().message;
  EXPECT_NE(result.error().message.find("a.png: no chessboard of 9x6"), std::string::npos)
      << result.error().message;
}

TEST_F(IntrinsicsTest, GatesNameEveryFailure) {
  // Raise the bars the good calibration passes: each failure is named.
  IntrinsicsOptions strict;
  strict.min_views = 20;
  strict.min_coverage = 0.99;
  strict.min_tilt_spread_deg = 170.0;
  strict.max_rms_px = 0.001;
  Expected<IntrinsicsResult> result = CalibrateIntrinsics(*views_, 768, 576, strict);
  ASSERT_FALSE(result);
  const std::string& m = result.error().message;
  EXPECT_NE(m.find("calibration refused"), std::string::npos) << m;
  EXPECT_NE(m.find("only 15 of 15 views (need 20"), std::string::npos) << m;
  EXPECT_NE(m.find("% of the image"), std::string::npos) << m;
  EXPECT_NE(m.find("orientations differ"), std::string::npos) << m;
  EXPECT_NE(m.find("RMS reprojection error"), std::string::npos) << m;
}

TEST(Intrinsics, FrontoParallelViewsAreRefused) {
  const CameraModel camera = sim::TrueLens();
  const Board board = sim::TestBoard();
  std::vector<Eigen::Isometry3d> poses = sim::HandHeldPoses(camera, board, 10);
  for (Eigen::Isometry3d& pose : poses) {
    const Eigen::Vector3d centre = pose * Eigen::Vector3d(60.0, 37.5, 0.0);
    pose.linear().setIdentity();
    pose.translation() = centre - Eigen::Vector3d(60.0, 37.5, 0.0);
  }
  Expected<IntrinsicsResult> result =
      CalibrateIntrinsics(RenderAndDetect(camera, board, poses), 768, 576);
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("orientations differ by at most"), std::string::npos)
      << result.error().message;
}

TEST(Intrinsics, CoverageOfTheImage) {
  Detection full;
  full.image_px = {{0.0f, 0.0f}, {767.0f, 0.0f}, {767.0f, 575.0f}, {0.0f, 575.0f}};
  EXPECT_NEAR(Coverage({full}, 768, 576), 1.0, 0.02);
  Detection quarter;
  quarter.image_px = {{0.0f, 0.0f}, {383.0f, 0.0f}, {383.0f, 287.0f}, {0.0f, 287.0f}};
  EXPECT_NEAR(Coverage({quarter}, 768, 576), 0.25, 0.03);
  EXPECT_NEAR(Coverage({quarter, quarter}, 768, 576), 0.25, 0.03);
}

}  // namespace
}  // namespace revolve::calibrate
