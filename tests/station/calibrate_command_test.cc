// `revolve calibrate` as a library call (station/calibrate_command.h): the board verb, the lens
// from a folder and from the camera with piped Enter presses, the axis step with the lens of a
// file, bad input (no board, a board of the wrong size, too few views) exiting non-zero with a
// message naming the cause; the [calibration] table of the station config; and the scan geometry
// (station/scan_geometry.h).
#include "station/commands/calibrate_command.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "calibrate/calibration.h"
#include "calibration_rig.h"
#include "config/config.h"
#include "station/commands/scan_command.h"
#include "station/scan_geometry.h"
#include "station/station_config.h"
#include "tests/support/test_files.h"

namespace revolve::station {
namespace {

namespace fs = std::filesystem;
namespace rig = calibration_rig;

struct Outcome {
  int code = -1;
  std::string out;
  std::string err;
};

class CalibrateCommandTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test_support::FreshTestDir("revolve_calibrate_cmd"); }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  Outcome Run(const CalibrateCommandOptions& options, const std::string& input = "") {
    std::istringstream in(input);
    std::ostringstream out;
    std::ostringstream err;
    Outcome o;
    o.code = RunCalibrateCommand(options, std::stop_token(), in, out, err);
    o.out = out.str();
    o.err = err.str();
    return o;
  }

  fs::path WriteConfig(const std::string& name, const std::string& text) {
    const fs::path path = dir_ / name;
    std::ofstream(path) << text;
    return path;
  }

  // Lens options reading `images`, with the test board.
  CalibrateCommandOptions LensFromImages(const fs::path& images) {
    CalibrateCommandOptions options;
    options.step = CalibrateStep::kLens;
    options.images = images;
    options.out = dir_ / "cal.toml";
    options.cols = 9;
    options.rows = 6;
    options.square_mm = 15.0;
    return options;
  }

  fs::path dir_;
};

TEST_F(CalibrateCommandTest, BoardWritesAPrintableImage) {
  CalibrateCommandOptions options;
  options.step = CalibrateStep::kBoard;
  options.out = dir_ / "board.png";
  const Outcome o = Run(options);
  ASSERT_EQ(o.code, kExitOk) << o.err;
  const cv::Mat image = cv::imread(options.out->string(), cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(image.cols, 2598);
  EXPECT_EQ(image.rows, 1890);
  EXPECT_NE(o.out.find("220 x 160 mm"), std::string::npos) << o.out;
  EXPECT_NE(o.out.find("chessboard 9x6 inner corners, 20 mm squares"), std::string::npos);
}

TEST_F(CalibrateCommandTest, NoBoardFoundNamesTheCause) {
  fs::create_directories(dir_ / "blank");
  for (int k = 0; k < 4; ++k) {
    cv::imwrite((dir_ / "blank" / fmt::format("img{}.png", k)).string(),
                cv::Mat(576, 768, CV_8UC3, cv::Scalar(90, 90, 90)));
  }
  const Outcome o = Run(LensFromImages(dir_ / "blank"));
  EXPECT_EQ(o.code, kExitFailed);
  EXPECT_NE(o.err.find("calibration refused: the board was found in 0 of 4 views"),
            std::string::npos)
      << o.err;
  EXPECT_NE(o.err.find("img0.png: no chessboard of 9x6 inner corners found"), std::string::npos)
      << o.err;
  EXPECT_FALSE(fs::exists(dir_ / "cal.toml"));
}

TEST_F(CalibrateCommandTest, WrongBoardSizeSaysWhatWasFound) {
  calibrate::Board printed = rig::TestBoard();
  printed.cols = 7;
  printed.rows = 5;
  rig::WriteLensImages(dir_ / "lens", printed, 3);
  const Outcome o = Run(LensFromImages(dir_ / "lens"));  // configured 9x6
  EXPECT_EQ(o.code, kExitFailed);
  EXPECT_NE(o.err.find("no chessboard of 9x6 inner corners found, but one of 7x5"),
            std::string::npos)
      << o.err;
}

TEST_F(CalibrateCommandTest, TooFewViewsAreRefused) {
  rig::WriteLensImages(dir_ / "lens", rig::TestBoard(), 4);
  const Outcome o = Run(LensFromImages(dir_ / "lens"));
  EXPECT_EQ(o.code, kExitFailed);
  EXPECT_NE(o.err.find("the board was found in only 4 of 4 views (need 10"), std::string::npos)
      << o.err;
  EXPECT_FALSE(fs::exists(dir_ / "cal.toml"));
}

TEST_F(CalibrateCommandTest, BadBoardFlagIsAUsageError) {
  CalibrateCommandOptions options = LensFromImages(dir_);
  options.type = "hexagons";
  const Outcome o = Run(options);
  EXPECT_EQ(o.code, kExitUsage);
  EXPECT_NE(o.err.find("--type hexagons"), std::string::npos) << o.err;
}

// The lens from the configured camera: a replay camera serving hand-held views in sequence, the
// views taken by piped Enter presses, "q" to finish.
TEST_F(CalibrateCommandTest, LensFromTheCameraWithPipedInput) {
  rig::WriteLensImages(dir_ / "lens", rig::TestBoard(), 12);
  const fs::path config = WriteConfig("rig.toml", fmt::format(R"([camera]
backend = "replay"
[camera.replay]
dir = "lens"
order = "sequence"
[calibration]
file = "lens.toml"
{})",
                                                              rig::BoardToml(rig::TestBoard())));
  CalibrateCommandOptions options;
  options.step = CalibrateStep::kLens;
  options.config = config;
  std::string input;
  for (int k = 0; k < 12; ++k) input += "\n";
  input += "q\n";
  const Outcome o = Run(options, input);
  ASSERT_EQ(o.code, kExitOk) << o.err << o.out;
  EXPECT_NE(o.out.find("view 12: board found (54 corners)"), std::string::npos) << o.out;
  EXPECT_NE(o.out.find("lens only"), std::string::npos);
  // Written where [calibration] file says, relative to the config's folder.
  Expected<calibrate::Calibration> cal = calibrate::LoadCalibration(dir_ / "lens.toml");
  ASSERT_TRUE(cal) << cal.error().ToString();
  EXPECT_FALSE(cal->axis.has_value());
  EXPECT_EQ(cal->lens.views, 12);
  const Intrinsics truth = rig::TrueRig().intrinsics;
  EXPECT_NEAR(cal->camera.intrinsics.fx_px, truth.fx_px, 0.005 * truth.fx_px);
  EXPECT_NEAR(cal->camera.intrinsics.cx_px, truth.cx_px, 2.0);
}

