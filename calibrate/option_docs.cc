// The descriptions of [calibration] and its tables for the configuration reference
// (docs/configuration.md, made by `revolve check-config --reference`). The types, defaults and
// ranges come from the parser itself; a key it reads with no description here fails the test
// config_reference.
#include "calibrate/options.h"

namespace revolve::calibrate {
namespace {

constexpr config::TableDoc kTables[] = {
    {"calibration",
     "Which calibration scans use, the board, and the quality gates of `revolve calibrate`; what "
     "they mean and how to choose them: [The board](calibration.md#the-board), [The "
     "lens](calibration.md#the-lens), [The turntable axis](calibration.md#the-turntable-axis) and "
     "[`revolve calibrate check`](calibration.md#before-a-days-scans-revolve-calibrate-check). "
     "`file` is relative to the configuration file's folder (to the working directory for the "
     "embedded default); empty or absent: scans use no calibration. `config/examples/default.toml` "
     "lists every key, commented out (the simulated camera knows its own geometry and needs "
     "none)."},
    {"calibration.board", "The calibration board (see [The board](calibration.md#the-board))."},
    {"calibration.intrinsics",
     "The gates of the lens step (see [The lens](calibration.md#the-lens))."},
    {"calibration.axis",
     "The gates of the axis step (see [The turntable axis](calibration.md#the-turntable-axis)). "
     "`board_height_mm` absent: 0 for a lying board, `square_mm` for a standing one."},
    {"calibration.check",
     "The gates of `revolve calibrate check` (see [Before a day's "
     "scans](calibration.md#before-a-days-scans-revolve-calibrate-check))."},
};

constexpr config::KeyDoc kKeys[] = {
    {"calibration", "file", "", "the calibration file scans use; `\"\"` = none"},
    {"calibration.board", "type", "", "the calibration target"},
    {"calibration.board", "cols", "inner corners", "inner corners along a row and a column"},
    {"calibration.board", "rows", "inner corners", "inner corners along a row and a column"},
    {"calibration.board", "square_mm", "mm", "square side, measured on the print"},
    {"calibration.board", "marker_mm", "mm", "ChArUco: marker side (smaller than the square)", "",
     "0.75 × `square_mm`", ""},
    {"calibration.board", "dictionary", "", "ChArUco", "", "", "an OpenCV dictionary name"},
    {"calibration.intrinsics", "min_views", "views",
     "the lens step needs the board found in at least this many views"},
    {"calibration.intrinsics", "min_coverage", "share of the image",
     "the lens step refuses views covering less of the image than this, together"},
    {"calibration.intrinsics", "max_rms_px", "px",
     "the lens step refuses an RMS reprojection error above this"},
    {"calibration.intrinsics", "min_tilt_spread_deg", "degrees",
     "the lens step refuses boards whose orientations differ by less than this"},
    {"calibration.intrinsics", "estimate_k3", "",
     "distortion model: estimate the third radial coefficient k3"},
    {"calibration.intrinsics", "estimate_tangential", "",
     "distortion model: estimate the tangential coefficients p1, p2"},
    {"calibration.axis", "min_stops", "stops",
     "the axis step needs the board found at at least this many stops"},
    {"calibration.axis", "min_span_deg", "degrees",
     "the stops with the board must span at least this angle"},
    {"calibration.axis", "board_height_mm", "mm", "height of the board's plane above the plate", "",
     "0 lying, `square_mm` standing", ""},
    {"calibration.axis", "max_reprojection_rms_px", "px",
     "the axis step refuses an RMS reprojection error above this"},
    {"calibration.check", "stops", "stops", "stops `revolve calibrate check` turns through"},
    {"calibration.check", "max_reprojection_rms_px", "px",
     "the check fails above this RMS reprojection error"},
    {"calibration.check", "max_axis_angle_deg", "degrees",
     "the check fails when the measured axis is tilted from the calibrated one by more than this"},
    {"calibration.check", "max_centre_mm", "mm",
     "the check fails when the plate centre moved by more than this"},
};

}  // namespace

config::OptionDocs ReferenceDocs() { return {kTables, kKeys}; }

}  // namespace revolve::calibrate
