// The whole station's configuration: [scan], [station], [daemon], [operator], [recipes.*] plus
// each module's own section ([calibration]: docs/calibration.md). Every key, type, default and
// range: docs/configuration.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "base/error.h"
#include "calibrate/options.h"
#include "capture/camera.h"
#include "capture/quality.h"
#include "capture/segmenter.h"
#include "config/config.h"
#include "reconstruct/reconstructor.h"
#include "turntable/turntable.h"

namespace revolve::station {

// [scan]
struct ScanOptions {
  int stops = 36;                  // [1, 3600]; stops * step_deg <= 360
  double step_deg = 10.0;          // [0.01, 360]
  double settle_ms = 30.0;         // [0, 60000]
  double move_timeout_s = 10.0;    // [0.1, 3600]
  double capture_timeout_s = 5.0;  // [0.1, 600]
};

// [station.simulate]: fault injection for the simulated rig (tests, demos). Refused with a real
// drive or camera.
struct SimulateOptions {
  std::string drive_fault = "none";  // none | stall | alarm | link_down (mock turntable only)
  int drive_fault_move = 0;          // the MoveTo() (counted from the daemon's start) that faults
  int drive_fault_count = 1;         // how many consecutive moves fault
  double drive_fault_at = 0.5;       // fraction of the move's time at which it strikes, [0, 1]
  int drive_alarm_code = 0x31;       // alarm code reported with drive_fault = "alarm"
  std::int64_t camera_fail_after =
      -1;  // captures (since start-up) before the camera is lost; -1 never
  std::int64_t camera_fail_count = 1;  // consecutive captures that fail with no_device
  // A bad frame instead of a lost camera, for the quality gates: none | blank (black: an empty
  // silhouette) | overexposed (gain x4) | blurred (Gaussian, sigma 6 px).
  std::string camera_glitch = "none";
  std::int64_t camera_glitch_after = 0;  // captures (since start-up) before the first bad frame
  std::int64_t camera_glitch_count = 1;  // consecutive bad frames
  std::int64_t disk_limit_bytes = 0;     // a scan folder's simulated disk space; 0 = unlimited

  bool Any() const {
    return drive_fault != "none" || camera_fail_after >= 0 || camera_glitch != "none" ||
           disk_limit_bytes > 0;
  }
};

// [station]
struct StationOptions {
  std::string recipe = "default";  // recipe of `revolve start` without --recipe and of the button
  // Where the daemon creates scans/<id>. Relative: to $STATE_DIRECTORY (systemd's
  // StateDirectory=) when set, else to the working directory.
  std::string scans_dir = "scans";
  int camera_retries = 2;  // re-tries of a failed capture (reopening the camera), [0, 20]
  double camera_retry_delay_ms = 200.0;  // [0, 60000]
  double min_free_mb = 16.0;  // a start is refused with less free space in scans_dir, [0, 1e7]
  SimulateOptions simulate;
};

// [daemon]
struct DaemonOptions {
  std::string socket = "/run/revolve/control.sock";  // the control socket's path
  int socket_mode = 0660;                            // octal string "0660", [0, 0777]
  std::string socket_group;                          // group name; "" = the daemon's own group
  int max_clients = 32;                              // [1, 1024]
  int max_request_bytes = 4096;                      // [64, 1048576]
  // A client that sends nothing and watches nothing for this long is closed; with every slot
  // taken, the one idle longest gives its slot to a newcomer. [1, 86400]
  double idle_timeout_s = 30.0;
};

// [web]: the web console and HTTP API (station/web_server.h, docs/web-console.md).
struct WebOptions {
  // "host:port" ("[::1]:8080" for IPv6); "" turns the server off. Port 0: any free port (the
  // log and the status say which). A host other than loopback (127.0.0.0/8, ::1, localhost)
  // needs token_file.
  std::string listen = "127.0.0.1:8080";
  // A file holding the access token (one line). Loopback: POSTs need it when set. Other hosts:
  // every request needs it. Relative to the config file's folder.
  std::string token_file;
  int max_connections = 64;       // open connections served at once, [1, 1024]
  int max_request_bytes = 65536;  // longest request body, [1024, 16777216]
  double timeout_s = 5.0;         // read/write timeout and idle keep-alive, [0.5, 300]
};

// `listen` split: host (no brackets) and port. Errors: bad_input for a malformed value.
struct ListenAddress {
  std::string host;
  int port = 0;
  bool loopback = false;
};
Expected<ListenAddress> ParseListenAddress(std::string_view listen);

// One GPIO line of the operator panel: an offset or a line name on [operator] chip.
using PanelLine = turntable::GpioLineSpec;

// [operator]: the start button, an optional abort button, the status LED, an optional lamp
// relay. No line configured: no panel.
struct OperatorOptions {
  std::string chip = "gpiochip0";  // name, /dev path or label
  PanelLine start_button;          // start_button, start_button_active_low (default true)
  PanelLine abort_button;          // abort_button, abort_button_active_low (default true)
  PanelLine led;                   // led, led_active_low (default false)
  PanelLine lamp;                  // lamp, lamp_active_low (default false)
  std::string bias = "pull_up";    // buttons: pull_up | pull_down | disable | as_is
  double debounce_ms = 30.0;       // [0, 1000]

