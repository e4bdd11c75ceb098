#include "calibrate/calibration.h"

#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>

#include <fmt/format.h>

#include "base/atomic_file.h"
#include "base/text_file.h"
#include "config/config.h"

#ifndef REVOLVE_VERSION
#define REVOLVE_VERSION "unknown"
#endif

namespace revolve::calibrate {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

std::string Numbers(const double* values, int n) {
  std::string out = "[";
  for (int i = 0; i < n; ++i) out += fmt::format("{}{}", i == 0 ? "" : ", ", values[i]);
  return out + "]";
}

// A required number: present, a number, within [min, max].
Expected<double> RequiredNumber(const config::Section& section, std::string_view key, double min,
                                double max) {
  if (!section.Has(key)) return std::unexpected(section.BadValue(key, "missing (required)"));
  return section.Number(key, kNan, min, max);
}

Expected<std::int64_t> RequiredInteger(const config::Section& section, std::string_view key,
                                       std::int64_t min, std::int64_t max) {
  if (!section.Has(key)) return std::unexpected(section.BadValue(key, "missing (required)"));
  return section.Integer(key, 0, min, max);
}

Expected<Board> ParseBoard(const config::Section& s) {
  Board board;
  std::string type;
  REVOLVE_ASSIGN_OR_RETURN(type, s.String("type", "chessboard", {"chessboard", "charuco"}));
  board.type = type == "charuco" ? BoardType::kCharuco : BoardType::kChessboard;
  REVOLVE_ASSIGN_OR_RETURN(board.cols, RequiredInteger(s, "cols", 3, 100));
  REVOLVE_ASSIGN_OR_RETURN(board.rows, RequiredInteger(s, "rows", 3, 100));
  REVOLVE_ASSIGN_OR_RETURN(board.square_mm, RequiredNumber(s, "square_mm", 1e-3, 1e4));
  if (board.type == BoardType::kCharuco) {
    REVOLVE_ASSIGN_OR_RETURN(board.marker_mm, RequiredNumber(s, "marker_mm", 1e-3, 1e4));
    REVOLVE_ASSIGN_OR_RETURN(board.dictionary, s.String("dictionary", board.dictionary));
  }
  if (auto valid = board.Validate(); !valid) {
    return std::unexpected(s.BadValue("cols", valid.error().message));
  }
  if (auto unknown = s.CheckNoUnknownKeys(); !unknown) return std::unexpected(unknown.error());
  return board;
}

}  // namespace

std::string_view SoftwareVersion() { return REVOLVE_VERSION; }

std::string NowUtc() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

Calibration Calibration::From(const Board& board, const IntrinsicsResult& intrinsics,
                              const std::optional<AxisResult>& axis) {
  Calibration c;
  c.software_version = std::string(SoftwareVersion());
  c.created = NowUtc();
  c.board = board;
  c.camera = intrinsics.camera;
  c.lens.rms_px = intrinsics.rms_px;
  c.lens.views = intrinsics.views_used;
  c.lens.coverage = intrinsics.coverage;
  c.lens.tilt_spread_deg = intrinsics.tilt_spread_deg;
  if (axis) {
    AxisCalibration a;
    a.cam_from_table = axis->cam_from_table;
    a.placement = axis->placement;
    a.stops = axis->stops_used;
    a.span_deg = axis->span_deg;
    a.reprojection_rms_px = axis->reprojection_rms_px;
    a.corner_rms_mm = axis->corner_rms_mm;
    a.corner_max_mm = axis->corner_max_mm;
    a.angle_rms_deg = axis->angle_rms_deg;
    a.wobble_deg = axis->wobble_deg;
    c.axis = a;
  }
  return c;
}

Expected<Rig> Calibration::ToRig() const {
  if (!axis) {
    return MakeError(ErrorCode::kBadInput,
                     "the calibration holds the lens only, no turntable axis: run `revolve "
                     "calibrate axis` with the board on the plate");
  }
  return Rig{camera.intrinsics, axis->cam_from_table};
}

