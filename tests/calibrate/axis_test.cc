// The turntable axis from a board turned through the stops by the station: direction within
// 0.2 deg and centre within 0.5 mm of the truth, on a rig off the thesis's assumptions; clear
// refusals for bad input; and `calibrate check` passing an unchanged rig and failing a moved one.
#include "calibrate/axis.h"

#include <cstdio>
#include <map>

#include <gtest/gtest.h>

#include "calibrate/board_render.h"
#include "calibrate/check.h"
#include "calibrate/intrinsics.h"
#include "calibrate/silhouette_axis.h"
#include "sim_rigs.h"

namespace revolve::calibrate {
namespace {

using sim::Degrees;

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return Degrees(std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)));
}

struct Truth {
  CameraModel camera;
  Rig rig;
  Board board;
};

Truth LyingSetup() {
  Truth t;
  t.camera = sim::TrueLens();
  t.rig = sim::OffRig(t.camera.intrinsics, 30.0, 0.0);
  t.board = sim::TestBoard();
  return t;
}

// `lens`: the intrinsics the fit used (the true ones unless calibrated).
void ExpectMatches(const AxisResult& result, const Rig& truth, const char* what,
                   const Intrinsics* lens = nullptr) {
  const double direction_deg =
      AngleDeg(result.AxisDirectionCam(), truth.cam_from_table.linear().col(2));
  const double centre_mm = (result.PlateCentreCam() - truth.cam_from_table.translation()).norm();
  const SilhouetteAxis line_true = ProjectedAxisLine(truth);
  const SilhouetteAxis line_got =
      ProjectedAxisLine(Rig{lens != nullptr ? *lens : truth.intrinsics, result.cam_from_table});
  std::printf(
      "%s: axis direction error %.4f deg, plate centre error %.3f mm (%.3f mm along the "
      "axis), axis column %.2f px (true %.2f), %d stops, reprojection %.3f px RMS, "
      "corners %.3f mm RMS, angles %.4f deg RMS, placement %s\n",
      what, direction_deg, centre_mm,
      (result.PlateCentreCam() - truth.cam_from_table.translation())
          .dot(truth.cam_from_table.linear().col(2)),
      line_got.column_px, line_true.column_px, result.stops_used, result.reprojection_rms_px,
      result.corner_rms_mm, result.angle_rms_deg, std::string(ToString(result.placement)).c_str());
  EXPECT_LT(direction_deg, 0.2);
  EXPECT_LT(centre_mm, 0.5);
  EXPECT_NEAR(line_got.column_px, line_true.column_px, 0.5);
  EXPECT_NEAR(line_got.tilt_deg, line_true.tilt_deg, 0.1);
  EXPECT_LT(result.reprojection_rms_px, 0.3);
  EXPECT_TRUE(result.warnings.empty()) << result.warnings.front();
}

// A board lying on the plate of the off-assumption rig, turned through 36 stops of 10 deg.
// Stops are rendered on first use (ctest runs every test in its own process).
class LyingBoardTest : public ::testing::Test {
 protected:
  static const Truth& truth() {
    static const Truth truth = LyingSetup();
    return truth;
  }
  static const StopDetection& Stop(int k) {
    static std::map<int, StopDetection> cache;
    auto it = cache.find(k);
    if (it == cache.end()) {
      const Truth& t = truth();
      it = cache
               .emplace(k, sim::TurnBoard(t.rig, t.camera.distortion, sim::LyingBoard(t.board),
                                          t.board, {10.0 * k}, 100 + static_cast<std::uint64_t>(k))
                               .front())
               .first;
    }
    return it->second;
  }
  // Stops first, first + every, ... below 36.
  static std::vector<StopDetection> Stops(int first, int count, int every = 1) {
    std::vector<StopDetection> out;
    for (int i = 0; i < count; ++i) out.push_back(Stop(first + i * every));
    return out;
  }
};

