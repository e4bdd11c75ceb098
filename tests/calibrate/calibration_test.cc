// The calibration file (round trip, errors that name file:line and key), the config section, and
// undistortion turning frames into ones the pinhole Rig describes.
#include "calibrate/calibration.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "calibrate/board_render.h"
#include "calibrate/options.h"
#include "sim_rigs.h"

namespace revolve::calibrate {
namespace {

Calibration Sample() {
  Calibration c;
  c.software_version = "0.1.0";
  c.created = "2024-05-01T12:34:56Z";
  c.board = sim::TestBoard();
  c.camera = sim::TrueLens();
  c.camera.intrinsics.fx_px = 1100.123456789012;
  c.camera.distortion = {-0.12, 0.09, 0.0004, -0.0003, 1e-7};
  c.lens = {0.0321, 15, 0.6, 77.8};
  AxisCalibration a;
  a.cam_from_table = sim::OffRig(c.camera.intrinsics).cam_from_table;
  a.placement = BoardPlacement::kStanding;
  a.stops = 36;
  a.span_deg = 350.0;
  a.reprojection_rms_px = 0.047;
  a.corner_rms_mm = 0.017;
  a.corner_max_mm = 0.06;
  a.angle_rms_deg = 0.0028;
  a.wobble_deg = 0.001;
  c.axis = a;
  return c;
}

std::filesystem::path TempDir() {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("revolve_calibration_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

// Parses `text` with `line` replaced (or appended, when `find` is empty) and returns the error.
std::string ErrorOf(std::string text) {
  Expected<Calibration> c = ParseCalibration(std::move(text), "cal.toml");
  EXPECT_FALSE(c);
  return c ? std::string() : c.error().message;
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(CalibrationFile, RoundTripIsExact) {
  const Calibration c = Sample();
  const std::string text = FormatCalibration(c);
  Expected<Calibration> back = ParseCalibration(text, "mem");
  ASSERT_TRUE(back) << back.error().ToString() << "\n" << text;
  EXPECT_EQ(back->format_version, kCalibrationFormatVersion);
  EXPECT_EQ(back->software_version, "0.1.0");
  EXPECT_EQ(back->created, c.created);
  EXPECT_EQ(back->board.cols, 9);
  EXPECT_EQ(back->board.square_mm, 15.0);
  EXPECT_EQ(back->camera.intrinsics.fx_px, c.camera.intrinsics.fx_px);
  EXPECT_EQ(back->camera.intrinsics.cy_px, c.camera.intrinsics.cy_px);
  EXPECT_EQ(back->camera.intrinsics.width_px, 768);
  EXPECT_EQ(back->camera.distortion, c.camera.distortion);
  EXPECT_EQ(back->lens.views, 15);
  ASSERT_TRUE(back->axis);
  EXPECT_TRUE(back->axis->cam_from_table.matrix() == c.axis->cam_from_table.matrix());
  EXPECT_EQ(back->axis->placement, BoardPlacement::kStanding);
  EXPECT_EQ(back->axis->corner_rms_mm, 0.017);
  // People can read it.
  EXPECT_NE(text.find("# axis direction in the camera frame"), std::string::npos);
  EXPECT_NE(text.find("software_version = \"0.1.0\""), std::string::npos);
}

TEST(CalibrationFile, SaveAndLoad) {
  const std::filesystem::path path = TempDir() / "calibration.toml";
  Calibration c = Sample();
  c.software_version = std::string(SoftwareVersion());
  ASSERT_TRUE(SaveCalibration(c, path));
  Expected<Calibration> back = LoadCalibration(path);
  ASSERT_TRUE(back) << back.error().ToString();
  EXPECT_EQ(back->software_version, PROJECT_VERSION_FOR_TEST);
  Expected<Rig> rig = back->ToRig();
  ASSERT_TRUE(rig);
  EXPECT_TRUE(rig->cam_from_table.matrix() == c.axis->cam_from_table.matrix());
  EXPECT_EQ(rig->intrinsics.fx_px, c.camera.intrinsics.fx_px);
  std::filesystem::remove_all(path.parent_path());

  Expected<Calibration> missing = LoadCalibration(path);
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("revolve calibrate"), std::string::npos);
}

TEST(CalibrationFile, LensOnlyHasNoRig) {
  Calibration c = Sample();
  c.axis.reset();
  Expected<Calibration> back = ParseCalibration(FormatCalibration(c), "mem");
  ASSERT_TRUE(back);
  EXPECT_FALSE(back->axis);
  Expected<Rig> rig = back->ToRig();
  ASSERT_FALSE(rig);
  EXPECT_NE(rig.error().message.find("lens only"), std::string::npos);
}

TEST(CalibrationFile, ErrorsNameFileLineAndKey) {
  const std::string good = FormatCalibration(Sample());
  std::string m = ErrorOf(Replace(good, "fx_px = ", "fx_px = \"wide\" # "));
  EXPECT_NE(m.find("cal.toml:"), std::string::npos) << m;
  EXPECT_NE(m.find("lens.fx_px: expected a number"), std::string::npos) << m;

  std::string no_fy = good;
  no_fy.erase(no_fy.find("fy_px = "),
              no_fy.find('\n', no_fy.find("fy_px = ")) - no_fy.find("fy_px = "));
  m = ErrorOf(no_fy);
  EXPECT_NE(m.find("lens.fy_px: missing"), std::string::npos) << m;

  m = ErrorOf(Replace(good, "[board]", "[board"));
  EXPECT_NE(m.find("cal.toml:"), std::string::npos) << m;
  EXPECT_NE(m.find("TOML syntax error"), std::string::npos) << m;

  m = ErrorOf(Replace(good, "cam_from_table_rotation = [", "cam_from_table_rotation = [2, "));
  EXPECT_NE(m.find("axis.cam_from_table_rotation: expected 9 numbers"), std::string::npos) << m;

  m = ErrorOf(Replace(good, "cam_from_table_rotation = [", "cam_from_table_rotation = [2 + "));
  EXPECT_NE(m.find("TOML syntax error"), std::string::npos) << m;

  const std::size_t rot = good.find("cam_from_table_rotation = [") + 27;
  std::string skewed = good;
  skewed.insert(rot, "0.5");
  skewed.erase(rot + 3, skewed.find(',', rot + 3) - (rot + 3));
  m = ErrorOf(skewed);
  EXPECT_NE(m.find("not a rotation matrix"), std::string::npos) << m;

  m = ErrorOf(Replace(good, "format_version = 1", "format_version = 7"));
  EXPECT_NE(m.find("newer revolve"), std::string::npos) << m;

  m = ErrorOf(Replace(good, "[lens]\n", "[lens]\nfocal_mm = 8\n"));
  EXPECT_NE(m.find("unknown key \"lens.focal_mm\""), std::string::npos) << m;

  m = ErrorOf(Replace(good, "distortion = [", "distortion = [1, "));
  EXPECT_NE(m.find("expected 0, 4, 5 or 8 coefficients"), std::string::npos) << m;

  m = ErrorOf(Replace(good, "cols = 9", "cols = 2"));
  EXPECT_NE(m.find("board.cols"), std::string::npos) << m;
}

TEST(CalibrationFile, FrameSizeMustMatch) {
  const Calibration c = Sample();
  EXPECT_TRUE(c.CheckFrameSize(768, 576));
  Expected<void> wrong = c.CheckFrameSize(1920, 1080);
  ASSERT_FALSE(wrong);
  EXPECT_NE(wrong.error().message.find("1920x1080"), std::string::npos);
}

// Undistorted frames show the board where the pinhole rig (no distortion) projects it.
TEST(Undistort, FramesMatchThePinholeRig) {
  const CameraModel lens = sim::TrueLens();
  const Board board = sim::TestBoard();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = sim::Rx(20.0) * sim::Ry(-15.0);
  // Far off centre, where the distortion is strong.
  pose.translation() = Eigen::Vector3d(-95.0, -80.0, 520.0);
  Expected<cv::Mat> raw = RenderBoard(lens, pose, board);
  ASSERT_TRUE(raw);
  const Undistorter undistorter(lens);
  EXPECT_FALSE(undistorter.identity());
  const cv::Mat frame = undistorter.Apply(*raw);
  ASSERT_EQ(frame.size(), raw->size());
  Expected<Detection> d = DetectBoard(frame, board);
  ASSERT_TRUE(d) << d.error().ToString();
  Expected<Detection> d_raw = DetectBoard(*raw, board);
  ASSERT_TRUE(d_raw);
  double worst = 0.0;
  double worst_raw = 0.0;
  for (std::size_t i = 0; i < d->size(); ++i) {
    const Eigen::Vector3d h = lens.intrinsics.K() * (pose * board.Corner(d->ids[i]));
    const Eigen::Vector2d ideal = h.head<2>() / h.z();
    worst = std::max(worst, (ideal - Eigen::Vector2d(d->image_px[i].x, d->image_px[i].y)).norm());
    worst_raw = std::max(
        worst_raw, (ideal - Eigen::Vector2d(d_raw->image_px[i].x, d_raw->image_px[i].y)).norm());
  }
  std::printf(
      "board corners vs the pinhole projection: %.3f px after undistortion, %.3f px "
      "before\n",
      worst, worst_raw);
  EXPECT_LT(worst, 0.3);
  EXPECT_GT(worst_raw, 1.0);
  // No distortion: frames pass through untouched.
  CameraModel pinhole = lens;
  pinhole.distortion = {0.0, 0.0, 0.0, 0.0};
  EXPECT_TRUE(Undistorter(pinhole).identity());
  EXPECT_EQ(UndistortFrame(pinhole, *raw).data, raw->data);
}

TEST(Options, DefaultsAndKeys) {
  Expected<config::Document> doc = config::Parse(R"(
[calibration]
file = "rig/calibration.toml"
[calibration.board]
cols = 11
rows = 8
square_mm = 25.0
[calibration.intrinsics]
min_views = 12
max_rms_px = 0.5
[calibration.axis]
board_height_mm = 3.0
[calibration.check]
max_centre_mm = 0.8
)",
                                                 "/etc/revolve/revolve.toml");
  ASSERT_TRUE(doc);
  Expected<config::Section> section = config::Section::Root(*doc).Child("calibration");
  ASSERT_TRUE(section);
  Expected<CalibrationOptions> o = ParseCalibrationOptions(*section);
  ASSERT_TRUE(o) << o.error().ToString();
  EXPECT_EQ(o->file, std::filesystem::path("/etc/revolve/rig/calibration.toml"));
  EXPECT_EQ(o->board.cols, 11);
  EXPECT_EQ(o->board.square_mm, 25.0);
  EXPECT_EQ(o->intrinsics.min_views, 12);
  EXPECT_EQ(o->intrinsics.max_rms_px, 0.5);
  EXPECT_EQ(o->axis.board_height_mm, 3.0);
  EXPECT_EQ(o->check.max_centre_mm, 0.8);
  EXPECT_EQ(o->check.stops, CheckOptions{}.stops);

  Expected<config::Document> empty = config::Parse("", "x.toml");
  ASSERT_TRUE(empty);
  Expected<CalibrationOptions> defaults =
      ParseCalibrationOptions(*config::Section::Root(*empty).Child("calibration"));
  ASSERT_TRUE(defaults);
  EXPECT_TRUE(defaults->file.empty());
  EXPECT_EQ(defaults->board.cols, 9);
}

TEST(Options, ErrorsNameTheKey) {
  for (const auto& [text, expected] : std::vector<std::pair<std::string, std::string>>{
           {"[calibration.board]\nsquares = 9\n", "unknown key \"calibration.board.squares\""},
           {"[calibration.board]\ncols = \"nine\"\n",
            "calibration.board.cols: expected an integer"},
           {"[calibration.board]\ntype = \"circles\"\n", "calibration.board.type"},
           {"[calibration.check]\nmax_centre_mm = -1\n", "calibration.check.max_centre_mm"},
           {"[calibration]\nfiles = \"x\"\n", "unknown key \"calibration.files\""}}) {
    Expected<config::Document> doc = config::Parse(text, "r.toml");
    ASSERT_TRUE(doc);
    Expected<CalibrationOptions> o =
        ParseCalibrationOptions(*config::Section::Root(*doc).Child("calibration"));
    ASSERT_FALSE(o) << text;
    EXPECT_NE(o.error().message.find("r.toml:"), std::string::npos) << o.error().message;
    EXPECT_NE(o.error().message.find(expected), std::string::npos) << o.error().message;
  }
}

}  // namespace
}  // namespace revolve::calibrate