Expected<void> Calibration::CheckFrameSize(int width_px, int height_px) const {
  if (width_px == camera.intrinsics.width_px && height_px == camera.intrinsics.height_px) return {};
  return MakeError(
      ErrorCode::kBadInput,
      fmt::format("frames are {}x{} pixels but the calibration was made at {}x{}: "
                  "calibrate this camera mode (or set the camera back to it)",
                  width_px, height_px, camera.intrinsics.width_px, camera.intrinsics.height_px));
}

std::string FormatCalibration(const Calibration& c) {
  std::string out;
  out += "# revolve calibration (docs/calibration.md). Lengths in mm, angles in degrees;\n";
  out += "# pixel (0, 0) is the centre of the top-left pixel. Made by `revolve calibrate`.\n";
  out += fmt::format("format_version = {}\n", c.format_version);
  out += fmt::format("software_version = \"{}\"\n", c.software_version);
  out += fmt::format("created = \"{}\"\n", c.created);
  out += "\n[board]\n";
  out += fmt::format("type = \"{}\"\n", ToString(c.board.type));
  out += fmt::format("cols = {}            # inner corners along a row\n", c.board.cols);
  out += fmt::format("rows = {}            # inner corners along a column\n", c.board.rows);
  out += fmt::format("square_mm = {}\n", c.board.square_mm);
  if (c.board.type == BoardType::kCharuco) {
    out += fmt::format("marker_mm = {}\n", c.board.marker_mm);
    out += fmt::format("dictionary = \"{}\"\n", c.board.dictionary);
  }
  const Intrinsics& in = c.camera.intrinsics;
  out += "\n[lens]\n";
  out += fmt::format("width_px = {}\n", in.width_px);
  out += fmt::format("height_px = {}\n", in.height_px);
  out += fmt::format("fx_px = {}\n", in.fx_px);
  out += fmt::format("fy_px = {}\n", in.fy_px);
  out += fmt::format("cx_px = {}\n", in.cx_px);
  out += fmt::format("cy_px = {}\n", in.cy_px);
  out += "# OpenCV order: k1, k2, p1, p2[, k3]\n";
  out += fmt::format("distortion = {}\n", Numbers(c.camera.distortion.data(),
                                                  static_cast<int>(c.camera.distortion.size())));
  out += fmt::format("rms_px = {}           # RMS reprojection error of the lens fit\n",
                     c.lens.rms_px);
  out += fmt::format("views = {}\n", c.lens.views);
  out += fmt::format("coverage = {}         # fraction of the image the boards covered\n",
                     c.lens.coverage);
  out += fmt::format("tilt_spread_deg = {}\n", c.lens.tilt_spread_deg);
  if (c.axis) {
    const AxisCalibration& a = *c.axis;
    const Eigen::Vector3d z = a.cam_from_table.linear().col(2);
    const Eigen::Vector3d o = a.cam_from_table.translation();
    out += "\n[axis]\n";
    out += "# cam_from_table: table point (mm; origin on the rotation axis at the plate's top,\n";
    out += "# +z up the axis) -> camera point (OpenCV camera frame). Rotation row-major.\n";
    out += fmt::format("# axis direction in the camera frame: ({:.6f}, {:.6f}, {:.6f})\n", z.x(),
                       z.y(), z.z());
    out += fmt::format("# plate centre in the camera frame: ({:.3f}, {:.3f}, {:.3f}) mm\n", o.x(),
                       o.y(), o.z());
    const Eigen::Matrix3d& r = a.cam_from_table.linear();
    out += "cam_from_table_rotation = [\n";
    for (int row = 0; row < 3; ++row) {
      out += fmt::format("  {}, {}, {},\n", r(row, 0), r(row, 1), r(row, 2));
    }
    out += "]\n";
    out += fmt::format("cam_from_table_translation_mm = {}\n", Numbers(o.data(), 3));
    out += fmt::format("placement = \"{}\"     # how the board sat on the plate\n",
                       ToString(a.placement));
    out += fmt::format("stops = {}\n", a.stops);
    out += fmt::format("span_deg = {}\n", a.span_deg);
    out += fmt::format("reprojection_rms_px = {}\n", a.reprojection_rms_px);
    out += fmt::format("corner_rms_mm = {}    # per-stop board corners vs a rigid turn\n",
                       a.corner_rms_mm);
    out += fmt::format("corner_max_mm = {}\n", a.corner_max_mm);
    out += fmt::format("angle_rms_deg = {}    # plate angles seen vs commanded\n", a.angle_rms_deg);
    out += fmt::format("wobble_deg = {}\n", a.wobble_deg);
  }
  return out;
}

