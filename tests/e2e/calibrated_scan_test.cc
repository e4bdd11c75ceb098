// End to end, the issue's acceptance test: the real `revolve` binary calibrating a simulated rig
// slightly off the thesis's assumptions (axis 15 px off centre, camera rolled 3 deg) from
// rendered board frames, then scanning a known sphere with that calibration (millimetres,
// accuracy against the truth) and without it (thesis mode: pixels, scale unknown), rebuilding
// both scans with `revolve reconstruct SCAN_DIR`, and `revolve calibrate check` passing the
// unchanged rig and failing a moved camera.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../station/calibration_rig.h"
#include "calibrate/calibration.h"
#include "calibrate/check.h"
#include "calibrate/silhouette_axis.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/metrics/metrics.h"
#include "tests/support/test_files.h"

namespace fs = std::filesystem;

namespace revolve {
namespace {

namespace rig = calibration_rig;

using test_support::ReadAll;
using test_support::RunResult;

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

// The axis step turns the board through 24 stops of 15 deg.
constexpr int kAxisStops = 24;
constexpr double kAxisStepDeg = 15.0;

class CalibratedScanTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test_support::FreshTestDir("revolve_calibrated"); }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  RunResult Run(const std::string& args) {
    return test_support::RunShell(
        "cd " + dir_.string() + " && " + std::string(REVOLVE_BIN) + " " + args, dir_);
  }

  void Write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name) << text;
  }

  // `revolve calibrate` on the rig: lens from 15 hand-held views (--images), then the axis with
  // the board lying on the plate, turned by the mock turntable and seen through a replay camera
  // serving the rendered frames. Writes cal.toml.
  void Calibrate() {
    const calibrate::Board board = rig::TestBoard();
    rig::WriteLensImages(dir_ / "lens", board, 15);
    rig::WriteTableImages(dir_ / "axis", rig::TrueRig(), calibrate::sim::LyingBoard(board), board,
                          rig::AllStops(kAxisStops), kAxisStepDeg);
    Write("calibrate.toml", rig::ReplayRigToml(dir_ / "axis", kAxisStops, kAxisStepDeg) +
                                "\n[calibration]\nfile = \"cal.toml\"\n\n" + rig::BoardToml(board));
    const RunResult r = Run("calibrate --config calibrate.toml --images lens");
    std::printf("%s", r.out.c_str());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    ASSERT_TRUE(fs::exists(dir_ / "cal.toml"));
  }

  // A scan of the sphere by the synthetic camera with its geometry hidden; with cal.toml when
  // `calibrated`.
  std::string ScanToml(bool calibrated) {
    return std::string(R"([scan]
stops = 36
step_deg = 10.0
settle_ms = 0

[turntable.mock]
time_scale = 0.01

[reconstruct]
formats = ["ply"]
texture = false

)") + rig::SyntheticToml(false) +
           (calibrated ? "\n[calibration]\nfile = \"cal.toml\"\n" : "");
  }

  fs::path dir_;
};