  bool Any() const {
    return start_button.present() || abort_button.present() || led.present() || lamp.present();
  }
};

// [recipes.NAME]: a named scan. Each key overrides one key of the base configuration:
//   stops, step_deg, settle_ms -> [scan]; exposure_us -> [camera.v4l2] / [camera.libcamera];
//   segment -> [segment] method; threshold -> [segment] threshold;
//   method, resolution, formats -> [reconstruct].
struct Recipe {
  std::string name;
  std::optional<int> stops;
  std::optional<double> step_deg;
  std::optional<double> settle_ms;
  std::optional<double> exposure_us;
  std::optional<std::string> segment;
  std::optional<int> threshold;
  std::optional<std::string> method;
  std::optional<int> resolution;
  std::optional<std::vector<std::string>> formats;
};

struct StationConfig {
  std::string origin;  // the file it came from, or config::kEmbeddedOrigin
  std::string text;    // the TOML as given, or the effective TOML after ApplyRecipe (scan.toml)
  std::string recipe = "default";  // the recipe this configuration is the effect of
  ScanOptions scan;
  StationOptions station;
  DaemonOptions daemon;
  WebOptions web;
  OperatorOptions panel;
  std::map<std::string, Recipe, std::less<>> recipes;  // "default" is implicit
  turntable::TurntableOptions turntable;
  capture::CameraOptions camera;
  capture::SegmentOptions segment;
  capture::QualityOptions quality;  // [quality]: the per-stop gates (capture/quality.h)
  reconstruct::ReconstructOptions reconstruct;
  // [calibration]: the calibration scans use (`file`, resolved against the config file's folder;
  // empty: none), the board and the gates of `revolve calibrate` (docs/calibration.md).
  calibrate::CalibrationOptions calibration;
};

// Parses a whole document: every section, unknown tables and keys are errors naming
// file:line:column.
Expected<StationConfig> ParseStationConfig(const config::Document& document);

// The descriptions of the keys of [scan], [station], [station.simulate], [daemon], [operator]
// and [recipes.NAME], for the configuration reference (config/reference.h).
config::OptionDocs ReferenceDocs();

// Loads `path`, or the embedded default (the simulated rig) when `path` is empty.
Expected<StationConfig> LoadStationConfig(const std::optional<std::filesystem::path>& path);

// The configuration of one scan with recipe `name` ("" = base.station.recipe): the recipe's keys
// laid over the base configuration. "default" without a [recipes.default] table is the base
// itself. The result's `text` is the effective TOML (no [recipes], no station.recipe), which
// reproduces the scan. Errors: not_found for an unknown recipe (naming the known ones);
// bad_input naming file:line:column when a recipe's value does not fit its key.
Expected<StationConfig> ApplyRecipe(const StationConfig& base, std::string_view name);

// Everything a scan checks of its configuration short of opening devices, shared by `revolve
// scan`, the daemon's start and `revolve check-config`: the segmenter's options, the configured
// turntable and camera backends' option sets, and the calibration file (loaded, and it must hold
// the turntable's axis). Errors name the file (and the key, where the options have one).
Expected<void> CheckWithoutDevices(const StationConfig& config);

// The names of the recipes: "default" first, then the configured ones.
std::vector<std::string> RecipeNames(const StationConfig& config);

}  // namespace revolve::station
