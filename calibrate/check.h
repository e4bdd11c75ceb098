// `revolve calibrate check`: does the rig still match its calibration? The board is put on the
// plate (anywhere), detected at a few stops, and compared with the stored calibration.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "base/error.h"
#include "calibrate/axis.h"
#include "calibrate/calibration.h"

namespace revolve::calibrate {

struct CheckOptions {
  int stops = 6;  // stops to re-detect the board at, spread over the turn (CheckStopAngles)
  // Tolerances: beyond any, the check fails.
  double max_reprojection_rms_px = 1.0;  // stored rig + best board placement vs the detections
  double max_axis_angle_deg = 0.3;       // refitted axis direction vs the stored one
  double max_centre_mm = 1.0;            // refitted axis vs the stored plate centre
};

struct CheckResult {
  bool passed = false;
  std::vector<std::string> failures;  // one sentence per figure over its tolerance
  int stops_used = 0;
  // The stored calibration explaining today's detections: the best board placement on the plate
  // with the stored lens and cam_from_table, RMS / max reprojection error over every corner.
  double reprojection_rms_px = 0.0;
  double reprojection_max_px = 0.0;
  double pose_rms_px = 0.0;  // per-stop PnP with the stored lens (lens or focus changes)
  // From an axis refitted to today's stops (when they span >= 60 deg): the angle between the
  // stored and the new axis direction, and how far the new axis passes from the stored plate
  // centre, measured in the stored plate plane.
  std::optional<double> axis_angle_change_deg;
  std::optional<double> centre_change_mm;

  // Multi-line report for people: the figures, their tolerances, PASS/FAIL.
  std::string Summary(const CheckOptions& options) const;
};

// Compares. A drift beyond tolerance is a result with passed = false (the caller exits non-zero),
// not an error. Errors (bad_input): the calibration has no axis; the board was found at no stop
// (lists the stops' problems).
Expected<CheckResult> CheckCalibration(const Calibration& calibration,
                                       const std::vector<StopDetection>& stops,
                                       const CheckOptions& options = {});

// `count` plate angles spread evenly over a turn of `scan_stops` stops of `step_deg` (angles are
// multiples of step_deg, so that the check uses the stops scans use).
std::vector<double> CheckStopAngles(int count, int scan_stops, double step_deg);

}  // namespace revolve::calibrate
