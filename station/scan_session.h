// One scan as a state machine (station/scan_state.h): home, then for each stop move, settle,
// capture (and segment), integrate (and save); then mesh, write the model and the report. Each
// transition is reported as a ScanEvent. The scan folder's manifest is rewritten after every
// stop, so an interrupted scan says how far it got, and Resume() finishes it.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stop_token>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "capture/quality.h"
#include "station/devices.h"
#include "station/saved_stops.h"
#include "station/scan_folder.h"
#include "station/scan_state.h"
#include "station/station_config.h"

namespace revolve::station {

// Wall-clock milliseconds spent in each stage, summed over the stops.
struct StageTimes {
  double home_ms = 0, move_ms = 0, settle_ms = 0, capture_ms = 0, segment_ms = 0, integrate_ms = 0,
         save_ms = 0, mesh_ms = 0, write_ms = 0, total_ms = 0;
  nlohmann::json ToJson() const;
};

// Reported after each stop.
struct StopProgress {
  int index = 0;  // 0-based
  int stops = 0;
  double commanded_deg = 0;
  double readback_deg = 0;
  int mask_area_px = 0;
  double stop_ms = 0;  // wall time of this stop
  double eta_s = 0;    // estimated time until the last stop is saved
};

// A saved stop as the live console shows it (station/live_view.h). The images are shared, not
// copied: neither the session nor a listener writes into them after the call.
struct LiveStop {
  std::string scan_id;
  int index = 0;
  int stops = 0;
  cv::Mat frame;             // as saved (undistorted), BGR
  cv::Mat mask;              // CV_8UC1, non-zero = object
  std::optional<View> view;  // known while scanning (not in thesis mode)
  Eigen::Vector3d bbox_min_mm = Eigen::Vector3d::Zero();  // the carving volume
  Eigen::Vector3d bbox_max_mm = Eigen::Vector3d::Zero();
};

struct ScanResult {
  int stops_done = 0;
  StageTimes times;
  std::size_t vertices = 0;
  std::size_t triangles = 0;
  std::vector<std::string> model_files;  // relative to the scan folder
  nlohmann::json report;                 // what report.json holds
};

class ScanSession {
 public:
  // Borrows everything; all must outlive the session. `scan_id` names the scan in events
  // (default: the folder's name).
  ScanSession(const StationConfig& config, Devices& devices, const ScanFolder& folder,
              std::string scan_id = {});

  // Called on the scanning thread after each stop is saved.
  void OnStop(std::function<void(const StopProgress&)> callback) { on_stop_ = std::move(callback); }
  // Called on the scanning thread after each stop is saved, with its frame and mask; must return
  // quickly (queue the work elsewhere): the next stop waits for it.
  void OnLive(std::function<void(const LiveStop&)> callback) { on_live_ = std::move(callback); }
  // Called on the scanning thread for every event (transitions and notes), in order. The last
  // event of Run()/Resume() is terminal (done, failed or aborted) and comes after the manifest
  // says so.
  void OnEvent(std::function<void(const ScanEvent&)> callback) { on_event_ = std::move(callback); }

  // Why the next stop request comes ("SIGTERM", "abort requested by a client"): recorded in the
  // manifest and the aborted event. Thread-safe; call before requesting the stop.
  void SetAbortReason(std::string reason);

  // Runs the scan. A stop request stops the motor at once (from the requesting thread) and
  // returns aborted. On any error the motor is stopped, the manifest says "failed" or "aborted"
  // with the reason (and the drive's alarm), and the frames and masks saved so far stay. Capture
  // errors that may pass (timeout, no_device, link_down, io) are re-tried
  // [station] camera_retries times, reopening the camera in between.
  Expected<ScanResult> Run(std::stop_token stop);

  // Finishes an interrupted scan in `folder` (opened with ScanFolder::Open): re-integrates the
  // stops its manifest lists, re-homes, captures the missing stops, then meshes and writes as
  // Run() does. Errors: bad_input when the folder's plan (stops, step) differs from `config`'s.
  Expected<ScanResult> Resume(std::stop_token stop);

 private:
  Expected<ScanResult> Execute(std::stop_token stop, std::vector<SavedStop> saved);
  // RunStops' steps: the saved stops of a resumed scan, the background frame or the learner
  // (no frame of the empty scene), each stop (move, settle, capture and segment with its quality
  // gates, integrate, save), then the model and the report.
  struct Stops;
  struct CapturedStop {
    capture::Frame frame;
    cv::Mat mask;
    capture::StopAssessment assessment;
  };
  Expected<ScanResult> RunStops(std::stop_token stop, std::vector<SavedStop> saved);
  Expected<void> ReintegrateSaved(Stops& run, std::vector<SavedStop>& saved);
  Expected<void> PrepareSegmentation(Stops& run);
  Expected<cv::Mat> SegmentStop(Stops& run, const cv::Mat& frame);
  Expected<CapturedStop> CaptureAndSegment(std::stop_token stop, Stops& run, int k,
                                           capture::Clock::time_point settled);
  Expected<void> ScanStop(std::stop_token stop, Stops& run, int k);
  Expected<void> SaveStop(Stops& run, int k, double commanded_deg, double readback_deg,
                          const CapturedStop& captured);
  Expected<ScanResult> FinishScan(std::stop_token stop, Stops& run);
  Expected<capture::Frame> CaptureWithRetries(std::stop_token stop, int stop_index,
                                              capture::Clock::time_point settled);
  Expected<void> SaveManifest();
  Expected<void> Enter(ScanState state, int stop = -1, double angle_deg = 0.0);
  void Emit(ScanEvent event);
  Error AbortedError(int stops_done) const;

  const StationConfig& config_;
  Devices& devices_;
  const ScanFolder& folder_;
  std::string scan_id_;
  std::function<void(const StopProgress&)> on_stop_;
  std::function<void(const ScanEvent&)> on_event_;
  std::function<void(const LiveStop&)> on_live_;
  nlohmann::json manifest_;
  StageTimes times_;
  std::unique_ptr<ScanStateMachine> machine_;

  mutable std::mutex abort_mutex_;
  std::string abort_reason_;
  std::string abort_requested_at_;       // UTC ISO time of the stop request
  std::optional<double> motor_stop_ms_;  // how long Turntable::Stop() took on the stop request
};

// UTC, ISO 8601 with milliseconds: "2026-11-21T23:01:05.123Z".
std::string IsoTimeNow();

}  // namespace revolve::station
