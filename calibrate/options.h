// The [calibration] section of revolve's config: which calibration scans use, the board, and the
// quality gates and tolerances of `revolve calibrate` / `revolve calibrate check`.
//
//   [calibration]
//   file = "calibration.toml"     # used by scans; relative to the config file's folder; "" = none
//   [calibration.board]           # type, cols, rows, square_mm, marker_mm, dictionary
//   [calibration.intrinsics]      # min_views, min_coverage, max_rms_px, min_tilt_spread_deg,
//                                 # estimate_k3, estimate_tangential
//   [calibration.axis]            # min_stops, min_span_deg, board_height_mm,
//                                 # max_reprojection_rms_px
//   [calibration.check]           # stops, max_reprojection_rms_px, max_axis_angle_deg,
//                                 # max_centre_mm
#pragma once

#include <filesystem>

#include "base/error.h"
#include "calibrate/axis.h"
#include "calibrate/board.h"
#include "calibrate/check.h"
#include "calibrate/intrinsics.h"
#include "config/config.h"

namespace revolve::calibrate {

struct CalibrationOptions {
  // The calibration file scans use; empty: none (the thesis's calibration-free geometry, units
  // of pixels, "scale unknown"). A relative path is resolved against the config file's folder.
  std::filesystem::path file;
  Board board;
  IntrinsicsOptions intrinsics;
  AxisOptions axis;
  CheckOptions check;
};

// Parses the [calibration] table (`section`; an absent table gives the defaults). Errors
// (bad_input) name file:line:column and the key: wrong types, values out of range, an invalid
// board, unknown keys.
Expected<CalibrationOptions> ParseCalibrationOptions(const config::Section& section);

// The descriptions of the keys of [calibration] and its tables, for the configuration reference
// (config/reference.h).
config::OptionDocs ReferenceDocs();

}  // namespace revolve::calibrate
