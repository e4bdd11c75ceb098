#include "station/scan_session.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <ctime>
#include <map>
#include <set>
#include <thread>

#include <fmt/format.h>

#include "base/image_read.h"
#include "capture/quality.h"
#include "capture/segment/set_segmentation.h"
#include "reconstruct/io/model_writer.h"
#include "reconstruct/metrics/metrics.h"
#include "station/contact_sheet.h"
#include "station/report_json.h"
#include "station/scan_geometry.h"
#include "station/timing.h"

namespace revolve::station {
namespace {

using Clock = std::chrono::steady_clock;

// The accepted stops next to stop k (k-1 and k+1; around the end when the plan is a full
// turn), for the quality gates' jump checks.
std::vector<capture::StopStats> NeighbourStats(const std::map<int, capture::StopStats>& stats,
                                               int k, const ScanOptions& scan) {
  const bool full_turn = std::abs(scan.stops * scan.step_deg - 360.0) < 1e-6;
  std::vector<capture::StopStats> out;
  for (int n : {k - 1, k + 1}) {
    if (full_turn) n = (n + scan.stops) % scan.stops;
    if (n == k) continue;
    if (auto it = stats.find(n); it != stats.end()) out.push_back(it->second);
  }
  return out;
}

std::string WarningsText(const std::vector<capture::QualityWarning>& warnings) {
  std::string text;
  for (const capture::QualityWarning& w : warnings) {
    if (!text.empty()) text += "; ";
    text += w.message;
  }
  return text;
}

bool MayPass(ErrorCode code) {
  return code == ErrorCode::kTimeout || code == ErrorCode::kNoDevice ||
         code == ErrorCode::kLinkDown || code == ErrorCode::kIo || code == ErrorCode::kProtocol;
}

// Points sampled on the model's surface for the distance to the truth.
constexpr int kSurfaceSamples = 20000;

// The accuracy of `mesh` against a simulated scene's true geometry.
nlohmann::json AccuracyJson(const reconstruct::Mesh& mesh, const reconstruct::MeshStats& stats,
                            const capture::SceneTruth& truth) {
  nlohmann::json j;
  j["truth"] = truth.description;
  j["true_volume_mm3"] = truth.volume_mm3;
  j["volume_error_percent"] = 100.0 * (stats.volume_mm3 - truth.volume_mm3) / truth.volume_mm3;
  if (truth.distance_mm) {
    const reconstruct::DistanceStats d =
        reconstruct::SurfaceDistance(mesh, truth.distance_mm, kSurfaceSamples);
    j["mean_surface_distance_mm"] = d.mean_mm;
    j["rms_surface_distance_mm"] = d.rms_mm;
    j["p90_surface_distance_mm"] = d.p90_mm;
    j["max_surface_distance_mm"] = d.max_mm;
  }
  if (truth.sphere_radius_mm && truth.sphere_center_mm) {
    const reconstruct::SphereFit fit = reconstruct::FitSphere(mesh);
    j["sphere_true_radius_mm"] = *truth.sphere_radius_mm;
    j["sphere_fitted_radius_mm"] = fit.radius_mm;
    j["sphere_radius_error_percent"] =
        100.0 * (fit.radius_mm - *truth.sphere_radius_mm) / *truth.sphere_radius_mm;
    j["sphere_center_error_mm"] = (fit.centre_mm - *truth.sphere_center_mm).norm();
  }
  return j;
}

void SortStopsByIndex(nlohmann::json& stops) {
  std::stable_sort(stops.begin(), stops.end(),
                   [](const nlohmann::json& a, const nlohmann::json& b) {
                     return a.value("index", 0) < b.value("index", 0);
                   });
}

}  // namespace

std::string IsoTimeNow() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t seconds = std::chrono::system_clock::to_time_t(now);
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()) % 1000;
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%S", &utc);
  return fmt::format("{}.{:03d}Z", buf, static_cast<int>(ms.count()));
}

nlohmann::json StageTimes::ToJson() const {
  return {{"home_ms", home_ms},       {"move_ms", move_ms},       {"settle_ms", settle_ms},
          {"capture_ms", capture_ms}, {"segment_ms", segment_ms}, {"integrate_ms", integrate_ms},
          {"save_ms", save_ms},       {"mesh_ms", mesh_ms},       {"write_ms", write_ms},
          {"total_ms", total_ms}};
}

