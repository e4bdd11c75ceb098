// The turntable's rotation axis from a board turned through the stops by the station itself.
//
// Model: the board is fixed to the plate, so at a stop with plate angle theta
//   cam_from_board(theta) = cam_from_table * Rz(theta) * object_from_board      (base/rig.h)
// The fit: board pose per stop (solvePnP with the calibrated lens), axis direction from the
// per-stop rotations (the direction they all share), axis point from the fixed points of the
// relative motions, then a joint least-squares refinement of cam_from_table (4 dof) and
// object_from_board (6 dof) minimising the reprojection error of every corner at every stop.
//
// Table frame convention (what cam_from_table means; base/rig.h):
//  - +z is the axis direction for which the commanded angles turn counter-clockwise (right-hand
//    rule). With a correctly configured drive that is "up": a warning says when +z points down
//    in the image (a drive turning the other way, or a camera mounted upside down).
//  - origin: the axis point at the plate's top surface, taken as `board_height_mm` below the
//    board's lowest inner corner (along the axis). A board lying on the plate: its corners are
//    the board's thickness above the plate (default 0: paper). A standing board: its lowest row
//    of inner corners is one square plus the paper margin above the plate (default: square_mm;
//    set board_height_mm to what you measure).
//  - +x: the camera's x axis (image right) projected onto the plate, so that at plate angle 0
//    object +x appears to the right of the image, as in CamFromTableLookingAtAxis.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "calibrate/board.h"
#include "calibrate/camera_model.h"

namespace revolve::calibrate {

struct AxisOptions {
  int min_stops = 6;           // stops in which the board was found
  double min_span_deg = 90.0;  // the angles of those stops must cover this much of a turn
  // Height of the board's lowest inner corner above the plate's top surface (see the file
  // comment). nullopt: 0 for a lying board, square_mm otherwise.
  std::optional<double> board_height_mm;
  // Refuse the fit above this RMS reprojection error: the board slipped, the commanded angles
  // are not the real ones, or the intrinsics are wrong.
  double max_reprojection_rms_px = 1.0;
};

// One stop: the commanded (or read-back) plate angle and the board found there, or why not.
struct StopDetection {
  double angle_deg = 0.0;
  Expected<Detection> detection;
};

enum class BoardPlacement { kLying, kStanding, kTilted };
std::string_view ToString(BoardPlacement placement);  // "lying" / "standing" / "tilted"

struct StopReport {
  double angle_deg = 0.0;
  bool used = false;
  std::string problem;               // why not used
  double reprojection_rms_px = 0.0;  // of the fitted rig model at this stop
  double corner_rms_mm = 0.0;        // this stop's PnP corners vs the model, in 3D
  double angle_error_deg = 0.0;      // plate angle seen by the board minus the commanded one
};

struct AxisResult {
  Eigen::Isometry3d cam_from_table = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d object_from_board = Eigen::Isometry3d::Identity();
  BoardPlacement placement = BoardPlacement::kLying;
  double reprojection_rms_px = 0.0;  // joint model, all corners of all used stops
  double reprojection_max_px = 0.0;
  double corner_rms_mm = 0.0;  // per-stop PnP corners vs the rigid-turn model (3D, mm)
  double corner_max_mm = 0.0;
  double angle_rms_deg = 0.0;  // plate angles seen by the board vs the commanded ones
  double wobble_deg = 0.0;     // RMS tilt of the per-stop rotations away from the axis
  double span_deg = 0.0;       // angular range of the used stops
  int stops_used = 0;
  std::vector<StopReport> stops;      // one per input stop
  std::vector<std::string> warnings;  // things worth telling the user that are not failures

  Eigen::Vector3d AxisDirectionCam() const { return cam_from_table.linear().col(2); }
  Eigen::Vector3d PlateCentreCam() const { return cam_from_table.translation(); }
};

// Fits the axis. Errors (bad_input, with the reason and what to do): fewer than min_stops
// detections (lists the stops' problems), span below min_span_deg, degenerate motion (the board
// did not turn), reprojection RMS over the limit.
Expected<AxisResult> CalibrateAxis(const std::vector<StopDetection>& stops,
                                   const CameraModel& camera, const Board& board,
                                   const AxisOptions& options = {});

// Detects the board in `images` (one per angle) and fits.
Expected<AxisResult> CalibrateAxisFromImages(const std::vector<cv::Mat>& images,
                                             const std::vector<double>& angles_deg,
                                             const CameraModel& camera, const Board& board,
                                             const AxisOptions& options = {},
                                             const DetectOptions& detect = {});

// The board pose per detection (solvePnP, IPPE then Levenberg-Marquardt) and its RMS
// reprojection error. Errors: bad_input when fewer than 4 corners or PnP fails.
struct BoardPose {
  Eigen::Isometry3d cam_from_board = Eigen::Isometry3d::Identity();
  double rms_px = 0.0;
};
Expected<BoardPose> EstimateBoardPose(const Detection& detection, const CameraModel& camera);

// With cam_from_table known (a stored calibration), the board placement on the plate that best
// explains the detections, and how well it does: RMS reprojection error over all corners.
// Errors: bad_input when no stop holds a detection.
struct BoardOnTable {
  Eigen::Isometry3d object_from_board = Eigen::Isometry3d::Identity();
  double reprojection_rms_px = 0.0;
  double reprojection_max_px = 0.0;
  int stops_used = 0;
};
Expected<BoardOnTable> FitBoardOnTable(const std::vector<StopDetection>& stops,
                                       const CameraModel& camera,
                                       const Eigen::Isometry3d& cam_from_table);

}  // namespace revolve::calibrate
