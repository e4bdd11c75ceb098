#include "station/commands/calibrate_command.h"

#include <poll.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <iostream>
#include <istream>
#include <mutex>
#include <ostream>
#include <vector>

#include <fmt/format.h>
#include <fmt/ostream.h>

#include "base/image_codecs.h"
#include "base/image_read.h"
#include "calibrate/axis.h"
#include "calibrate/board.h"
#include "calibrate/calibration.h"
#include "calibrate/check.h"
#include "calibrate/intrinsics.h"
#include "capture/replay/replay_camera.h"
#include "station/commands/scan_command.h"
#include "station/devices.h"
#include "station/station_config.h"
#include "station/timing.h"

namespace revolve::station {
namespace {

namespace cal = revolve::calibrate;
using Clock = std::chrono::steady_clock;

// A failure of the command: what to print and the exit code.
struct Failure {
  int code = kExitFailed;
  std::string message;
};
template <class T>
using Result = std::expected<T, Failure>;

std::unexpected<Failure> Fail(int code, std::string message) {
  return std::unexpected(Failure{code, std::move(message)});
}

// One line of input; false at the end of the input or when a stop is requested. On a terminal
// (std::cin) the wait polls, so that Ctrl-C interrupts a prompt. (A terminal delivers a line at a
// time, so nothing waits in stdio's buffer while poll() blocks; piped input is read as is.)
bool ReadLine(std::istream& in, std::stop_token stop, std::string* line) {
  line->clear();
  if (&in == &std::cin && ::isatty(STDIN_FILENO) == 1) {
    pollfd fd{STDIN_FILENO, POLLIN, 0};
    while (!stop.stop_requested()) {
      const int ready = ::poll(&fd, 1, 100);
      if (ready > 0 || (ready < 0 && errno != EINTR)) break;
    }
    if (stop.stop_requested()) return false;
  }
  if (!std::getline(in, *line)) return false;
  if (!line->empty() && line->back() == '\r') line->pop_back();
  return true;
}

std::string Percent(double fraction) { return fmt::format("{:.0f} %", 100.0 * fraction); }

// The board of `base` with the command line's overrides. Errors name the flag.
Result<cal::Board> BoardWithOverrides(cal::Board board, const CalibrateCommandOptions& options) {
  if (options.type) {
    if (*options.type == "chessboard") {
      board.type = cal::BoardType::kChessboard;
    } else if (*options.type == "charuco") {
      board.type = cal::BoardType::kCharuco;
    } else {
      return Fail(kExitUsage,
                  fmt::format("--type {}: expected chessboard or charuco", *options.type));
    }
  }
  if (options.cols) board.cols = *options.cols;
  if (options.rows) board.rows = *options.rows;
  if (options.square_mm) {
    board.square_mm = *options.square_mm;
    if (!options.type || board.type == cal::BoardType::kCharuco) {
      board.marker_mm = std::min(board.marker_mm, 0.75 * board.square_mm);
    }
  }
  if (auto valid = board.Validate(); !valid) {
    const bool flags = options.type || options.cols || options.rows || options.square_mm;
    return Fail(flags ? kExitUsage : kExitConfig,
                fmt::format("{}{}", flags ? "--cols/--rows/--square-mm/--type: " : "",
                            valid.error().message));
  }
  return board;
}

// The rig's devices, stopped on every way out.
class RigDevices {
 public:
  explicit RigDevices(Devices devices) : devices_(std::move(devices)) {}
  RigDevices(const RigDevices&) = delete;
  RigDevices& operator=(const RigDevices&) = delete;
  ~RigDevices() {
    if (devices_.camera) devices_.camera->Stop();
    if (devices_.turntable) devices_.turntable->Stop();
  }
  capture::Camera& camera() { return *devices_.camera; }
  turntable::Turntable& turntable() { return *devices_.turntable; }