ScanSession::ScanSession(const StationConfig& config, Devices& devices, const ScanFolder& folder,
                         std::string scan_id)
    : config_(config),
      devices_(devices),
      folder_(folder),
      scan_id_(scan_id.empty() ? folder.dir().filename().string() : std::move(scan_id)) {}

void ScanSession::SetAbortReason(std::string reason) {
  std::lock_guard lock(abort_mutex_);
  abort_reason_ = std::move(reason);
}

Error ScanSession::AbortedError(int stops_done) const {
  std::lock_guard lock(abort_mutex_);
  return Error{ErrorCode::kAborted,
               fmt::format("aborted{} after {} of {} stops",
                           abort_reason_.empty() ? "" : " (" + abort_reason_ + ")", stops_done,
                           config_.scan.stops)};
}

Expected<void> ScanSession::SaveManifest() { return folder_.WriteJson("manifest.json", manifest_); }

void ScanSession::Emit(ScanEvent event) {
  event.time = IsoTimeNow();
  if (on_event_) on_event_(event);
}

Expected<void> ScanSession::Enter(ScanState state, int stop, double angle_deg) {
  Expected<ScanEvent> event = machine_->Enter(state, Clock::now(), stop, angle_deg);
  if (!event) return std::unexpected(event.error());
  Emit(std::move(*event));
  return {};
}

Expected<ScanResult> ScanSession::Run(std::stop_token stop) {
  manifest_ = {{"version", 1},
               {"scan_id", scan_id_},
               {"recipe", config_.recipe},
               {"state", "running"},
               {"started", IsoTimeNow()},
               {"config", config_.origin},
               {"stops_planned", config_.scan.stops},
               {"step_deg", config_.scan.step_deg},
               {"stops_done", 0},
               {"turntable", devices_.turntable->Describe()},
               {"camera", devices_.camera->Describe()},
               {"stops", nlohmann::json::array()}};
  return Execute(stop, {});
}

Expected<ScanResult> ScanSession::Resume(std::stop_token stop) {
  Expected<nlohmann::json> manifest = ReadManifest(folder_.dir());
  if (!manifest) return std::unexpected(manifest.error());
  const int planned = manifest->value("stops_planned", -1);
  const double step_deg = manifest->value("step_deg", -1.0);
  if (planned != config_.scan.stops || std::abs(step_deg - config_.scan.step_deg) > 1e-9) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{}: planned {} stops of {} deg, but the configuration says {} "
                                 "of {} deg; resume it with its own scan.toml",
                                 folder_.dir().string(), planned, step_deg, config_.scan.stops,
                                 config_.scan.step_deg));
  }
  if (manifest->value("state", std::string()) == "complete") {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("{}: the scan is complete; nothing to resume", folder_.dir().string()));
  }
  std::vector<std::string> skipped;
  Expected<std::vector<SavedStop>> saved = ReadSavedStops(folder_.dir(), *manifest, true, &skipped);
  if (!saved) return std::unexpected(saved.error());

  manifest_ = std::move(*manifest);
  manifest_["state"] = "running";
  manifest_.erase("error");
  manifest_.erase("abort");
  manifest_.erase("finished");
  manifest_.erase("model");
  manifest_["stops"] = nlohmann::json::array();
  for (const SavedStop& s : *saved) manifest_["stops"].push_back(s.entry);
  manifest_["stops_done"] = saved->size();
  if (!manifest_.contains("resumed") || !manifest_["resumed"].is_array()) {
    manifest_["resumed"] = nlohmann::json::array();
  }
  manifest_["resumed"].push_back(
      {{"time", IsoTimeNow()}, {"stops_loaded", saved->size()}, {"skipped", skipped}});
  return Execute(stop, std::move(*saved));
}