TEST_F(LyingBoardTest, RecoversTheAxis) {
  Expected<AxisResult> result = CalibrateAxis(Stops(0, 36), truth().camera, truth().board);
  ASSERT_TRUE(result) << result.error().ToString();
  EXPECT_EQ(result->stops_used, 36);
  EXPECT_EQ(result->placement, BoardPlacement::kLying);
  EXPECT_NEAR(result->span_deg, 350.0, 1e-9);
  ExpectMatches(*result, truth().rig, "lying board, 36 stops");
  // The table frame's x axis follows the camera's x axis: object +x to the right at angle 0.
  const Eigen::Vector3d x_cam = result->cam_from_table.linear().col(0);
  EXPECT_GT(x_cam.x(), 0.99);
  // The board placement found is the true one up to the frame's turn about the axis.
  const Eigen::Isometry3d true_board = sim::LyingBoard(truth().board);
  EXPECT_NEAR((result->object_from_board.translation() - true_board.translation()).z(), 0.0, 0.5);
}

TEST_F(LyingBoardTest, TwelveStopsAreEnough) {
  Expected<AxisResult> result = CalibrateAxis(Stops(0, 12, 3), truth().camera, truth().board);
  ASSERT_TRUE(result) << result.error().ToString();
  ExpectMatches(*result, truth().rig, "lying board, 12 stops");
}

TEST_F(LyingBoardTest, TooFewStopsAreRefused) {
  std::vector<StopDetection> few = Stops(0, 4);
  few.push_back(
      {40.0, MakeError(ErrorCode::kBadInput, "no chessboard of 9x6 inner corners found")});
  Expected<AxisResult> result = CalibrateAxis(few, truth().camera, truth().board);
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("found at 4 of 5 stops (need 6"), std::string::npos)
      << result.error().message;
  EXPECT_NE(result.error().message.find("stop at 40 deg: no chessboard"), std::string::npos)
      << result.error().message;
}

TEST_F(LyingBoardTest, NarrowSpanIsRefused) {
  const std::vector<StopDetection> narrow = Stops(0, 7);  // 0..60 deg
  Expected<AxisResult> result = CalibrateAxis(narrow, truth().camera, truth().board);
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("span 60 deg of the turn (need 90"), std::string::npos)
      << result.error().message;
}

TEST_F(LyingBoardTest, WrongAnglesAreRefused) {
  // The drive turned 30 deg per stop but the station believed 36: the rigid-turn model fails.
  std::vector<StopDetection> wrong = Stops(0, 12, 3);
  for (std::size_t k = 0; k < wrong.size(); ++k) wrong[k].angle_deg = 36.0 * k;
  Expected<AxisResult> result = CalibrateAxis(wrong, truth().camera, truth().board);
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("RMS reprojection error"), std::string::npos)
      << result.error().message;
}

TEST_F(LyingBoardTest, BoardThatDidNotTurnIsRefused) {
  std::vector<StopDetection> still(8, Stop(0));
  for (std::size_t k = 0; k < still.size(); ++k) still[k].angle_deg = 45.0 * k;
  Expected<AxisResult> result = CalibrateAxis(still, truth().camera, truth().board);
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("did not turn"), std::string::npos)
      << result.error().message;
}

TEST_F(LyingBoardTest, SymmetricChessboardIsRefused) {
  Board symmetric = truth().board;
  symmetric.cols = 7;
  symmetric.rows = 5;
  Expected<AxisResult> result = CalibrateAxis(Stops(0, 1), truth().camera, symmetric);
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("looks the same turned by 180 deg"), std::string::npos);
}

TEST(StandingBoard, RecoversTheAxis) {
  // A camera nearly level with the plate sees a lying board edge-on: stand it up. It is found
  // only while it faces the camera.
  const CameraModel camera = sim::TrueLens();
  const Rig rig = sim::OffRig(camera.intrinsics, 10.0, 40.0);
  const Board board = sim::TestBoard();
  const std::vector<StopDetection> stops = sim::TurnBoard(
      rig, camera.distortion, sim::StandingBoard(board), board, sim::StopAngles(24, 15.0));
  Expected<AxisResult> result = CalibrateAxis(stops, camera, board);
  ASSERT_TRUE(result) << result.error().ToString();
  EXPECT_EQ(result->placement, BoardPlacement::kStanding);
  EXPECT_LT(result->stops_used, 24);
  EXPECT_GE(result->stops_used, 7);
  for (const StopReport& stop : result->stops) {
    if (!stop.used) {
      EXPECT_NE(stop.problem.find("no chessboard"), std::string::npos);
    }
  }
  ExpectMatches(*result, rig, "standing board");
}