 private:
  Devices devices_;
};

// The command's state: the configuration, the board, the streams, and the rig once opened.
class Calibrator {
 public:
  Calibrator(const CalibrateCommandOptions& options, std::stop_token stop, std::istream& in,
             std::ostream& out, std::ostream& err)
      : options_(options), stop_(std::move(stop)), in_(in), out_(out), err_(err) {}

  int Run() {
    Result<void> done = Execute();
    if (done) return kExitOk;
    if (stop_.stop_requested() && done.error().code != kExitConfig &&
        done.error().code != kExitUsage) {
      fmt::print(err_, "revolve calibrate: aborted\n");
      return kExitAborted;
    }
    fmt::print(err_, "revolve calibrate{}: {}\n", Verb(), done.error().message);
    return done.error().code;
  }

 private:
  std::string Verb() const {
    switch (options_.step) {
      case CalibrateStep::kAll:
        return "";
      case CalibrateStep::kLens:
        return " lens";
      case CalibrateStep::kAxis:
        return " axis";
      case CalibrateStep::kCheck:
        return " check";
      case CalibrateStep::kBoard:
        return " board";
    }
    return "";
  }

  Result<void> Execute() {
    auto config = LoadStationConfig(options_.config);
    if (!config) return Fail(kExitConfig, config.error().message);
    config_ = std::move(*config);
    const cal::CalibrationOptions& calibration = config_.calibration;
    switch (options_.step) {
      case CalibrateStep::kBoard:
        return WriteBoard();
      case CalibrateStep::kCheck:
        return Check();
      default:
        break;
    }
    auto board = BoardWithOverrides(calibration.board, options_);
    if (!board) return std::unexpected(board.error());
    board_ = *board;
    const std::filesystem::path out_path = OutPath();

    cal::IntrinsicsResult lens;
    if (options_.step == CalibrateStep::kAxis) {
      if (!options_.calibration) {
        return Fail(kExitUsage,
                    "--calibration FILE is required: the calibration whose lens to use (made by "
                    "`revolve calibrate lens`)");
      }
      auto stored = cal::LoadCalibration(*options_.calibration);
      if (!stored) return Fail(kExitConfig, stored.error().message);
      lens.camera = stored->camera;
      lens.rms_px = stored->lens.rms_px;
      lens.views_used = stored->lens.views;
      lens.coverage = stored->lens.coverage;
      lens.tilt_spread_deg = stored->lens.tilt_spread_deg;
      fmt::print(out_, "lens from {}: fx {:.2f} px, fy {:.2f} px, cx {:.2f} px, cy {:.2f} px\n",
                 options_.calibration->string(), lens.camera.intrinsics.fx_px,
                 lens.camera.intrinsics.fy_px, lens.camera.intrinsics.cx_px,
                 lens.camera.intrinsics.cy_px);
    } else {
      auto fitted = Lens();
      if (!fitted) return std::unexpected(fitted.error());
      lens = std::move(*fitted);
      PrintLens(lens);
    }
    if (options_.step == CalibrateStep::kLens) {
      return Save(cal::Calibration::From(board_, lens, std::nullopt), out_path);
    }

    auto axis = Axis(lens.camera);
    if (!axis) {
      if (options_.step == CalibrateStep::kAll) {
        // Keep the lens: the axis step can be repeated alone.
        if (auto saved = Save(cal::Calibration::From(board_, lens, std::nullopt), out_path);
            saved) {
          axis.error().message += fmt::format(
              " (the lens is saved in {}; fix this and run `revolve calibrate axis "
              "--calibration {}`)",
              out_path.string(), out_path.string());
        }
      }
      return std::unexpected(axis.error());
    }
    PrintAxis(*axis);
    return Save(cal::Calibration::From(board_, lens, *axis), out_path);
  }

  std::filesystem::path OutPath() const {
    if (options_.out) return *options_.out;
    if (options_.step == CalibrateStep::kAxis && options_.calibration) {
      return *options_.calibration;
    }
    if (!config_.calibration.file.empty()) return config_.calibration.file;
    return "calibration.toml";
  }