Expected<Calibration> ParseCalibration(std::string text, std::string origin) {
  Expected<config::Document> document = config::Parse(std::move(text), std::move(origin));
  if (!document) return std::unexpected(document.error());
  const config::Section root = config::Section::Root(*document);
  Calibration c;
  REVOLVE_ASSIGN_OR_RETURN(c.format_version, RequiredInteger(root, "format_version", 1, 1000000));
  if (c.format_version > kCalibrationFormatVersion) {
    return std::unexpected(root.BadValue(
        "format_version",
        fmt::format("format {} was written by a newer revolve; this one ({}) reads up to {}",
                    c.format_version, SoftwareVersion(), kCalibrationFormatVersion)));
  }
  REVOLVE_ASSIGN_OR_RETURN(c.software_version, root.String("software_version", "unknown"));
  REVOLVE_ASSIGN_OR_RETURN(c.created, root.String("created", ""));

  config::Section board_section = root;
  REVOLVE_ASSIGN_OR_RETURN(board_section, root.Child("board"));
  REVOLVE_ASSIGN_OR_RETURN(c.board, ParseBoard(board_section));

  config::Section lens = root;
  REVOLVE_ASSIGN_OR_RETURN(lens, root.Child("lens"));
  Intrinsics& in = c.camera.intrinsics;
  REVOLVE_ASSIGN_OR_RETURN(in.width_px, RequiredInteger(lens, "width_px", 1, 100000));
  REVOLVE_ASSIGN_OR_RETURN(in.height_px, RequiredInteger(lens, "height_px", 1, 100000));
  REVOLVE_ASSIGN_OR_RETURN(in.fx_px, RequiredNumber(lens, "fx_px", 1e-3, 1e7));
  REVOLVE_ASSIGN_OR_RETURN(in.fy_px, RequiredNumber(lens, "fy_px", 1e-3, 1e7));
  REVOLVE_ASSIGN_OR_RETURN(in.cx_px, RequiredNumber(lens, "cx_px", -1e6, 1e6));
  REVOLVE_ASSIGN_OR_RETURN(in.cy_px, RequiredNumber(lens, "cy_px", -1e6, 1e6));
  if (!lens.Has("distortion")) {
    return std::unexpected(lens.BadValue("distortion", "missing (required; [] for none)"));
  }
  REVOLVE_ASSIGN_OR_RETURN(c.camera.distortion, lens.Numbers("distortion", {}));
  const std::size_t nd = c.camera.distortion.size();
  if (nd != 0 && nd != 4 && nd != 5 && nd != 8) {
    return std::unexpected(lens.BadValue(
        "distortion",
        fmt::format("expected 0, 4, 5 or 8 coefficients (OpenCV order), got {}", nd)));
  }
  for (double d : c.camera.distortion) {
    if (!std::isfinite(d)) {
      return std::unexpected(lens.BadValue("distortion", "coefficients must be finite"));
    }
  }
  REVOLVE_ASSIGN_OR_RETURN(c.lens.rms_px, lens.Number("rms_px", 0.0, 0.0, kInf));
  REVOLVE_ASSIGN_OR_RETURN(c.lens.views, lens.Integer("views", 0, 0, 1000000));
  REVOLVE_ASSIGN_OR_RETURN(c.lens.coverage, lens.Number("coverage", 0.0, 0.0, 1.0));
  REVOLVE_ASSIGN_OR_RETURN(c.lens.tilt_spread_deg, lens.Number("tilt_spread_deg", 0.0, 0.0, 180.0));
  if (auto unknown = lens.CheckNoUnknownKeys(); !unknown) return std::unexpected(unknown.error());

  if (root.Has("axis")) {
    config::Section axis = root;
    REVOLVE_ASSIGN_OR_RETURN(axis, root.Child("axis"));
    AxisCalibration a;
    if (!axis.Has("cam_from_table_rotation")) {
      return std::unexpected(axis.BadValue("cam_from_table_rotation", "missing (required)"));
    }
    if (!axis.Has("cam_from_table_translation_mm")) {
      return std::unexpected(axis.BadValue("cam_from_table_translation_mm", "missing (required)"));
    }
    std::vector<double> r;
    std::vector<double> t;
    REVOLVE_ASSIGN_OR_RETURN(r, axis.Numbers("cam_from_table_rotation", {}, 9));
    REVOLVE_ASSIGN_OR_RETURN(t, axis.Numbers("cam_from_table_translation_mm", {}, 3));
    Eigen::Matrix3d rotation;
    for (int i = 0; i < 9; ++i) rotation(i / 3, i % 3) = r[static_cast<std::size_t>(i)];
    const double orthogonality =
        (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (!(orthogonality < 1e-6) || !(rotation.determinant() > 0.0)) {
      return std::unexpected(axis.BadValue("cam_from_table_rotation",
                                           "not a rotation matrix (row-major, orthonormal, "
                                           "determinant +1)"));
    }
    a.cam_from_table.linear() = rotation;
    a.cam_from_table.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
    if (!a.cam_from_table.translation().allFinite()) {
      return std::unexpected(
          axis.BadValue("cam_from_table_translation_mm", "values must be finite"));
    }
    std::string placement;
    REVOLVE_ASSIGN_OR_RETURN(placement,
                             axis.String("placement", "lying", {"lying", "standing", "tilted"}));
    a.placement = placement == "standing" ? BoardPlacement::kStanding
                  : placement == "tilted" ? BoardPlacement::kTilted
                                          : BoardPlacement::kLying;
    REVOLVE_ASSIGN_OR_RETURN(a.stops, axis.Integer("stops", 0, 0, 1000000));
    REVOLVE_ASSIGN_OR_RETURN(a.span_deg, axis.Number("span_deg", 0.0, 0.0, 360.0));
    REVOLVE_ASSIGN_OR_RETURN(a.reprojection_rms_px,
                             axis.Number("reprojection_rms_px", 0.0, 0.0, kInf));
    REVOLVE_ASSIGN_OR_RETURN(a.corner_rms_mm, axis.Number("corner_rms_mm", 0.0, 0.0, kInf));
    REVOLVE_ASSIGN_OR_RETURN(a.corner_max_mm, axis.Number("corner_max_mm", 0.0, 0.0, kInf));
    REVOLVE_ASSIGN_OR_RETURN(a.angle_rms_deg, axis.Number("angle_rms_deg", 0.0, 0.0, kInf));
    REVOLVE_ASSIGN_OR_RETURN(a.wobble_deg, axis.Number("wobble_deg", 0.0, 0.0, kInf));
    if (auto unknown = axis.CheckNoUnknownKeys(); !unknown) return std::unexpected(unknown.error());
    c.axis = a;
  }
  if (auto unknown = root.CheckNoUnknownKeys(); !unknown) return std::unexpected(unknown.error());
  return c;
}

#undef REVOLVE_READ

Expected<void> SaveCalibration(const Calibration& calibration, const std::filesystem::path& path) {
  const std::string text = FormatCalibration(calibration);
  return WriteFileAtomically(path, std::string_view(text));
}

Expected<Calibration> LoadCalibration(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return MakeError(ErrorCode::kNotFound,
                     fmt::format("{}: calibration file not found (make one with `revolve "
                                 "calibrate`, or fix [calibration] file in the config)",
                                 path.string()));
  }
  // A calibration file is a few kB; a device or FIFO is refused, never read.
  auto text = ReadRegularFile(path, std::uintmax_t{1} << 20);
  if (!text) {
    return MakeError(text.error().code,
                     fmt::format("{} (expected a calibration file)", text.error().message));
  }
  return ParseCalibration(std::move(*text), path.string());
}

}  // namespace revolve::calibrate