TEST(CharucoBoard, RecoversTheAxis) {
  if (!CharucoSupported()) GTEST_SKIP() << "built without OpenCV's aruco module";
  const CameraModel camera = sim::TrueLens();
  const Rig rig = sim::OffRig(camera.intrinsics, 30.0, 0.0);
  Board board = sim::TestBoard();
  board.type = BoardType::kCharuco;
  board.marker_mm = 11.0;
  const std::vector<StopDetection> stops = sim::TurnBoard(
      rig, camera.distortion, sim::LyingBoard(board), board, sim::StopAngles(12, 30.0));
  Expected<AxisResult> result = CalibrateAxis(stops, camera, board);
  ASSERT_TRUE(result) << result.error().ToString();
  ExpectMatches(*result, rig, "ChArUco board, 12 stops");
}

// The whole procedure: the lens from hand-held views, then the axis with that lens.
TEST(EndToEnd, LensThenAxis) {
  const CameraModel truth = sim::TrueLens();
  const Board board = sim::TestBoard();
  std::vector<cv::Mat> images;
  int seed = 1;
  for (const Eigen::Isometry3d& pose : sim::HandHeldPoses(truth, board, 15)) {
    BoardRenderOptions options;
    options.seed = static_cast<std::uint64_t>(seed++);
    options.blur_sigma_px = 0.6;
    Expected<cv::Mat> image = RenderBoard(truth, pose, board, options);
    ASSERT_TRUE(image);
    images.push_back(*image);
  }
  Expected<IntrinsicsResult> lens = CalibrateIntrinsicsFromImages(images, {}, board);
  ASSERT_TRUE(lens) << lens.error().ToString();
  const Rig rig = sim::OffRig(truth.intrinsics, 30.0, 0.0);
  std::vector<cv::Mat> frames;
  const std::vector<double> angles = sim::StopAngles(24, 15.0);
  for (double angle : angles) {
    BoardRenderOptions options;
    options.seed = static_cast<std::uint64_t>(1000 + angle);
    Expected<cv::Mat> frame =
        RenderBoardOnTable(rig, truth.distortion, angle, sim::LyingBoard(board), board, options);
    ASSERT_TRUE(frame);
    frames.push_back(*frame);
  }
  Expected<AxisResult> axis = CalibrateAxisFromImages(frames, angles, lens->camera, board);
  ASSERT_TRUE(axis) << axis.error().ToString();
  ExpectMatches(*axis, rig, "calibrated lens, then axis (24 stops)", &lens->camera.intrinsics);
  // Scans then see the rig through the calibration: the projection of table points matches.
  const Calibration calibration = Calibration::From(board, *lens, *axis);
  Expected<Rig> got = calibration.ToRig();
  ASSERT_TRUE(got);
  for (double angle : {0.0, 95.0, 222.0}) {
    for (const Eigen::Vector3d& p :
         {Eigen::Vector3d(30, 0, 0), Eigen::Vector3d(0, -40, 60), Eigen::Vector3d(-20, 25, 100)}) {
      // Compare in the true rig's object frame: the calibrated one may be turned about the axis
      // (its angle zero is the station's, its x axis the camera's), so map the point through it.
      const Eigen::Vector3d cam_true = rig.CamFromObject(angle) * p;
      const Eigen::Vector3d object_got = got->CamFromObject(angle).inverse() * cam_true;
      EXPECT_NEAR(object_got.z(), p.z(), 0.5);  // heights on the axis are absolute
      EXPECT_NEAR(object_got.head<2>().norm(), p.head<2>().norm(), 0.5);  // so are radii
    }
  }
}