  Result<void> Save(const cal::Calibration& calibration, const std::filesystem::path& path) {
    if (auto saved = cal::SaveCalibration(calibration, path); !saved) {
      return Fail(kExitFailed, saved.error().message);
    }
    fmt::print(out_, "wrote {}{}\n", path.string(),
               calibration.axis ? "" : " (lens only: no turntable axis yet)");
    if (config_.calibration.file.empty() ||
        std::filesystem::absolute(config_.calibration.file).lexically_normal() !=
            std::filesystem::absolute(path).lexically_normal()) {
      fmt::print(out_,
                 "scans use it once the config says so: [calibration] file = \"{}\" (relative "
                 "to the config file's folder)\n",
                 path.filename().string());
    }
    return {};
  }

  // --- devices ---

  Result<RigDevices*> OpenRig() {
    if (rig_) return rig_.get();
    auto devices = OpenDevices(config_);
    if (!devices) return Fail(kExitConfig, devices.error().message);
    rig_ = std::make_unique<RigDevices>(std::move(*devices));
    auto format = rig_->camera().Start();
    if (!format) {
      return Fail(
          kExitUnavailable,
          WithContext(format.error(), "starting the camera " + rig_->camera().Describe()).message);
    }
    format_ = *format;
    return rig_.get();
  }

  Result<cv::Mat> CaptureFrame(Clock::time_point not_before) {
    const auto timeout = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(config_.scan.capture_timeout_s));
    auto frame = rig_->camera().Capture(not_before, timeout);
    if (!frame) {
      return Fail(
          kExitUnavailable,
          WithContext(frame.error(), "capturing from " + rig_->camera().Describe()).message);
    }
    return frame->image;
  }

  // After the prompt just printed: waits for Enter (or the end of the input), then Turn()s the
  // board through `angles`. aborted when a stop is requested meanwhile.
  Result<std::vector<cal::StopDetection>> TurnAfterEnter(const std::vector<double>& angles) {
    out_.flush();
    std::string line;
    if (!ReadLine(in_, stop_, &line)) fmt::print(out_, "\n");
    if (stop_.stop_requested()) return Fail(kExitAborted, "aborted");
    return Turn(angles, board_);
  }

  // Homes, then for each angle: move, settle, capture, detect; progress per stop.
  Result<std::vector<cal::StopDetection>> Turn(const std::vector<double>& angles,
                                               const cal::Board& board) {
    const ScanOptions& scan = config_.scan;
    if (auto homed = rig_->turntable().Home(DeadlineIn(scan.move_timeout_s)); !homed) {
      return Fail(kExitUnavailable, WithContext(homed.error(), "homing the turntable").message);
    }
    cal::DetectOptions detect;
    detect.diagnose_failures = false;  // a board seen edge-on at some stops is expected
    std::vector<cal::StopDetection> stops;
    cv::Mat first_miss;
    for (std::size_t k = 0; k < angles.size(); ++k) {
      if (stop_.stop_requested()) return Fail(kExitAborted, "aborted");
      if (auto moved = rig_->turntable().MoveTo(angles[k], DeadlineIn(scan.move_timeout_s));
          !moved) {
        return Fail(
            kExitUnavailable,
            WithContext(moved.error(), fmt::format("moving to {:g} deg", angles[k])).message);
      }
      auto state = rig_->turntable().State();
      if (!state) {
        return Fail(kExitUnavailable, WithContext(state.error(), "reading the turntable").message);
      }
      SleepFor(stop_, scan.settle_ms);
      if (stop_.stop_requested()) return Fail(kExitAborted, "aborted");
      auto frame = CaptureFrame(Clock::now());
      if (!frame) return std::unexpected(frame.error());
      cal::StopDetection detection{state->angle_deg, cal::DetectBoard(*frame, board, detect)};
      if (detection.detection) {
        fmt::print(out_, "[{:>3}/{}] {:6.1f} deg (read back {:7.2f})  board: {} corners\n", k + 1,
                   angles.size(), angles[k], state->angle_deg, detection.detection->size());
      } else {
        fmt::print(out_, "[{:>3}/{}] {:6.1f} deg (read back {:7.2f})  no board\n", k + 1,
                   angles.size(), angles[k], state->angle_deg);
        if (first_miss.empty()) first_miss = *frame;
      }
      out_.flush();
      stops.push_back(std::move(detection));
    }
    // Say why the board was missed where it was (a wrong size costs one more search).
    if (!first_miss.empty()) {
      if (auto diagnosed = cal::DetectBoard(first_miss, board); !diagnosed) {
        for (cal::StopDetection& s : stops) {
          if (s.detection) continue;
          s.detection = std::unexpected(diagnosed.error());
          break;
        }
      }
    }
    return stops;
  }