// `revolve calibrate axis --calibration FILE`: the lens of FILE, the board lying on the plate
// turned by the mock turntable (replay camera), FILE rewritten with the axis.
TEST_F(CalibrateCommandTest, AxisStepAddsTheAxisToTheFile) {
  calibrate::IntrinsicsResult lens;
  lens.camera = rig::TrueLens();
  const calibrate::Board board = rig::TestBoard();
  ASSERT_TRUE(calibrate::SaveCalibration(calibrate::Calibration::From(board, lens, std::nullopt),
                                         dir_ / "cal.toml"));
  rig::WriteTableImages(dir_ / "axis", rig::TrueRig(), calibrate::sim::LyingBoard(board), board,
                        rig::AllStops(12), 30.0);
  CalibrateCommandOptions options;
  options.step = CalibrateStep::kAxis;
  options.config =
      WriteConfig("rig.toml", rig::ReplayRigToml(dir_ / "axis", 12, 30.0) + rig::BoardToml(board));
  options.calibration = dir_ / "cal.toml";
  const Outcome o = Run(options, "\n");
  ASSERT_EQ(o.code, kExitOk) << o.err << o.out;
  EXPECT_NE(o.out.find("[ 12/12]  330.0 deg (read back  330.00)  board: 54 corners"),
            std::string::npos)
      << o.out;
  Expected<calibrate::Calibration> cal = calibrate::LoadCalibration(dir_ / "cal.toml");
  ASSERT_TRUE(cal) << cal.error().ToString();
  ASSERT_TRUE(cal->axis.has_value());
  const Rig truth = rig::TrueRig();
  EXPECT_LT((cal->axis->cam_from_table.translation() - truth.cam_from_table.translation()).norm(),
            0.5);
}

TEST_F(CalibrateCommandTest, AxisWithoutTheBoardSaysWhy) {
  calibrate::IntrinsicsResult lens;
  lens.camera = rig::TrueLens();
  ASSERT_TRUE(calibrate::SaveCalibration(
      calibrate::Calibration::From(rig::TestBoard(), lens, std::nullopt), dir_ / "cal.toml"));
  fs::create_directories(dir_ / "empty");
  for (int k = 0; k < 6; ++k) {
    cv::imwrite((dir_ / "empty" / fmt::format("board_{:03d}.png", k)).string(),
                cv::Mat(576, 768, CV_8UC3, cv::Scalar(50, 50, 50)));
  }
  CalibrateCommandOptions options;
  options.step = CalibrateStep::kAxis;
  options.config = WriteConfig(
      "rig.toml", rig::ReplayRigToml(dir_ / "empty", 6, 60.0) + rig::BoardToml(rig::TestBoard()));
  options.calibration = dir_ / "cal.toml";
  const Outcome o = Run(options);
  EXPECT_EQ(o.code, kExitFailed);
  EXPECT_NE(o.err.find("axis calibration refused: the board was found at 0 of 6 stops"),
            std::string::npos)
      << o.err;
  EXPECT_NE(o.err.find("no chessboard of 9x6 inner corners found"), std::string::npos) << o.err;
}