TEST_F(CalibratedScanTest, CalibrateThenScanInMillimetres) {
  ASSERT_NO_FATAL_FAILURE(Calibrate());

  // Recovered vs true.
  Expected<calibrate::Calibration> cal = calibrate::LoadCalibration(dir_ / "cal.toml");
  ASSERT_TRUE(cal) << cal.error().ToString();
  ASSERT_TRUE(cal->axis.has_value());
  const Rig truth = rig::TrueRig();
  const Intrinsics& got = cal->camera.intrinsics;
  const Eigen::Isometry3d& cam_from_table = cal->axis->cam_from_table;
  const double fx_error = 100.0 * (got.fx_px - truth.intrinsics.fx_px) / truth.intrinsics.fx_px;
  const double fy_error = 100.0 * (got.fy_px - truth.intrinsics.fy_px) / truth.intrinsics.fy_px;
  const double axis_deg =
      AngleDeg(cam_from_table.linear().col(2), truth.cam_from_table.linear().col(2));
  const double centre_mm =
      (cam_from_table.translation() - truth.cam_from_table.translation()).norm();
  std::printf(
      "recovered vs true: fx %.2f vs %.2f px (%+.3f%%), fy %.2f vs %.2f px (%+.3f%%), cx %.2f vs "
      "%.2f px, cy %.2f vs %.2f px; axis direction off by %.4f deg, plate centre off by %.3f mm "
      "((%.2f, %.2f, %.2f) vs (%.2f, %.2f, %.2f) mm); lens RMS %.3f px, axis RMS %.3f px\n",
      got.fx_px, truth.intrinsics.fx_px, fx_error, got.fy_px, truth.intrinsics.fy_px, fy_error,
      got.cx_px, truth.intrinsics.cx_px, got.cy_px, truth.intrinsics.cy_px, axis_deg, centre_mm,
      cam_from_table.translation().x(), cam_from_table.translation().y(),
      cam_from_table.translation().z(), truth.cam_from_table.translation().x(),
      truth.cam_from_table.translation().y(), truth.cam_from_table.translation().z(),
      cal->lens.rms_px, cal->axis->reprojection_rms_px);
  EXPECT_LT(std::abs(fx_error), 0.5);
  EXPECT_LT(std::abs(fy_error), 0.5);
  EXPECT_LT(std::abs(got.cx_px - truth.intrinsics.cx_px), 2.0);
  EXPECT_LT(std::abs(got.cy_px - truth.intrinsics.cy_px), 2.0);
  EXPECT_LT(axis_deg, 0.2);
  EXPECT_LT(centre_mm, 0.5);

  // A scan with the calibration: millimetres, the file copied, accurate.
  Write("scan.toml", ScanToml(true));
  const RunResult scan = Run("scan --config scan.toml --out scan_cal");
  ASSERT_EQ(scan.exit_code, 0) << scan.err << scan.out;
  EXPECT_TRUE(fs::exists(dir_ / "scan_cal" / "calibration.toml"));
  const nlohmann::json report = nlohmann::json::parse(ReadAll(dir_ / "scan_cal" / "report.json"));
  EXPECT_EQ(report["units"], "mm");
  ASSERT_TRUE(report.contains("calibration"));
  EXPECT_EQ(report["calibration"]["created"], cal->created);
  EXPECT_NE(report["calibration"]["file"].get<std::string>().find("cal.toml"), std::string::npos);
  ASSERT_TRUE(report.contains("accuracy"));
  const nlohmann::json& accuracy = report["accuracy"];
  const double radius_error = accuracy["sphere_radius_error_percent"].get<double>();
  const double volume_error = accuracy["volume_error_percent"].get<double>();
  std::printf(
      "calibrated scan: sphere radius %.3f mm (true 40, %+.3f%%), volume %+.3f%%, surface "
      "distance mean %.3f mm, centre off by %.3f mm; silhouette axis column %.2f px vs "
      "calibrated %.2f px\n",
      accuracy["sphere_fitted_radius_mm"].get<double>(), radius_error, volume_error,
      accuracy["mean_surface_distance_mm"].get<double>(),
      accuracy["sphere_center_error_mm"].get<double>(),
      report["silhouette_axis"].value("column_px", 0.0),
      report["silhouette_axis"].value("calibrated_column_px", 0.0));
  EXPECT_LT(std::abs(radius_error), 1.0);
  EXPECT_LT(std::abs(volume_error), 3.0);
  EXPECT_LT(accuracy["sphere_center_error_mm"].get<double>(), 1.0);

  // `revolve reconstruct SCAN_DIR` rebuilds it the same way (the folder's calibration.toml).
  const RunResult rebuilt = Run("reconstruct scan_cal --out rebuilt");
  ASSERT_EQ(rebuilt.exit_code, 0) << rebuilt.err;
  EXPECT_NE(rebuilt.out.find("calibration geometry"), std::string::npos) << rebuilt.out;
  Expected<reconstruct::Mesh> mesh = reconstruct::ReadPly(dir_ / "rebuilt" / "model.ply");
  ASSERT_TRUE(mesh) << mesh.error().ToString();
  const double volume = reconstruct::ComputeStats(*mesh).volume_mm3;
  EXPECT_NEAR(volume, report["model"]["volume_mm3"].get<double>(),
              0.01 * report["model"]["volume_mm3"].get<double>());
}