Expected<ScanResult> ScanSession::Execute(std::stop_token stop, std::vector<SavedStop> saved) {
  const int already = static_cast<int>(saved.size());
  const bool resumed = manifest_.contains("resumed");
  machine_ =
      std::make_unique<ScanStateMachine>(scan_id_, config_.scan.stops, already, Clock::now());
  if (auto entered = Enter(ScanState::kHoming); !entered) return std::unexpected(entered.error());
  if (resumed) {
    Emit(machine_->Note(
        fmt::format("resuming: {} of {} stops are saved; re-homing", already, config_.scan.stops),
        Clock::now()));
  }

  Expected<ScanResult> result = [&]() -> Expected<ScanResult> {
    std::error_code ec;
    if (!resumed || !std::filesystem::exists(folder_.dir() / "scan.toml", ec)) {
      if (auto w = folder_.WriteText("scan.toml", config_.text); !w) {
        return std::unexpected(w.error());
      }
    }
    if (auto w = SaveManifest(); !w) return std::unexpected(w.error());
    // Runs on the thread that requests the stop (a signal handler thread, the daemon's loop), so
    // the motor stops at once, whatever the scanning thread is doing.
    std::stop_callback stop_motor(stop, [this] {
      const auto t = Clock::now();
      devices_.turntable->Stop();
      const double ms = MsSince(t);
      std::lock_guard lock(abort_mutex_);
      motor_stop_ms_ = ms;
      abort_requested_at_ = IsoTimeNow();
    });
    return RunStops(stop, std::move(saved));
  }();
  devices_.turntable->Stop();
  devices_.camera->Stop();
  if (config_.turntable.disable_at_end) (void)devices_.turntable->Disable();

  if (!result && stop.stop_requested()) {
    result = std::unexpected(AbortedError(machine_->stops_done()));
  }
  manifest_["finished"] = IsoTimeNow();
  std::optional<int> alarm_code;
  std::string alarm_text;
  if (result) {
    manifest_["state"] = "complete";
  } else {
    const Error& error = result.error();
    const bool aborted = error.code == ErrorCode::kAborted;
    manifest_["state"] = aborted ? "aborted" : "failed";
    manifest_["error"] = {{"code", ToString(error.code)}, {"message", error.message}};
    if (!aborted) {
      if (auto state = devices_.turntable->State(); state && state->alarm_code) {
        alarm_code = state->alarm_code;
        alarm_text = state->alarm_text;
        manifest_["error"]["alarm_code"] = *state->alarm_code;
        manifest_["error"]["alarm_text"] = alarm_text;
      }
    } else {
      std::lock_guard lock(abort_mutex_);
      manifest_["abort"] = {{"reason", abort_reason_.empty() ? "stop requested" : abort_reason_},
                            {"requested", abort_requested_at_}};
      if (motor_stop_ms_) manifest_["abort"]["motor_stop_ms"] = *motor_stop_ms_;
    }
  }
  if (auto w = SaveManifest(); !w) {
    if (result) result = std::unexpected(w.error());
  }
  if (result) {
    if (auto done = Enter(ScanState::kDone); !done) result = std::unexpected(done.error());
  }
  if (!result) {
    if (auto failed = machine_->Fail(result.error(), Clock::now(), alarm_code, alarm_text)) {
      Emit(std::move(*failed));
    }
  }
  return result;
}

Expected<capture::Frame> ScanSession::CaptureWithRetries(std::stop_token stop, int stop_index,
                                                         capture::Clock::time_point settled) {
  const int retries = config_.station.camera_retries;
  const auto timeout = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(config_.scan.capture_timeout_s));
  std::optional<Error> start_error;
  for (int attempt = 0;; ++attempt) {
    Expected<capture::Frame> frame = start_error
                                         ? Expected<capture::Frame>(std::unexpected(*start_error))
                                         : devices_.camera->Capture(settled, timeout);
    if (frame) return frame;
    const Error& error = frame.error();
    if (!MayPass(error.code) || attempt >= retries || stop.stop_requested()) {
      return std::unexpected(WithContext(
          error, attempt == 0 ? fmt::format("capturing stop {}", stop_index)
                              : fmt::format("capturing stop {} (gave up after {} re-tries)",
                                            stop_index, attempt)));
    }
    Emit(machine_->Note(fmt::format("camera: {}; re-try {} of {}, reopening the camera",
                                    error.message, attempt + 1, retries),
                        Clock::now()));
    devices_.camera->Stop();
    SleepFor(stop, config_.station.camera_retry_delay_ms);
    start_error.reset();
    if (auto started = devices_.camera->Start(); !started) start_error = started.error();
    settled = Clock::now();
  }
}

// What the steps of one run share.
struct ScanSession::Stops {
  ScanGeometry* geometry = nullptr;
  Clock::time_point scan_start;
  Clock::time_point stops_start;
  int captured = 0;  // stops captured by this run (not resumed)
  std::map<int, cv::Mat> thumbnails;
  std::map<int, capture::StopStats> stop_stats;  // of the accepted stops, for the jump gates
  std::set<int> done;
  cv::Mat background;  // the empty scene: given or captured; empty when learned or not needed
  // The backdrop learned from the first stops (no frame of the empty scene).
  std::optional<capture::StopBackdropLearner> learner;
  ScanResult result;
};

