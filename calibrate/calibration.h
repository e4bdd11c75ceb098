// The calibration file: a versioned TOML document holding the lens (intrinsics, distortion), the
// turntable axis (cam_from_table), the board used, when and by which revolve it was made, and the
// residuals that say how good it is. Scans reference it from their config ([calibration] file)
// and keep a copy in their folder. Format: docs/calibration.md, "The calibration file".
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Geometry>

#include "base/error.h"
#include "base/rig.h"
#include "calibrate/axis.h"
#include "calibrate/board.h"
#include "calibrate/camera_model.h"
#include "calibrate/intrinsics.h"

namespace revolve::calibrate {

// The format written by this build; files with a larger version are refused.
inline constexpr int kCalibrationFormatVersion = 1;

// revolve's version (CMake PROJECT_VERSION), recorded in every file.
std::string_view SoftwareVersion();

// The current time as "2024-05-01T12:34:56Z".
std::string NowUtc();

struct LensQuality {
  double rms_px = 0.0;  // RMS reprojection error of the intrinsics calibration
  int views = 0;
  double coverage = 0.0;
  double tilt_spread_deg = 0.0;
};

struct AxisCalibration {
  Eigen::Isometry3d cam_from_table = Eigen::Isometry3d::Identity();
  BoardPlacement placement = BoardPlacement::kLying;
  int stops = 0;  // stops the fit used
  double span_deg = 0.0;
  double reprojection_rms_px = 0.0;
  double corner_rms_mm = 0.0;
  double corner_max_mm = 0.0;
  double angle_rms_deg = 0.0;
  double wobble_deg = 0.0;
};

struct Calibration {
  int format_version = kCalibrationFormatVersion;
  std::string software_version;  // of the revolve that made it
  std::string created;           // UTC, ISO 8601
  Board board;
  CameraModel camera;
  LensQuality lens;
  std::optional<AxisCalibration> axis;  // absent: lens only (`revolve calibrate intrinsics`)

  // A calibration from the results of the two steps, stamped with SoftwareVersion() and NowUtc().
  static Calibration From(const Board& board, const IntrinsicsResult& intrinsics,
                          const std::optional<AxisResult>& axis);

  // The pinhole rig for UNDISTORTED frames (Undistorter): intrinsics and cam_from_table. Views
  // for reconstruction: ToRig()->PixelFromObject(angle_deg), lengths in millimetres. Error
  // (bad_input) when the file holds no axis.
  Expected<Rig> ToRig() const;

  // bad_input unless frames of width x height are what the lens was calibrated at.
  Expected<void> CheckFrameSize(int width_px, int height_px) const;
};

// The TOML text (full precision, with comments for people).
std::string FormatCalibration(const Calibration& calibration);

// Parses TOML text; `origin` names it in errors. Errors (bad_input): "<origin>:<line>:<column>:
// <key>: <what>" for a wrong value, "<origin>: <key>: missing" for an absent required key,
// unknown keys, a format_version newer than this build, a rotation that is not a rotation.
Expected<Calibration> ParseCalibration(std::string text, std::string origin);

// Writes atomically (base/atomic_file.h).
Expected<void> SaveCalibration(const Calibration& calibration, const std::filesystem::path& path);

// Reads and parses; not_found when the file does not exist (the message says how to make one).
Expected<Calibration> LoadCalibration(const std::filesystem::path& path);

}  // namespace revolve::calibrate
