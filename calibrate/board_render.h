// A test renderer: photo-like images of a calibration board seen by a (distorting) camera, for
// the calibration tests and for simulated rigs. Pure: no files, no devices.
#pragma once

#include <cstdint>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "calibrate/board.h"
#include "calibrate/camera_model.h"

namespace revolve::calibrate {

struct BoardRenderOptions {
  // Resolution of the board texture; <= 0: matched to the rendering's finest scale on the board.
  double texture_px_per_mm = 0.0;
  double margin_mm = -1.0;     // white paper around the squares; < 0: half a square
  int supersample = 2;         // render at this many times the resolution, then average
  int background_grey = 50;    // the scene behind the board
  int paper_grey = 215;        // white of the paper (and the back of the board)
  int ink_grey = 25;           // black of the squares
  double noise_sigma = 2.0;    // Gaussian sensor noise, grey levels
  double blur_sigma_px = 0.0;  // optional defocus, pixels of the final image
  std::uint64_t seed = 1;      // noise seed: renders are reproducible
};

// Renders `board` seen from `camera` at `cam_from_board` (board frame: calibrate/board.h) as a
// CV_8UC3 BGR frame of the camera's size: background, the board's paper with the pattern (or the
// plain back of the board when the camera sees its back), lens distortion, blur, noise.
// Errors: bad_input when the board is invalid or crosses the camera's plane (z <= 1 mm).
Expected<cv::Mat> RenderBoard(const CameraModel& camera, const Eigen::Isometry3d& cam_from_board,
                              const Board& board, const BoardRenderOptions& options = {});

// The board resting on the turntable: fixed to the plate at `object_from_board` (object frame,
// base/rig.h), the plate at `plate_angle_deg`, the camera at `rig.cam_from_table` with
// `rig.intrinsics` and the lens distortion `distortion` (OpenCV order; empty: none).
Expected<cv::Mat> RenderBoardOnTable(const Rig& rig, const std::vector<double>& distortion,
                                     double plate_angle_deg,
                                     const Eigen::Isometry3d& object_from_board, const Board& board,
                                     const BoardRenderOptions& options = {});

}  // namespace revolve::calibrate