  Result<void> FrameSizeMatches(const cal::CameraModel& camera) const {
    const Intrinsics& in = camera.intrinsics;
    if (in.width_px == format_.width_px && in.height_px == format_.height_px) return {};
    return Fail(kExitFailed,
                fmt::format("frames of {} are {}x{} pixels but the lens was calibrated at {}x{}: "
                            "calibrate this camera mode (or set the camera's size to the "
                            "calibrated one)",
                            rig_->camera().Describe(), format_.width_px, format_.height_px,
                            in.width_px, in.height_px));
  }

  // --- the lens ---

  Result<cal::IntrinsicsResult> Lens() {
    const cal::IntrinsicsOptions& gates = config_.calibration.intrinsics;
    if (options_.images) {
      auto files = capture::ListImages(*options_.images);
      if (!files) return Fail(kExitFailed, files.error().message);
      std::vector<cv::Mat> images;
      std::vector<std::string> names;
      for (const std::filesystem::path& file : *files) {
        ImageReadOptions read_options;
        read_options.imread_flags = cv::IMREAD_COLOR;
        Expected<cv::Mat> image = ReadImageFile(file, read_options);
        if (!image) {
          fmt::print(out_, "{}; skipped\n", image.error().message);
          continue;
        }
        images.push_back(std::move(*image));
        names.push_back(file.filename().string());
      }
      fmt::print(out_, "lens: {} images from {}, board {}\n", images.size(),
                 options_.images->string(), board_.Describe());
      out_.flush();
      auto lens = cal::CalibrateIntrinsicsFromImages(images, names, board_, gates);
      if (!lens) return Fail(kExitFailed, lens.error().message);
      return *lens;
    }

    auto rig = OpenRig();
    if (!rig) return std::unexpected(rig.error());
    fmt::print(out_,
               "lens: hold the board ({}) in front of the camera, at a different place and tilt "
               "each time: near the edges and corners too, tilted 20-40 deg left, right, up and "
               "down. Need {} views.\n",
               board_.Describe(), gates.min_views);
    std::vector<cal::ViewDetection> views;
    std::string line;
    while (true) {
      fmt::print(out_, "move and tilt the board, press Enter; `q` to finish ({} views so far): ",
                 views.size());
      out_.flush();
      if (!ReadLine(in_, stop_, &line)) {
        if (stop_.stop_requested()) return Fail(kExitAborted, "aborted");
        fmt::print(out_, "\n");
        break;
      }
      if (line == "q" || line == "Q") break;
      if (stop_.stop_requested()) return Fail(kExitAborted, "aborted");
      auto frame = CaptureFrame(Clock::now());
      if (!frame) return std::unexpected(frame.error());
      cal::ViewDetection view{fmt::format("view {}", views.size() + 1),
                              cal::DetectBoard(*frame, board_)};
      if (view.detection) {
        fmt::print(out_, "{}: board found ({} corners)\n", view.name, view.detection->size());
      } else {
        fmt::print(out_, "{}: {}\n", view.name, view.detection.error().message);
      }
      views.push_back(std::move(view));
    }
    auto lens = cal::CalibrateIntrinsics(views, format_.width_px, format_.height_px, gates);
    if (!lens) return Fail(kExitFailed, lens.error().message);
    return *lens;
  }

