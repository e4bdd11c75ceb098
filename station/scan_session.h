// One scan: home, then for each stop move, settle, capture, segment, integrate and save; then
// mesh, write the model and the report. The scan folder's manifest is rewritten after every
// stop, so an interrupted scan says how far it got.
#pragma once

#include <functional>
#include <memory>
#include <stop_token>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "base/sim_plate.h"
#include "capture/camera.h"
#include "capture/segmenter.h"
#include "reconstruct/reconstructor.h"
#include "station/scan_folder.h"
#include "station/station_config.h"
#include "turntable/turntable.h"

namespace revolve::station {

// The devices of a rig, owned. For the simulated rig the turntable and the camera share `plate`.
struct Devices {
  std::shared_ptr<SimulatedPlate> plate;
  std::unique_ptr<turntable::Turntable> turntable;
  std::unique_ptr<capture::Camera> camera;
  std::unique_ptr<capture::Segmenter> segmenter;
};

// Creates the configured devices (nothing moves yet).
Expected<Devices> OpenDevices(const StationConfig& config);

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
  double eta_s = 0;    // estimated time until the model is written
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
  // Borrows everything; all must outlive the session.
  ScanSession(const StationConfig& config, Devices& devices, const ScanFolder& folder);

  void OnStop(std::function<void(const StopProgress&)> callback) { on_stop_ = std::move(callback); }

  // Runs the scan. A stop request (signal, abort) stops the motor and returns kAborted. On any
  // error the motor is stopped, the manifest says "failed" or "aborted" with the reason, and
  // the frames and masks saved so far stay.
  Expected<ScanResult> Run(std::stop_token stop);

 private:
  Expected<ScanResult> RunStops(std::stop_token stop);
  Expected<void> SaveManifest();

  const StationConfig& config_;
  Devices& devices_;
  const ScanFolder& folder_;
  std::function<void(const StopProgress&)> on_stop_;
  nlohmann::json manifest_;
  StageTimes times_;
};

}  // namespace revolve::station