TEST_F(CalibratedScanTest, WithoutCalibrationTheScaleIsUnknown) {
  Write("scan.toml", ScanToml(false));
  const RunResult scan = Run("scan --config scan.toml --out scan_px");
  ASSERT_EQ(scan.exit_code, 0) << scan.err << scan.out;
  EXPECT_NE(scan.out.find(" px^3 (no calibration: scale unknown)"), std::string::npos) << scan.out;
  EXPECT_FALSE(fs::exists(dir_ / "scan_px" / "calibration.toml"));
  const nlohmann::json report = nlohmann::json::parse(ReadAll(dir_ / "scan_px" / "report.json"));
  EXPECT_EQ(report["units"], "px");
  EXPECT_EQ(report["scale"], "unknown");
  EXPECT_FALSE(report.contains("accuracy"));  // the truth is in mm
  EXPECT_FALSE(report["model"].contains("volume_mm3")) << "pixels are not millimetres";
  // The axis line fitted to the silhouettes replaces the middle column.
  const nlohmann::json& axis = report["silhouette_axis"];
  ASSERT_TRUE(axis.contains("column_px")) << axis.dump();
  EXPECT_TRUE(axis["used"].get<bool>());
  const double true_column = calibrate::ProjectedAxisLine(rig::TrueRig()).column_px;
  EXPECT_NEAR(axis["column_px"].get<double>(), true_column, 1.5);
  EXPECT_EQ(report["thesis_axis"]["source"], "silhouettes");

  // The model in pixels: the sphere's radius over the true magnification at the axis.
  Expected<reconstruct::Mesh> mesh = reconstruct::ReadPly(dir_ / "scan_px" / "model" / "model.ply");
  ASSERT_TRUE(mesh) << mesh.error().ToString();
  const reconstruct::SphereFit fit = reconstruct::FitSphere(*mesh);
  const double px_per_mm = rig::TrueRig().intrinsics.fx_px / 450.0;
  std::printf(
      "uncalibrated scan (thesis mode): axis column %.2f px (true %.2f, middle 383.5), sphere "
      "radius %.2f px = %.3f mm at the true %.4f px/mm (%+.2f%%), volume %.0f px^3 = %+.2f%% of "
      "the true sphere's\n",
      axis["column_px"].get<double>(), true_column, fit.radius_mm, fit.radius_mm / px_per_mm,
      px_per_mm, 100.0 * (fit.radius_mm / px_per_mm - 40.0) / 40.0,
      report["model"]["volume_px3"].get<double>(),
      100.0 * (report["model"]["volume_px3"].get<double>() / std::pow(px_per_mm, 3) /
                   (4.0 / 3.0 * M_PI * 40.0 * 40.0 * 40.0) -
               1.0));
  EXPECT_GT(fit.radius_mm, 0.9 * 40.0 * px_per_mm);
  EXPECT_LT(fit.radius_mm, 1.1 * 40.0 * px_per_mm);

  const RunResult rebuilt = Run("reconstruct scan_px --out rebuilt");
  ASSERT_EQ(rebuilt.exit_code, 0) << rebuilt.err;
  EXPECT_NE(rebuilt.out.find("thesis geometry"), std::string::npos) << rebuilt.out;
  EXPECT_NE(rebuilt.out.find("scale unknown"), std::string::npos) << rebuilt.out;
}

TEST_F(CalibratedScanTest, CheckPassesTheRigAndFailsAMovedCamera) {
  ASSERT_NO_FATAL_FAILURE(Calibrate());
  const calibrate::Board board = rig::TestBoard();
  // Today the board lies elsewhere on the plate.
  Eigen::Isometry3d today = calibrate::sim::LyingBoard(board);
  today.prerotate(calibrate::sim::Rz(70.0));
  today.pretranslate(Eigen::Vector3d(-6.0, 4.0, 0.0));
  std::vector<int> check_stops;
  for (double angle : calibrate::CheckStopAngles(6, kAxisStops, kAxisStepDeg)) {
    check_stops.push_back(static_cast<int>(std::lround(angle / kAxisStepDeg)));
  }
  auto check = [&](const std::string& name, const Rig& rig_today) {
    rig::WriteTableImages(dir_ / name, rig_today, today, board, check_stops, kAxisStepDeg, 500);
    Write(name + ".toml", rig::ReplayRigToml(dir_ / name, kAxisStops, kAxisStepDeg) +
                              "\n[calibration]\nfile = \"cal.toml\"\n");
    return Run("calibrate check --config " + name + ".toml");
  };

  const RunResult same = check("same", rig::TrueRig());
  std::printf("unchanged rig:\n%s", same.out.c_str());
  EXPECT_EQ(same.exit_code, 0) << same.err;
  EXPECT_NE(same.out.find("PASS"), std::string::npos);

  Rig turned = rig::TrueRig();
  turned.cam_from_table.prerotate(calibrate::sim::Rx(0.5));
  const RunResult nodded = check("turned", turned);
  std::printf("camera turned 0.5 deg:\n%s%s", nodded.out.c_str(), nodded.err.c_str());
  EXPECT_EQ(nodded.exit_code, 1);
  EXPECT_NE(nodded.out.find("FAIL"), std::string::npos);
  EXPECT_NE(nodded.err.find("no longer matches"), std::string::npos);

  Rig shifted = rig::TrueRig();
  shifted.cam_from_table.pretranslate(Eigen::Vector3d(2.0, 0.0, 0.0));
  const RunResult moved = check("shifted", shifted);
  std::printf("camera shifted 2 mm:\n%s%s", moved.out.c_str(), moved.err.c_str());
  EXPECT_EQ(moved.exit_code, 1);
  EXPECT_NE(moved.out.find("FAIL"), std::string::npos);
}

}  // namespace
}  // namespace revolve