  void PrintLens(const cal::IntrinsicsResult& lens) {
    const Intrinsics& in = lens.camera.intrinsics;
    fmt::print(out_,
               "lens: {}x{} px, board found in {} of {} views, RMS reprojection error {:.3f} px\n",
               in.width_px, in.height_px, lens.views_used, lens.views.size(), lens.rms_px);
    fmt::print(out_, "  focal length     fx {:.2f} px (+- {:.2f}), fy {:.2f} px (+- {:.2f})\n",
               in.fx_px, lens.fx_std_px, in.fy_px, lens.fy_std_px);
    fmt::print(out_, "  principal point  cx {:.2f} px (+- {:.2f}), cy {:.2f} px (+- {:.2f})\n",
               in.cx_px, lens.cx_std_px, in.cy_px, lens.cy_std_px);
    std::string distortion;
    const char* names[] = {"k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"};
    for (std::size_t i = 0; i < lens.camera.distortion.size() && i < 8; ++i) {
      distortion +=
          fmt::format("{}{} {:.5f}", i == 0 ? "" : ", ", names[i], lens.camera.distortion[i]);
    }
    fmt::print(out_, "  distortion       {}\n", distortion.empty() ? "none" : distortion);
    fmt::print(out_, "  coverage {} of the image, tilt spread {:.1f} deg\n", Percent(lens.coverage),
               lens.tilt_spread_deg);
    for (const cal::ViewReport& view : lens.views) {
      if (view.used) {
        fmt::print(out_, "  {:<24} {:.3f} px RMS, tilted {:4.1f} deg, {:.0f} mm away\n", view.name,
                   view.rms_px, view.tilt_deg, view.distance_mm);
      } else {
        fmt::print(out_, "  {:<24} not used: {}\n", view.name, view.problem);
      }
    }
  }

  // --- the axis ---

  Result<cal::AxisResult> Axis(const cal::CameraModel& camera) {
    auto rig = OpenRig();
    if (!rig) return std::unexpected(rig.error());
    if (auto size = FrameSizeMatches(camera); !size) return std::unexpected(size.error());
    std::vector<double> angles;
    angles.reserve(config_.scan.stops);
    for (int k = 0; k < config_.scan.stops; ++k) angles.push_back(k * config_.scan.step_deg);
    fmt::print(out_,
               "axis: lay the board ({}) flat on the plate (a camera looking down at it) or stand "
               "it up facing the camera (a camera nearly level), fixed so that it cannot slip; "
               "the station turns it through {} stops of {:g} deg. Press Enter to start: ",
               board_.Describe(), angles.size(), config_.scan.step_deg);
    auto stops = TurnAfterEnter(angles);
    if (!stops) return std::unexpected(stops.error());
    auto axis = cal::CalibrateAxis(*stops, camera, board_, config_.calibration.axis);
    if (!axis) return Fail(kExitFailed, axis.error().message);
    return *axis;
  }

  void PrintAxis(const cal::AxisResult& axis) {
    const Eigen::Vector3d d = axis.AxisDirectionCam();
    const Eigen::Vector3d c = axis.PlateCentreCam();
    fmt::print(out_, "axis: board {}, found at {} of {} stops spanning {:.0f} deg\n",
               cal::ToString(axis.placement), axis.stops_used, axis.stops.size(), axis.span_deg);
    fmt::print(out_, "  direction        ({:.6f}, {:.6f}, {:.6f}) in the camera frame\n", d.x(),
               d.y(), d.z());
    fmt::print(out_, "  plate centre     ({:.3f}, {:.3f}, {:.3f}) mm in the camera frame\n", c.x(),
               c.y(), c.z());
    fmt::print(out_, "  reprojection     {:.3f} px RMS, {:.3f} px max\n", axis.reprojection_rms_px,
               axis.reprojection_max_px);
    fmt::print(out_, "  corners          {:.3f} mm RMS, {:.3f} mm max (vs a rigid turn)\n",
               axis.corner_rms_mm, axis.corner_max_mm);
    fmt::print(out_, "  plate angles     {:.4f} deg RMS (seen vs commanded), wobble {:.4f} deg\n",
               axis.angle_rms_deg, axis.wobble_deg);
    for (const std::string& warning : axis.warnings) fmt::print(out_, "  warning: {}\n", warning);
  }