TEST_F(CalibrateCommandTest, CheckWithoutACalibrationIsAConfigError) {
  CalibrateCommandOptions options;
  options.step = CalibrateStep::kCheck;
  const Outcome o = Run(options);
  EXPECT_EQ(o.code, kExitConfig);
  EXPECT_NE(o.err.find("no calibration to check"), std::string::npos) << o.err;
}

TEST_F(CalibrateCommandTest, CheckOfAMissingFileIsAConfigError) {
  CalibrateCommandOptions options;
  options.step = CalibrateStep::kCheck;
  options.calibration = dir_ / "nowhere.toml";
  const Outcome o = Run(options);
  EXPECT_EQ(o.code, kExitConfig);
  EXPECT_NE(o.err.find("nowhere.toml"), std::string::npos) << o.err;
}

// --- [calibration] in the station config ---

TEST(CalibrationConfig, FileIsRelativeToTheConfigFile) {
  Expected<config::Document> document =
      config::Parse("[calibration]\nfile = \"cal/rig.toml\"\n", "/etc/revolve/rig.toml");
  ASSERT_TRUE(document);
  Expected<StationConfig> config = ParseStationConfig(*document);
  ASSERT_TRUE(config) << config.error().ToString();
  EXPECT_EQ(config->calibration.file, fs::path("/etc/revolve/cal/rig.toml"));
}

TEST(CalibrationConfig, AbsentMeansNone) {
  Expected<StationConfig> config = LoadStationConfig(std::nullopt);
  ASSERT_TRUE(config) << config.error().ToString();
  EXPECT_TRUE(config->calibration.file.empty());
}

TEST(CalibrationConfig, UnknownKeysNameFileLineAndColumn) {
  Expected<config::Document> document = config::Parse(
      "[scan]\nstops = 4\n\n[calibration.board]\ncols = 9\nsquare = 20\n", "rig.toml");
  ASSERT_TRUE(document);
  Expected<StationConfig> config = ParseStationConfig(*document);
  ASSERT_FALSE(config);
  EXPECT_NE(config.error().message.find("rig.toml:6:1"), std::string::npos)
      << config.error().message;
  EXPECT_NE(config.error().message.find("square"), std::string::npos);
}

// --- the scan geometry ---

TEST(ScanGeometry, ThesisViewWithAxisPutsTheAxisOnTheLine) {
  const int width = 768;
  const int height = 576;
  const double column = 398.5;
  const double tilt_deg = 3.0;
  const double row0 = 0.5 * (height - 1);
  for (double angle : {0.0, 70.0, 200.0}) {
    const View view = ThesisViewWithAxis(width, height, angle, column, tilt_deg);
    // Points on the axis land on u = column + tan(tilt) (v - row0), whatever the angle.
    for (double z : {0.0, 150.0, 400.0}) {
      Eigen::Vector2d pixel;
      ASSERT_TRUE(view.Project(Eigen::Vector3d(0.0, 0.0, z), &pixel));
      EXPECT_NEAR(pixel.x(), column + std::tan(tilt_deg * M_PI / 180.0) * (pixel.y() - row0), 1e-9);
    }
  }
  // No tilt, the middle column: the thesis's view.
  const View plain = ThesisViewWithAxis(width, height, 30.0, 0.5 * (width - 1), 0.0);
  EXPECT_TRUE(plain.IsAffine());
  Eigen::Vector2d pixel;
  ASSERT_TRUE(plain.Project(Eigen::Vector3d(10.0, 0.0, 0.0), &pixel));
  EXPECT_NEAR(pixel.x(), 383.5 + 10.0 * std::cos(30.0 * M_PI / 180.0), 1e-9);
  EXPECT_NEAR(pixel.y(), height - 1, 1e-9);
}

class ScanGeometryTest : public CalibrateCommandTest {
 protected:
  void SetUp() override {
    CalibrateCommandTest::SetUp();
    auto camera = capture::Create(capture::CameraOptions{}, std::make_shared<SimulatedPlate>());
    ASSERT_TRUE(camera);
    camera_ = std::move(*camera);
  }

