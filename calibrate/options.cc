#include "calibrate/options.h"

#include <limits>
#include <string>

namespace revolve::calibrate {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

Expected<void> Done(const config::Section& s) { return s.CheckNoUnknownKeys(); }

}  // namespace

Expected<CalibrationOptions> ParseCalibrationOptions(const config::Section& section) {
  CalibrationOptions o;
  REVOLVE_ASSIGN_OR_RETURN(o.file, section.Path("file"));

  config::Section s = section;
  REVOLVE_ASSIGN_OR_RETURN(s, section.Child("board"));
  std::string type;
  REVOLVE_ASSIGN_OR_RETURN(type, s.String("type", "chessboard", {"chessboard", "charuco"}));
  o.board.type = type == "charuco" ? BoardType::kCharuco : BoardType::kChessboard;
  REVOLVE_ASSIGN_OR_RETURN(o.board.cols, s.Integer("cols", o.board.cols, 3, 100));
  REVOLVE_ASSIGN_OR_RETURN(o.board.rows, s.Integer("rows", o.board.rows, 3, 100));
  REVOLVE_ASSIGN_OR_RETURN(o.board.square_mm,
                           s.Number("square_mm", o.board.square_mm, 0.1, 1000.0));
  REVOLVE_ASSIGN_OR_RETURN(o.board.marker_mm,
                           s.Number("marker_mm", 0.75 * o.board.square_mm, 0.1, 1000.0));
  REVOLVE_ASSIGN_OR_RETURN(o.board.dictionary, s.String("dictionary", o.board.dictionary));
  if (auto valid = o.board.Validate(); !valid) {
    return std::unexpected(s.BadValue(type == "charuco" ? "type" : "cols", valid.error().message));
  }
  if (auto done = Done(s); !done) return std::unexpected(done.error());

  REVOLVE_ASSIGN_OR_RETURN(s, section.Child("intrinsics"));
  IntrinsicsOptions& in = o.intrinsics;
  REVOLVE_ASSIGN_OR_RETURN(in.min_views, s.Integer("min_views", in.min_views, 3, 10000));
  REVOLVE_ASSIGN_OR_RETURN(in.min_coverage, s.Number("min_coverage", in.min_coverage, 0.0, 1.0));
  REVOLVE_ASSIGN_OR_RETURN(in.max_rms_px, s.Number("max_rms_px", in.max_rms_px, 0.0, kInf));
  REVOLVE_ASSIGN_OR_RETURN(in.min_tilt_spread_deg,
                           s.Number("min_tilt_spread_deg", in.min_tilt_spread_deg, 0.0, 180.0));
  REVOLVE_ASSIGN_OR_RETURN(in.estimate_k3, s.Boolean("estimate_k3", in.estimate_k3));
  REVOLVE_ASSIGN_OR_RETURN(in.estimate_tangential,
                           s.Boolean("estimate_tangential", in.estimate_tangential));
  if (auto done = Done(s); !done) return std::unexpected(done.error());

  REVOLVE_ASSIGN_OR_RETURN(s, section.Child("axis"));
  AxisOptions& axis = o.axis;
  REVOLVE_ASSIGN_OR_RETURN(axis.min_stops, s.Integer("min_stops", axis.min_stops, 2, 10000));
  REVOLVE_ASSIGN_OR_RETURN(axis.min_span_deg,
                           s.Number("min_span_deg", axis.min_span_deg, 0.0, 360.0));
  if (s.Has("board_height_mm")) {
    REVOLVE_ASSIGN_OR_RETURN(axis.board_height_mm,
                             s.Number("board_height_mm", 0.0, -1000.0, 1000.0));
  }
  REVOLVE_ASSIGN_OR_RETURN(
      axis.max_reprojection_rms_px,
      s.Number("max_reprojection_rms_px", axis.max_reprojection_rms_px, 0.0, kInf));
  if (auto done = Done(s); !done) return std::unexpected(done.error());

  REVOLVE_ASSIGN_OR_RETURN(s, section.Child("check"));
  CheckOptions& check = o.check;
  REVOLVE_ASSIGN_OR_RETURN(check.stops, s.Integer("stops", check.stops, 2, 10000));
  REVOLVE_ASSIGN_OR_RETURN(
      check.max_reprojection_rms_px,
      s.Number("max_reprojection_rms_px", check.max_reprojection_rms_px, 0.0, kInf));
  REVOLVE_ASSIGN_OR_RETURN(check.max_axis_angle_deg,
                           s.Number("max_axis_angle_deg", check.max_axis_angle_deg, 0.0, 180.0));
  REVOLVE_ASSIGN_OR_RETURN(check.max_centre_mm,
                           s.Number("max_centre_mm", check.max_centre_mm, 0.0, kInf));
  if (auto done = Done(s); !done) return std::unexpected(done.error());

  if (auto done = Done(section); !done) return std::unexpected(done.error());
  return o;
}

#undef REVOLVE_READ

}  // namespace revolve::calibrate
