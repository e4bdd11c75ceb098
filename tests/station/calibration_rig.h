// The issue's simulated rig "slightly off the thesis's assumptions" for the calibration wiring
// tests (tests/station/calibrate_command_test.cc, tests/e2e/calibrated_scan_test.cc): the
// synthetic camera with its axis 15 px right of the middle column (principal point moved), rolled
// 3 deg about its optical axis, 20 deg above the plate (so that a board lying on the plate is
// seen), and images of the board rendered as that camera would see it: held in front of it (the
// lens step) or lying on the plate at each stop (the axis step and the check).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "../calibrate/sim_rigs.h"
#include "calibrate/board_render.h"
#include "capture/camera.h"
#include "capture/synthetic/synthetic_camera.h"

namespace revolve::calibration_rig {

inline constexpr double kAxisOffsetPx = 15.0;
inline constexpr double kRollDeg = 3.0;
inline constexpr double kElevationDeg = 20.0;
inline constexpr double kTargetHeightMm = 40.0;

// [camera.synthetic] of the rig: a sphere of radius 40 mm.
inline capture::SyntheticOptions SyntheticOptions() {
  capture::SyntheticOptions o;
  o.object = "sphere";
  o.radius_mm = 40.0;
  o.elevation_deg = kElevationDeg;
  o.target_height_mm = kTargetHeightMm;
  o.axis_offset_px = kAxisOffsetPx;
  o.roll_deg = kRollDeg;
  return o;
}

// The same as TOML, with the true geometry hidden from the station (a real camera) unless
// `known_geometry`.
inline std::string SyntheticToml(bool known_geometry) {
  return fmt::format(R"([camera]
backend = "synthetic"

[camera.synthetic]
object = "sphere"
radius_mm = 40.0
elevation_deg = {}
target_height_mm = {}
axis_offset_px = {}
roll_deg = {}
known_geometry = {}
)",
                     kElevationDeg, kTargetHeightMm, kAxisOffsetPx, kRollDeg,
                     known_geometry ? "true" : "false");
}

// The true rig and lens (the synthetic camera has no distortion).
inline Rig TrueRig() { return capture::RigFromOptions(SyntheticOptions()); }
inline calibrate::CameraModel TrueLens() {
  return calibrate::CameraModel{TrueRig().intrinsics, {}};
}

// The board: 9 x 6 inner corners of 15 mm.
inline calibrate::Board TestBoard() { return calibrate::sim::TestBoard(); }

// `count` hand-held views of `board` for the lens step, written as view_00.png ...
inline void WriteLensImages(const std::filesystem::path& dir, const calibrate::Board& board,
                            int count, std::uint64_t seed = 1) {
  std::filesystem::create_directories(dir);
  const calibrate::CameraModel lens = TrueLens();
  int k = 0;
  for (const Eigen::Isometry3d& pose : calibrate::sim::HandHeldPoses(lens, board, count)) {
    calibrate::BoardRenderOptions options;
    options.seed = seed + static_cast<std::uint64_t>(k);
    options.blur_sigma_px = 0.5;
    Expected<cv::Mat> image = calibrate::RenderBoard(lens, pose, board, options);
    if (!image) throw std::runtime_error(image.error().ToString());
    cv::imwrite((dir / fmt::format("view_{:02d}.png", k)).string(), *image);
    ++k;
  }
}

// The board fixed to the plate at `object_from_board`, seen by `rig` at stop k (plate angle
// k * step_deg) for every k in `stops`, written as board_000.png ... (the stop's index): a
// folder for [camera.replay] pattern = "board_{index:03}.png", order = "angle".
inline void WriteTableImages(const std::filesystem::path& dir, const Rig& rig,
                             const Eigen::Isometry3d& object_from_board,
                             const calibrate::Board& board, const std::vector<int>& stops,
                             double step_deg, std::uint64_t seed = 100) {
  std::filesystem::create_directories(dir);
  for (int k : stops) {
    calibrate::BoardRenderOptions options;
    options.seed = seed + static_cast<std::uint64_t>(k);
    options.blur_sigma_px = 0.5;
    Expected<cv::Mat> image =
        calibrate::RenderBoardOnTable(rig, {}, k * step_deg, object_from_board, board, options);
    if (!image) throw std::runtime_error(image.error().ToString());
    cv::imwrite((dir / fmt::format("board_{:03d}.png", k)).string(), *image);
  }
}

// A config whose camera replays `dir`'s board_NNN.png at the mock turntable's angle.
inline std::string ReplayRigToml(const std::filesystem::path& dir, int stops, double step_deg) {
  return fmt::format(R"([scan]
stops = {}
step_deg = {}
settle_ms = 0

[turntable.mock]
time_scale = 0.01

[camera]
backend = "replay"

[camera.replay]
dir = "{}"
pattern = "board_{{index:03}}.png"
step_deg = {}
order = "angle"
)",
                     stops, step_deg, dir.string(), step_deg);
}

// The board's TOML, [calibration.board].
inline std::string BoardToml(const calibrate::Board& board) {
  return fmt::format("[calibration.board]\ncols = {}\nrows = {}\nsquare_mm = {}\n", board.cols,
                     board.rows, board.square_mm);
}

inline std::vector<int> AllStops(int stops) {
  std::vector<int> out;
  for (int k = 0; k < stops; ++k) out.push_back(k);
  return out;
}

}  // namespace revolve::calibration_rig