Expected<ScanResult> ScanSession::RunStops(std::stop_token stop, std::vector<SavedStop> saved) {
  Stops run;
  run.scan_start = Clock::now();

  // The camera model (station/scan_geometry.h): the calibration, the camera's own geometry, or
  // the thesis's. A resumed scan keeps the calibration it started with.
  std::filesystem::path calibration_file = config_.calibration.file;
  std::error_code exists_error;
  if (manifest_.contains("resumed") &&
      std::filesystem::exists(folder_.dir() / "calibration.toml", exists_error)) {
    calibration_file = folder_.dir() / "calibration.toml";
  }
  auto geometry = ScanGeometry::Create(config_.reconstruct, *devices_.camera, calibration_file);
  if (!geometry) {
    return std::unexpected(
        calibration_file.empty()
            ? geometry.error()
            : WithContext(geometry.error(), fmt::format("{}: [calibration] file", config_.origin)));
  }
  if (geometry->calibration() && calibration_file != folder_.dir() / "calibration.toml") {
    if (auto w = folder_.WriteText("calibration.toml", geometry->calibration_text()); !w) {
      return std::unexpected(w.error());
    }
  }
  run.geometry = &*geometry;
  if (auto r = ReintegrateSaved(run, saved); !r) return std::unexpected(r.error());

  auto t = Clock::now();
  if (auto homed = devices_.turntable->Home(DeadlineIn(config_.scan.move_timeout_s)); !homed) {
    return std::unexpected(WithContext(homed.error(), "homing the turntable"));
  }
  times_.home_ms = MsSince(t);
  if (stop.stop_requested()) return std::unexpected(AbortedError(run.result.stops_done));
  auto format = devices_.camera->Start();
  if (!format) return std::unexpected(WithContext(format.error(), "starting the camera"));
  if (auto size = geometry->CheckFrameSize(format->width_px, format->height_px); !size) {
    return std::unexpected(size.error());
  }
  if (auto prepared = PrepareSegmentation(run); !prepared) {
    return std::unexpected(prepared.error());
  }

  run.stops_start = Clock::now();
  for (int k = 0; k < config_.scan.stops; ++k) {
    if (run.done.contains(k)) continue;
    if (stop.stop_requested()) return std::unexpected(AbortedError(run.result.stops_done));
    if (auto scanned = ScanStop(stop, run, k); !scanned) return std::unexpected(scanned.error());
  }
  if (stop.stop_requested()) return std::unexpected(AbortedError(run.result.stops_done));
  return FinishScan(stop, run);
}

Expected<void> ScanSession::ReintegrateSaved(Stops& run, std::vector<SavedStop>& saved) {
  for (SavedStop& s : saved) {
    if (s.index < 0 || s.index >= config_.scan.stops) continue;
    if (cv::countNonZero(s.mask) == 0) {
      // Not used for the model (see ScanStop); still a stop done.
    } else if (auto integrated = run.geometry->Integrate(s.mask, s.frame, s.readback_deg);
               !integrated) {
      return std::unexpected(
          WithContext(integrated.error(), fmt::format("re-integrating saved stop {}", s.index)));
    }
    run.thumbnails[s.index] = ContactSheetTile(s.frame, s.mask);
    run.stop_stats[s.index] = capture::MeasureStop(s.frame, s.mask);
    run.done.insert(s.index);
    s.frame.release();
    s.mask.release();
  }
  run.result.stops_done = static_cast<int>(run.done.size());
  return {};
}

