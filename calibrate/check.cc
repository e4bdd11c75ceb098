#include "calibrate/check.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "base/angles.h"

namespace revolve::calibrate {
std::string CheckResult::Summary(const CheckOptions& options) const {
  std::string out;
  out += fmt::format("stops with the board: {}\n", stops_used);
  out += fmt::format(
      "reprojection with the stored calibration: {:.3f} px RMS, {:.3f} px max "
      "(tolerance {:.3f} px RMS)\n",
      reprojection_rms_px, reprojection_max_px, options.max_reprojection_rms_px);
  out += fmt::format("board pose fit with the stored lens: {:.3f} px RMS\n", pose_rms_px);
  if (axis_angle_change_deg) {
    out += fmt::format("axis direction change: {:.3f} deg (tolerance {:.3f} deg)\n",
                       *axis_angle_change_deg, options.max_axis_angle_deg);
  }
  if (centre_change_mm) {
    out += fmt::format("plate centre change: {:.3f} mm (tolerance {:.3f} mm)\n", *centre_change_mm,
                       options.max_centre_mm);
  }
  if (passed) {
    out += "PASS: the rig matches its calibration\n";
  } else {
    for (const std::string& f : failures) out += "FAIL: " + f + "\n";
  }
  return out;
}

Expected<CheckResult> CheckCalibration(const Calibration& calibration,
                                       const std::vector<StopDetection>& stops,
                                       const CheckOptions& options) {
  if (!calibration.axis) {
    return MakeError(ErrorCode::kBadInput,
                     "the calibration holds no turntable axis to check: run `revolve calibrate` "
                     "with the board on the plate first");
  }
  CheckResult result;
  std::string problems;
  double pose_sum = 0.0;
  int pose_corners = 0;
  for (const StopDetection& stop : stops) {
    if (!stop.detection) {
      if (problems.size() < 400) {
        problems +=
            fmt::format("; stop at {:g} deg: {}", stop.angle_deg, stop.detection.error().message);
      }
      continue;
    }
    Expected<BoardPose> pose = EstimateBoardPose(*stop.detection, calibration.camera);
    if (!pose) continue;
    ++result.stops_used;
    const int n = static_cast<int>(stop.detection->size());
    pose_sum += pose->rms_px * pose->rms_px * n;
    pose_corners += n;
  }
  if (result.stops_used == 0) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("calibration check: the board ({}) was found at none of the {} "
                                 "stops: put it flat on the plate, fully in view{}",
                                 calibration.board.Describe(), stops.size(), problems));
  }
  result.pose_rms_px = std::sqrt(pose_sum / pose_corners);

  const Eigen::Isometry3d& stored = calibration.axis->cam_from_table;
  Expected<BoardOnTable> fit = FitBoardOnTable(stops, calibration.camera, stored);
  if (!fit) return std::unexpected(fit.error());
  result.reprojection_rms_px = fit->reprojection_rms_px;
  result.reprojection_max_px = fit->reprojection_max_px;
  if (!(result.reprojection_rms_px <= options.max_reprojection_rms_px)) {
    result.failures.push_back(fmt::format(
        "the stored calibration misses today's board corners by {:.2f} px RMS (tolerance {:.2f} "
        "px): the camera, its lens or the turntable moved; run `revolve calibrate` again",
        result.reprojection_rms_px, options.max_reprojection_rms_px));
  }

  AxisOptions refit;
  refit.min_stops = 3;
  refit.min_span_deg = 60.0;
  refit.max_reprojection_rms_px = 1e9;  // judged here, against the tolerances
  if (Expected<AxisResult> axis =
          CalibrateAxis(stops, calibration.camera, calibration.board, refit);
      axis) {
    const Eigen::Vector3d stored_z = stored.linear().col(2);
    const Eigen::Vector3d new_z = axis->AxisDirectionCam();
    result.axis_angle_change_deg = Degrees(std::acos(std::clamp(stored_z.dot(new_z), -1.0, 1.0)));
    // Where the new axis line crosses the stored plate plane, in the stored table frame.
    const Eigen::Isometry3d table_from_cam = stored.inverse();
    const Eigen::Vector3d p = table_from_cam * axis->PlateCentreCam();
    const Eigen::Vector3d d = table_from_cam.linear() * new_z;
    if (std::abs(d.z()) > 1e-6) {
      const Eigen::Vector3d crossing = p - (p.z() / d.z()) * d;
      result.centre_change_mm = crossing.head<2>().norm();
    }
    if (*result.axis_angle_change_deg > options.max_axis_angle_deg) {
      result.failures.push_back(fmt::format(
          "the turntable axis tilted by {:.3f} deg relative to the camera (tolerance {:.3f} deg): "
          "run `revolve calibrate` again",
          *result.axis_angle_change_deg, options.max_axis_angle_deg));
    }
    if (result.centre_change_mm && *result.centre_change_mm > options.max_centre_mm) {
      result.failures.push_back(fmt::format(
          "the turntable axis moved {:.2f} mm relative to the camera (tolerance {:.2f} mm): run "
          "`revolve calibrate` again",
          *result.centre_change_mm, options.max_centre_mm));
    }
  }
  result.passed = result.failures.empty();
  return result;
}

std::vector<double> CheckStopAngles(int count, int scan_stops, double step_deg) {
  std::vector<double> angles;
  if (count <= 0 || scan_stops <= 0) return angles;
  count = std::min(count, scan_stops);
  for (int i = 0; i < count; ++i) {
    const int stop = static_cast<int>(std::lround(static_cast<double>(i) * scan_stops / count));
    angles.push_back(std::min(stop, scan_stops - 1) * step_deg);
  }
  return angles;
}

}  // namespace revolve::calibrate
