// `revolve calibrate`: I/O shell around calibrate/ (docs/calibration.md). It reads images or
// drives the configured rig (station/devices.h), calls the pure calibration library, prints the
// figures and writes the calibration file.
//
//   revolve calibrate [--config FILE] [--images DIR] [--out FILE]    lens, then axis
//   revolve calibrate lens [--config FILE] [--images DIR] [--out FILE]
//   revolve calibrate axis --calibration FILE [--config FILE] [--out FILE]
//   revolve calibrate check [--config FILE] [--calibration FILE]
//   revolve calibrate board [--config FILE] [--out board.png]
// Every verb takes --cols --rows --square-mm --type to override [calibration.board].
#pragma once

#include <filesystem>
#include <iosfwd>
#include <optional>
#include <stop_token>
#include <string>

namespace revolve::station {

// Exit code of `revolve calibrate check` when it could not measure: the board was found at no
// stop, or the frames have another size than the calibration (EX_DATAERR). A drift beyond
// tolerance is kExitFailed (1).
inline constexpr int kExitNoData = 65;

enum class CalibrateStep {
  kAll,    // lens, then axis
  kLens,   // lens only: a calibration file without [axis]
  kAxis,   // the axis with the lens of --calibration FILE
  kCheck,  // compare the rig with its calibration
  kBoard,  // write the printable board
};

struct CalibrateCommandOptions {
  CalibrateStep step = CalibrateStep::kAll;
  std::optional<std::filesystem::path> config;  // empty: the embedded default (simulated rig)
  // Lens: a folder of images (sorted by name; every file cv::imread can read) instead of
  // frames captured from the camera.
  std::optional<std::filesystem::path> images;
  // Where to write: the calibration file (default [calibration] file, else ./calibration.toml),
  // or for kBoard the image (default ./board.png).
  std::optional<std::filesystem::path> out;
  // kAxis: the lens-only (or full) calibration whose lens to use; it is rewritten with the axis
  // unless --out says otherwise. kCheck: the calibration to check (default [calibration] file).
  std::optional<std::filesystem::path> calibration;
  // Overrides of [calibration.board].
  std::optional<int> cols;
  std::optional<int> rows;
  std::optional<double> square_mm;
  std::optional<std::string> type;  // chessboard | charuco
};

// Runs the step. Prompts go to `out` and read a line from `in` each: for the lens, Enter captures
// a view and "q" (or the end of the input) finishes; before the axis and check turns, any line
// (or the end of the input) starts. So the command needs no terminal: with --images and the input
// at its end (< /dev/null) it runs straight through. Progress and figures go to `out`, errors to
// `err`. Returns (scan_command.h) kExitOk (check: the rig matches); kExitFailed (a calibration
// refused, no images, a write failed; check: the rig drifted); kExitNoData (check could not
// measure); kExitUsage (bad board flags, --calibration missing for kAxis); kExitConfig (the
// config, or the calibration file to use, is missing or invalid); kExitUnavailable (a device
// failed); kExitAborted (stop requested).
int RunCalibrateCommand(const CalibrateCommandOptions& options, std::stop_token stop,
                        std::istream& in, std::ostream& out, std::ostream& err);

}  // namespace revolve::station