Expected<void> ScanSession::PrepareSegmentation(Stops& run) {
  const capture::SegmentOptions& segment = config_.segment;
  const bool background_method = devices_.segmenter->NeedsBackground();
  const bool automatic = segment.method == "auto";
  if (!background_method && !automatic) return {};
  if (const auto& file = segment.background_file; !file.empty()) {
    ImageReadOptions read_options;
    read_options.imread_flags = cv::IMREAD_COLOR;
    Expected<cv::Mat> background = ReadImageFile(file, read_options);
    if (!background) {
      return MakeError(ErrorCode::kNotFound,
                       fmt::format("[segment] background_file: {} (take it with `revolve camera "
                                   "snapshot {}` with the plate empty)",
                                   background.error().message, file.string()));
    }
    run.background = std::move(*background);
  } else if (background_method) {
    auto frame = devices_.camera->CaptureBackground(
        Clock::now(), std::chrono::duration_cast<Clock::duration>(
                          std::chrono::duration<double>(config_.scan.capture_timeout_s)));
    if (frame) {
      run.background = frame->image;
    } else if (frame.error().code != ErrorCode::kUnsupported) {
      return std::unexpected(
          WithContext(frame.error(),
                      "capturing the background frame (real cameras need [segment] "
                      "background_file, an image of the empty scene)"));
    }
  }
  if (run.background.empty()) {
    // No frame of the empty scene: the backdrop is learned from the first stops.
    Expected<capture::StopBackdropLearner> learner = capture::StopBackdropLearner::Create(segment);
    if (!learner) return std::unexpected(learner.error());
    run.learner = std::move(*learner);
    Emit(machine_->Note(fmt::format("segmentation: {}", run.learner->reason()), Clock::now()));
    manifest_["segmentation"] = {{"method", run.learner->method()},
                                 {"reason", run.learner->reason()}};
    return {};
  }
  run.background = run.geometry->Undistort(run.background);
  if (auto w = folder_.WriteImage("frames/background.png", run.background); !w) {
    return std::unexpected(w.error());
  }
  return {};
}

Expected<cv::Mat> ScanSession::SegmentStop(Stops& run, const cv::Mat& frame) {
  if (run.learner) return run.learner->Segment(frame);
  return devices_.segmenter->Segment(frame, run.background);
}

Expected<ScanSession::CapturedStop> ScanSession::CaptureAndSegment(
    std::stop_token stop, Stops& run, int k, capture::Clock::time_point settled) {
  // A stop that fails a quality gate is captured again up to [quality] recaptures times, then
  // kept with its warnings.
  CapturedStop captured;
  for (int attempt = 0;; ++attempt) {
    auto t = Clock::now();
    Expected<capture::Frame> frame = CaptureWithRetries(stop, k, settled);
    if (!frame) return std::unexpected(frame.error());
    // Segmented, integrated and saved as the views describe it.
    frame->image = run.geometry->Undistort(frame->image);
    times_.capture_ms += MsSince(t);

    t = Clock::now();
    Expected<cv::Mat> mask = SegmentStop(run, frame->image);
    if (!mask) {
      return std::unexpected(WithContext(mask.error(), fmt::format("segmenting stop {}", k)));
    }
    captured.assessment = capture::AssessStop(
        frame->image, *mask, NeighbourStats(run.stop_stats, k, config_.scan), config_.quality);
    times_.segment_ms += MsSince(t);
    captured.frame = std::move(*frame);
    captured.mask = std::move(*mask);
    if (captured.assessment.ok() || attempt >= config_.quality.recaptures ||
        stop.stop_requested()) {
      break;
    }
    Emit(machine_->Note(fmt::format("stop {}: {}; capturing again ({} of {})", k,
                                    WarningsText(captured.assessment.warnings), attempt + 1,
                                    config_.quality.recaptures),
                        Clock::now()));
    settled = Clock::now();
  }
  // A kept stop teaches the learned backdrop (the first ones), when it has an object.
  if (run.learner && captured.assessment.ok() &&
      run.learner->Add(captured.frame.image, captured.mask)) {
    Emit(machine_->Note(fmt::format("segmentation: {}", run.learner->reason()), Clock::now()));
    manifest_["segmentation"] = {{"method", run.learner->method()},
                                 {"reason", run.learner->reason()},
                                 {"learned_after_stop", k}};
    if (auto w = folder_.WriteImage("frames/background.png", run.learner->backdrop()); !w) {
      return std::unexpected(w.error());
    }
  }
  return captured;
}