  // The simulated camera's scan geometry from a calibration of `lens` (and `axis`) saved as
  // `name` in the test's folder.
  Expected<ScanGeometry> GeometryFrom(const calibrate::IntrinsicsResult& lens,
                                      const std::optional<calibrate::AxisResult>& axis,
                                      const std::string& name) {
    EXPECT_TRUE(calibrate::SaveCalibration(
        calibrate::Calibration::From(rig::TestBoard(), lens, axis), dir_ / name));
    return ScanGeometry::Create({}, *camera_, dir_ / name);
  }

  std::unique_ptr<capture::Camera> camera_;
};

TEST_F(ScanGeometryTest, ALensOnlyCalibrationIsRefusedWithWhatToDo) {
  calibrate::IntrinsicsResult lens;
  lens.camera = rig::TrueLens();
  Expected<ScanGeometry> geometry = GeometryFrom(lens, std::nullopt, "lens.toml");
  ASSERT_FALSE(geometry);
  EXPECT_NE(geometry.error().message.find("revolve calibrate axis --calibration"),
            std::string::npos)
      << geometry.error().message;
}

TEST_F(ScanGeometryTest, FramesOfAnotherSizeAreRefused) {
  calibrate::IntrinsicsResult lens;
  lens.camera = rig::TrueLens();
  calibrate::AxisResult axis;
  axis.cam_from_table = rig::TrueRig().cam_from_table;
  Expected<ScanGeometry> geometry = GeometryFrom(lens, axis, "cal.toml");
  ASSERT_TRUE(geometry) << geometry.error().ToString();
  EXPECT_EQ(geometry->source(), GeometrySource::kCalibration);
  EXPECT_TRUE(geometry->metric());
  EXPECT_TRUE(geometry->CheckFrameSize(768, 576));
  Expected<void> other = geometry->CheckFrameSize(1280, 720);
  ASSERT_FALSE(other);
  EXPECT_NE(other.error().message.find("1280x720"), std::string::npos) << other.error().message;
  EXPECT_NE(other.error().message.find("cal.toml"), std::string::npos);
}

TEST_F(ScanGeometryTest, FramesAreUndistortedWithTheCalibratedLens) {
  calibrate::IntrinsicsResult lens;
  lens.camera = rig::TrueLens();
  lens.camera.distortion = {-0.12, 0.09, 0.0004, -0.0003, 0.0};
  calibrate::AxisResult axis;
  axis.cam_from_table = rig::TrueRig().cam_from_table;
  Expected<ScanGeometry> geometry = GeometryFrom(lens, axis, "cal.toml");
  ASSERT_TRUE(geometry) << geometry.error().ToString();
  cv::Mat frame(576, 768, CV_8UC3);
  cv::randu(frame, cv::Scalar::all(0), cv::Scalar::all(255));
  const cv::Mat undistorted = geometry->Undistort(frame);
  const cv::Mat expected = calibrate::UndistortFrame(lens.camera, frame);
  ASSERT_EQ(undistorted.size(), frame.size());
  EXPECT_EQ(cv::norm(undistorted, expected, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(undistorted, frame, cv::NORM_L1), 0.0);
  EXPECT_TRUE(geometry->ReportJson()["calibration"]["undistorted"].get<bool>());
  // No calibration: frames pass as they are.
  Expected<ScanGeometry> none = ScanGeometry::Create({}, *camera_, {});
  ASSERT_TRUE(none);
  EXPECT_EQ(none->Undistort(frame).data, frame.data);
}

TEST(ScanGeometrySources, CameraGeometryOrThesis) {
  capture::CameraOptions options;
  auto known = capture::Create(options, std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(known);
  Expected<ScanGeometry> camera = ScanGeometry::Create({}, **known, {});
  ASSERT_TRUE(camera);
  EXPECT_EQ(camera->source(), GeometrySource::kCamera);
  EXPECT_EQ(camera->ReportJson()["units"], "mm");
  options.synthetic.known_geometry = false;
  auto hidden = capture::Create(options, std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(hidden);
  EXPECT_FALSE((*hidden)->KnownView(0.0).has_value());
  EXPECT_FALSE((*hidden)->KnownRig().has_value());
  EXPECT_TRUE((*hidden)->KnownScene().has_value());
  Expected<ScanGeometry> thesis = ScanGeometry::Create({}, **hidden, {});
  ASSERT_TRUE(thesis);
  EXPECT_EQ(thesis->source(), GeometrySource::kThesis);
  EXPECT_FALSE(thesis->metric());
  const nlohmann::json report = thesis->ReportJson();
  EXPECT_EQ(report["units"], "px");
  EXPECT_EQ(report["scale"], "unknown");
}

}  // namespace
}  // namespace revolve::station