// `revolve calibrate check` on the stored calibration with today's board (placed elsewhere on
// the plate) at six stops, with the camera where it was or moved.
class CheckTest : public LyingBoardTest {
 protected:
  static Calibration Stored() {
    Expected<AxisResult> axis = CalibrateAxis(Stops(0, 12, 3), truth().camera, truth().board);
    EXPECT_TRUE(axis);
    IntrinsicsResult lens;
    lens.camera = truth().camera;
    return Calibration::From(truth().board, lens, *axis);
  }
  static std::vector<StopDetection> Today(const Rig& rig) {
    Eigen::Isometry3d moved = sim::LyingBoard(truth().board);
    moved.prerotate(sim::Rz(70.0));
    moved.pretranslate(Eigen::Vector3d(-6.0, 4.0, 0.0));
    return sim::TurnBoard(rig, truth().camera.distortion, moved, truth().board,
                          CheckStopAngles(6, 36, 10.0), 500);
  }
};

TEST_F(CheckTest, PassesAnUnchangedRig) {
  Expected<CheckResult> check = CheckCalibration(Stored(), Today(truth().rig));
  ASSERT_TRUE(check) << check.error().ToString();
  std::printf("unchanged rig:\n%s", check->Summary({}).c_str());
  EXPECT_TRUE(check->passed);
  EXPECT_EQ(check->stops_used, 6);
  EXPECT_LT(check->reprojection_rms_px, 0.3);
  ASSERT_TRUE(check->axis_angle_change_deg && check->centre_change_mm);
  EXPECT_LT(*check->axis_angle_change_deg, 0.2);
  EXPECT_LT(*check->centre_change_mm, 0.5);
}

TEST_F(CheckTest, FailsWhenTheCameraTurned) {
  Rig bumped = truth().rig;
  bumped.cam_from_table.prerotate(sim::Rx(0.5));  // camera nodded by half a degree
  Expected<CheckResult> check = CheckCalibration(Stored(), Today(bumped));
  ASSERT_TRUE(check) << check.error().ToString();
  std::printf("camera turned 0.5 deg:\n%s", check->Summary({}).c_str());
  EXPECT_FALSE(check->passed);
  ASSERT_TRUE(check->axis_angle_change_deg);
  EXPECT_NEAR(*check->axis_angle_change_deg, 0.5, 0.1);
  ASSERT_FALSE(check->failures.empty());
  EXPECT_NE(check->failures.front().find("run `revolve calibrate` again"), std::string::npos);
}

TEST_F(CheckTest, FailsWhenTheCameraShifted) {
  Rig bumped = truth().rig;
  bumped.cam_from_table.pretranslate(Eigen::Vector3d(2.0, 0.0, 0.0));  // 2 mm sideways
  Expected<CheckResult> check = CheckCalibration(Stored(), Today(bumped));
  ASSERT_TRUE(check) << check.error().ToString();
  std::printf("camera shifted 2 mm:\n%s", check->Summary({}).c_str());
  EXPECT_FALSE(check->passed);
  ASSERT_TRUE(check->centre_change_mm);
  EXPECT_NEAR(*check->centre_change_mm, 2.0, 0.3);
  bool named = false;
  for (const std::string& f : check->failures) named |= f.find("moved") != std::string::npos;
  EXPECT_TRUE(named);
}

TEST_F(CheckTest, NoBoardIsAnError) {
  std::vector<StopDetection> none;
  for (double angle : CheckStopAngles(4, 36, 10.0)) {
    none.push_back({angle, MakeError(ErrorCode::kBadInput, "no chessboard of 9x6 found")});
  }
  Expected<CheckResult> check = CheckCalibration(Stored(), none);
  ASSERT_FALSE(check);
  EXPECT_NE(check.error().message.find("found at none of the 4 stops"), std::string::npos)
      << check.error().message;
}

TEST(CheckStopAngles, SpreadOverTheTurn) {
  EXPECT_EQ(CheckStopAngles(6, 36, 10.0), (std::vector<double>{0, 60, 120, 180, 240, 300}));
  EXPECT_EQ(CheckStopAngles(4, 10, 36.0), (std::vector<double>{0, 108, 180, 288}));
  EXPECT_EQ(CheckStopAngles(5, 3, 120.0).size(), 3u);
}

}  // namespace
}  // namespace revolve::calibrate