Expected<void> ScanSession::ScanStop(std::stop_token stop, Stops& run, int k) {
  const ScanOptions& scan = config_.scan;
  const auto stop_start = Clock::now();
  const double commanded_deg = k * scan.step_deg;

  if (auto e = Enter(ScanState::kMoving, k, commanded_deg); !e) return std::unexpected(e.error());
  auto t = Clock::now();
  if (auto moved = devices_.turntable->MoveTo(commanded_deg, DeadlineIn(scan.move_timeout_s));
      !moved) {
    return std::unexpected(
        WithContext(moved.error(), fmt::format("moving to stop {} ({} deg)", k, commanded_deg)));
  }
  auto state = devices_.turntable->State();
  if (!state) return std::unexpected(WithContext(state.error(), "reading the turntable"));
  times_.move_ms += MsSince(t);

  if (auto e = Enter(ScanState::kSettling, k, commanded_deg); !e) {
    return std::unexpected(e.error());
  }
  t = Clock::now();
  SleepFor(stop, scan.settle_ms);
  if (stop.stop_requested()) return std::unexpected(AbortedError(run.result.stops_done));
  const auto settled = Clock::now();
  times_.settle_ms += MsSince(t);

  if (auto e = Enter(ScanState::kCapturing, k, commanded_deg); !e) {
    return std::unexpected(e.error());
  }
  Expected<CapturedStop> captured = CaptureAndSegment(stop, run, k, settled);
  if (!captured) return std::unexpected(captured.error());
  const capture::StopAssessment& assessment = captured->assessment;
  run.stop_stats[k] = assessment.stats;
  const int mask_area_px = assessment.stats.area_px;
  if (!assessment.ok()) {
    Emit(machine_->Note(fmt::format("stop {}: warning: {}{}", k, WarningsText(assessment.warnings),
                                    mask_area_px == 0 ? " (not used for the model)" : ""),
                        Clock::now()));
  } else if (mask_area_px == 0) {
    Emit(machine_->Note(fmt::format("stop {}: the silhouette is empty (not used for the model)", k),
                        Clock::now()));
  }

  // The integrating event carries the silhouette's area.
  if (auto e = machine_->Enter(ScanState::kIntegrating, Clock::now(), k, commanded_deg); e) {
    e->mask_area_px = mask_area_px;
    Emit(std::move(*e));
  } else {
    return std::unexpected(e.error());
  }
  t = Clock::now();
  // An empty silhouette would carve the whole model away: it is kept in the folder (with its
  // warning) but not used.
  if (mask_area_px > 0) {
    if (auto integrated =
            run.geometry->Integrate(captured->mask, captured->frame.image, state->angle_deg);
        !integrated) {
      return std::unexpected(
          WithContext(integrated.error(), fmt::format("integrating stop {}", k)));
    }
  }
  times_.integrate_ms += MsSince(t);
  if (auto saved = SaveStop(run, k, commanded_deg, state->angle_deg, *captured); !saved) {
    return saved;
  }

  if (on_stop_) {
    StopProgress p;
    p.index = k;
    p.stops = scan.stops;
    p.commanded_deg = commanded_deg;
    p.readback_deg = state->angle_deg;
    p.mask_area_px = mask_area_px;
    p.stop_ms = MsSince(stop_start);
    const double per_stop_ms = MsSince(run.stops_start) / run.captured;
    p.eta_s = per_stop_ms * (scan.stops - run.result.stops_done) / 1000.0;
    on_stop_(p);
  }
  return {};
}

Expected<void> ScanSession::SaveStop(Stops& run, int k, double commanded_deg, double readback_deg,
                                     const CapturedStop& captured) {
  const auto t = Clock::now();
  const std::string name = StopFileName(k);
  const cv::Mat& image = captured.frame.image;
  if (auto w = folder_.WriteImage("frames/" + name, image); !w) return std::unexpected(w.error());
  if (auto w = folder_.WriteImage("masks/" + name, captured.mask); !w) {
    return std::unexpected(w.error());
  }
  run.thumbnails[k] = ContactSheetTile(image, captured.mask);
  nlohmann::json entry = {{"index", k},
                          {"commanded_deg", commanded_deg},
                          {"readback_deg", readback_deg},
                          {"captured", IsoTimeNow()},
                          {"frame", "frames/" + name},
                          {"mask", "masks/" + name},
                          {"mask_area_px", captured.assessment.stats.area_px}};
  if (captured.frame.exposure_us > 0.0) entry["exposure_us"] = captured.frame.exposure_us;
  if (!captured.assessment.ok()) {
    entry["quality"] = nlohmann::json::array();
    for (const capture::QualityWarning& w : captured.assessment.warnings) {
      entry["quality"].push_back({{"code", w.code}, {"message", w.message}});
    }
  }
  manifest_["stops"].push_back(std::move(entry));
  SortStopsByIndex(manifest_["stops"]);
  manifest_["stops_done"] = run.result.stops_done + 1;
  if (auto w = SaveManifest(); !w) return std::unexpected(w.error());
  times_.save_ms += MsSince(t);
  machine_->StopSaved();
  if (on_live_) {
    on_live_(LiveStop{scan_id_, k, config_.scan.stops, image, captured.mask,
                      run.geometry->LiveView(readback_deg, captured.mask.cols, captured.mask.rows),
                      run.geometry->bbox_min_mm(), run.geometry->bbox_max_mm()});
  }
  run.done.insert(k);
  ++run.result.stops_done;
  ++run.captured;
  return {};
}

