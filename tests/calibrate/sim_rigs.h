// Simulated rigs and board poses shared by the calibration tests.
#pragma once

#include <cmath>
#include <numbers>
#include <vector>

#include <Eigen/Geometry>

#include "base/angles.h"
#include "base/rig.h"
#include "calibrate/board.h"
#include "calibrate/camera_model.h"

namespace revolve::calibrate::sim {

using revolve::Degrees;
using revolve::Radians;

inline Eigen::Matrix3d Rx(double deg) {
  return Eigen::AngleAxisd(Radians(deg), Eigen::Vector3d::UnitX()).toRotationMatrix();
}
inline Eigen::Matrix3d Ry(double deg) {
  return Eigen::AngleAxisd(Radians(deg), Eigen::Vector3d::UnitY()).toRotationMatrix();
}
inline Eigen::Matrix3d Rz(double deg) {
  return Eigen::AngleAxisd(Radians(deg), Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

// A lens that is not the ideal one: off-centre principal point, barrel distortion.
inline CameraModel TrueLens() {
  CameraModel camera;
  camera.intrinsics.width_px = 768;
  camera.intrinsics.height_px = 576;
  camera.intrinsics.fx_px = 1100.0;
  camera.intrinsics.fy_px = 1100.0;
  camera.intrinsics.cx_px = 391.3;
  camera.intrinsics.cy_px = 280.6;
  camera.distortion = {-0.12, 0.09, 0.0004, -0.0003, 0.0};
  return camera;
}

inline Board TestBoard() {
  Board board;
  board.cols = 9;
  board.rows = 6;
  board.square_mm = 15.0;
  return board;
}

// Board poses for an intrinsics calibration: the board held at `count` places spread over the
// image at 450-600 mm, tilted up to ~35 deg in varied directions, always wholly in view (with a
// margin of half a square around the squares).
inline std::vector<Eigen::Isometry3d> HandHeldPoses(const CameraModel& camera, const Board& board,
                                                    int count) {
  std::vector<Eigen::Isometry3d> poses;
  const Intrinsics& in = camera.intrinsics;
  const double s = board.square_mm;
  const Eigen::Vector3d centre_board(0.5 * (board.cols - 1) * s, 0.5 * (board.rows - 1) * s, 0.0);
  const double spots[9][2] = {{0, 0},  {-1, -1}, {1, -1}, {-1, 1}, {1, 1},
                              {0, -1}, {0, 1},   {-1, 0}, {1, 0}};
  for (int i = 0; i < count; ++i) {
    const double depth = 450.0 + 150.0 * ((i * 7) % 5) / 4.0;
    Eigen::Isometry3d cam_from_board = Eigen::Isometry3d::Identity();
    cam_from_board.linear() = Rz(20.0 * std::sin(0.9 * i)) * Rx(32.0 * std::sin(1.7 * i + 0.3)) *
                              Ry(32.0 * std::cos(1.3 * i + 0.9));
    // Push the board toward the image's edges, as far as it stays in view.
    for (double reach = 1.0; reach > 0.0; reach -= 0.05) {
      const double su = spots[i % 9][0] * reach * 0.5 * in.width_px;
      const double sv = spots[i % 9][1] * reach * 0.5 * in.height_px;
      const Eigen::Vector3d target(su / in.fx_px * depth, sv / in.fy_px * depth, depth);
      cam_from_board.translation() = target - cam_from_board.linear() * centre_board;
      bool inside = true;
      for (double x : {-1.5 * s, (board.cols + 0.5) * s}) {
        for (double y : {-1.5 * s, (board.rows + 0.5) * s}) {
          const Eigen::Vector3d h = in.K() * (cam_from_board * Eigen::Vector3d(x, y, 0.0));
          const Eigen::Vector2d p = camera.DistortPixel(h.head<2>() / h.z());
          inside = inside && p.x() > 2.0 && p.y() > 2.0 && p.x() < in.width_px - 3.0 &&
                   p.y() < in.height_px - 3.0;
        }
      }
      if (inside) break;
    }
    poses.push_back(cam_from_board);
  }
  return poses;
}

// The rig "slightly off the thesis's assumptions": a camera 450 mm from the axis,
// `elevation_deg` above the plate (30 deg: a board lying on it is seen well), turned so that the
// axis appears 15 px right of the principal point, and rolled 3 deg about its optical axis.
inline Rig OffRig(const Intrinsics& intrinsics, double elevation_deg = 30.0,
                  double target_height_mm = 0.0) {
  Rig rig;
  rig.intrinsics = intrinsics;
  const Eigen::Isometry3d looking =
      CamFromTableLookingAtAxis(450.0, elevation_deg, target_height_mm);
  Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
  // Turning the camera about its y axis by atan(15 / fx) moves the axis 15 px to the right;
  // then the roll.
  turn.linear() = Rz(3.0) * Ry(Degrees(std::atan(15.0 / intrinsics.fx_px)));
  rig.cam_from_table = turn * looking;
  return rig;
}

// A board lying face up on the plate: board z (into the print) points down, its centre 12 mm
// from the axis, turned 25 deg.
inline Eigen::Isometry3d LyingBoard(const Board& board, double height_mm = 0.0) {
  Eigen::Matrix3d face_up;
  face_up.col(0) = Eigen::Vector3d::UnitX();
  face_up.col(1) = -Eigen::Vector3d::UnitY();
  face_up.col(2) = -Eigen::Vector3d::UnitZ();
  Eigen::Isometry3d object_from_board = Eigen::Isometry3d::Identity();
  object_from_board.linear() = Rz(25.0) * face_up;
  const Eigen::Vector3d centre_board(0.5 * (board.cols - 1) * board.square_mm,
                                     0.5 * (board.rows - 1) * board.square_mm, 0.0);
  object_from_board.translation() =
      Eigen::Vector3d(9.0, -8.0, height_mm) - object_from_board.linear() * centre_board;
  return object_from_board;
}

// A board standing on the plate facing -y (the camera at plate angle 0), its lowest row of inner
// corners one square above the plate, centred 5 mm behind the axis.
inline Eigen::Isometry3d StandingBoard(const Board& board) {
  Eigen::Matrix3d standing;
  standing.col(0) = Eigen::Vector3d::UnitX();
  standing.col(1) = -Eigen::Vector3d::UnitZ();
  standing.col(2) = Eigen::Vector3d::UnitY();
  Eigen::Isometry3d object_from_board = Eigen::Isometry3d::Identity();
  object_from_board.linear() = standing;
  object_from_board.translation() =
      Eigen::Vector3d(-0.5 * (board.cols - 1) * board.square_mm, 5.0, board.rows * board.square_mm);
  return object_from_board;
}

}  // namespace revolve::calibrate::sim

#include "calibrate/axis.h"
#include "calibrate/board_render.h"

namespace revolve::calibrate::sim {

// The station turning a board fixed to the plate to each of `angles_deg`: rendered frames
// (noise, slight blur) and the detections in them.
inline std::vector<StopDetection> TurnBoard(const Rig& rig, const std::vector<double>& distortion,
                                            const Eigen::Isometry3d& object_from_board,
                                            const Board& board,
                                            const std::vector<double>& angles_deg,
                                            std::uint64_t seed = 100) {
  std::vector<StopDetection> out;
  DetectOptions detect;
  detect.diagnose_failures = false;  // boards seen edge-on are expected to fail
  for (std::size_t k = 0; k < angles_deg.size(); ++k) {
    BoardRenderOptions options;
    options.noise_sigma = 2.0;
    options.blur_sigma_px = 0.5;
    options.seed = seed + k;
    Expected<cv::Mat> image =
        RenderBoardOnTable(rig, distortion, angles_deg[k], object_from_board, board, options);
    if (!image) {
      out.push_back({angles_deg[k], std::unexpected(image.error())});
      continue;
    }
    out.push_back({angles_deg[k], DetectBoard(*image, board, detect)});
  }
  return out;
}

// `stops` stops of `step_deg` from 0.
inline std::vector<double> StopAngles(int stops, double step_deg) {
  std::vector<double> angles;
  for (int k = 0; k < stops; ++k) angles.push_back(k * step_deg);
  return angles;
}

}  // namespace revolve::calibrate::sim