  // --- check ---

  Result<void> Check() {
    const std::filesystem::path file =
        options_.calibration ? *options_.calibration : config_.calibration.file;
    if (file.empty()) {
      return Fail(kExitConfig,
                  fmt::format("{}: no calibration to check: set [calibration] file, or give "
                              "--calibration FILE",
                              config_.origin));
    }
    auto calibration = cal::LoadCalibration(file);
    if (!calibration) return Fail(kExitConfig, calibration.error().message);
    if (!calibration->axis) {
      return Fail(kExitConfig, fmt::format("{}: holds the lens only, no turntable axis to check: "
                                           "run `revolve calibrate axis --calibration {}` first",
                                           file.string(), file.string()));
    }
    // Today's board: the one the calibration was made with, unless the flags say otherwise.
    auto board = BoardWithOverrides(calibration->board, options_);
    if (!board) return std::unexpected(board.error());
    board_ = *board;
    auto rig = OpenRig();
    if (!rig) return std::unexpected(rig.error());
    if (auto size = calibration->CheckFrameSize(format_.width_px, format_.height_px); !size) {
      return Fail(kExitNoData, size.error().message);
    }
    const cal::CheckOptions& options = config_.calibration.check;
    const std::vector<double> angles =
        cal::CheckStopAngles(options.stops, config_.scan.stops, config_.scan.step_deg);
    fmt::print(out_,
               "check {} (made {}): put the board ({}) on the plate, anywhere, as for the "
               "calibration; the station looks at it at {} stops. Press Enter to start: ",
               file.string(), calibration->created, board_.Describe(), angles.size());
    auto stops = TurnAfterEnter(angles);
    if (!stops) return std::unexpected(stops.error());
    auto result = cal::CheckCalibration(*calibration, *stops, options);
    if (!result) return Fail(kExitNoData, result.error().message);
    fmt::print(out_, "{}", result->Summary(options));
    if (!result->passed) {
      return Fail(kExitFailed,
                  fmt::format("the rig no longer matches {}: {}", file.string(),
                              result->failures.empty() ? "see above" : result->failures.front()));
    }
    return {};
  }

  // --- board ---

  Result<void> WriteBoard() {
    auto board = BoardWithOverrides(config_.calibration.board, options_);
    if (!board) return std::unexpected(board.error());
    auto image = cal::PrintableBoard(*board);
    if (!image) return Fail(kExitUsage, image.error().message);
    const std::filesystem::path path = options_.out ? *options_.out : "board.png";
    if (Expected<void> written = WriteImageFile(path, image->image); !written) {
      return Fail(kExitFailed, fmt::format("{} (is the folder there and the extension one OpenCV "
                                           "writes: png, tif, ...?)",
                                           written.error().message));
    }
    const double width_mm = image->image.cols / image->px_per_mm;
    const double height_mm = image->image.rows / image->px_per_mm;
    fmt::print(out_,
               "{}: {}; {}x{} px at 300 dpi = {:.0f} x {:.0f} mm. Print at 100 % (\"actual "
               "size\"), measure ten squares and set [calibration.board] square_mm to a tenth of "
               "that\n",
               path.string(), board->Describe(), image->image.cols, image->image.rows, width_mm,
               height_mm);
    return {};
  }

  const CalibrateCommandOptions& options_;
  std::stop_token stop_;
  std::istream& in_;
  std::ostream& out_;
  std::ostream& err_;
  StationConfig config_;
  cal::Board board_;
  std::unique_ptr<RigDevices> rig_;
  capture::FrameFormat format_;
};

}  // namespace

int RunCalibrateCommand(const CalibrateCommandOptions& options, std::stop_token stop,
                        std::istream& in, std::ostream& out, std::ostream& err) {
  return Calibrator(options, std::move(stop), in, out, err).Run();
}

}  // namespace revolve::station