Expected<ScanResult> ScanSession::FinishScan(std::stop_token stop, Stops& run) {
  ScanResult& result = run.result;
  const ScanGeometry& geometry = *run.geometry;
  if (auto e = Enter(ScanState::kMeshing); !e) return std::unexpected(e.error());
  auto t = Clock::now();
  // The files are written while the mesh is made, each as soon as what it holds is final
  // (mesh_ms is the mesh; write_ms what is left of the files after it).
  reconstruct::Mesh mesh;  // before the writer, which borrows it
  auto writer = reconstruct::ModelWriter::Start(mesh, folder_.model_dir(), "model",
                                                config_.reconstruct.formats);
  if (!writer) return std::unexpected(writer.error());
  if (auto made = run.geometry->Finish(&mesh, (*writer)->Hook()); !made) {
    return std::unexpected(WithContext(made.error(), "meshing"));
  }
  times_.mesh_ms = MsSince(t);
  if (stop.stop_requested()) return std::unexpected(AbortedError(result.stops_done));

  if (auto e = Enter(ScanState::kWriting); !e) return std::unexpected(e.error());
  t = Clock::now();
  auto files = (*writer)->Finish();
  if (!files) return std::unexpected(files.error());
  result.model_files.reserve(files->size());
  for (const auto& f : *files) {
    result.model_files.push_back(std::filesystem::relative(f, folder_.dir()).string());
  }
  std::vector<cv::Mat> tiles;
  tiles.reserve(run.thumbnails.size());
  for (auto& [index, tile] : run.thumbnails) tiles.push_back(tile);
  if (auto w = folder_.WriteImage("contact_sheet.png", AssembleContactSheet(tiles)); !w) {
    return std::unexpected(w.error());
  }
  times_.write_ms = MsSince(t);
  times_.total_ms = MsSince(run.scan_start);

  const reconstruct::MeshStats stats = reconstruct::ComputeStats(mesh);
  result.vertices = static_cast<std::size_t>(stats.vertex_count);
  result.triangles = static_cast<std::size_t>(stats.triangle_count);
  result.times = times_;
  nlohmann::json& report = result.report;
  report["scan_id"] = scan_id_;
  report["recipe"] = config_.recipe;
  report["stops_done"] = result.stops_done;
  // units ("mm" | "px"), scale, camera model, calibration, silhouette axis.
  report.update(geometry.ReportJson());
  // Lengths in the model's unit, named by it: _mm with a metric geometry, _px in thesis mode.
  const std::string unit = geometry.metric() ? "mm" : "px";
  report["model"] = ModelReportJson(result.model_files, stats, unit);
  if (manifest_.contains("segmentation")) report["segmentation"] = manifest_["segmentation"];
  // The quality gates' warnings of the kept stops (the manifest has them per stop).
  report["quality_warnings"] = nlohmann::json::array();
  for (const nlohmann::json& entry : manifest_["stops"]) {
    if (!entry.contains("quality")) continue;
    for (const nlohmann::json& w : entry["quality"]) {
      report["quality_warnings"].push_back(
          {{"stop", entry["index"]}, {"code", w["code"]}, {"message", w["message"]}});
    }
  }
  report["times_ms"] = times_.ToJson();
  // The truth is in millimetres: not comparable with a thesis-mode model in pixels.
  if (auto truth = devices_.camera->KnownScene(); truth && geometry.metric()) {
    report["accuracy"] = AccuracyJson(mesh, stats, *truth);
  }
  if (auto w = folder_.WriteJson("report.json", report); !w) return std::unexpected(w.error());
  manifest_["model"] = result.model_files;
  return result;
}

}  // namespace revolve::station
