// The whole station's configuration: [scan] plus each module's own section.
#pragma once

#include <filesystem>
#include <optional>

#include "base/error.h"
#include "capture/camera.h"
#include "capture/segmenter.h"
#include "config/config.h"
#include "reconstruct/reconstructor.h"
#include "turntable/turntable.h"

namespace revolve::station {

// [scan]
struct ScanOptions {
  int stops = 36;
  double step_deg = 10.0;
  double settle_ms = 30.0;
  double move_timeout_s = 10.0;
  double capture_timeout_s = 5.0;
};

struct StationConfig {
  std::string origin;  // the file it came from, or config::kEmbeddedOrigin
  std::string text;    // the TOML text as given (saved as scan.toml in every scan folder)
  ScanOptions scan;
  turntable::TurntableOptions turntable;
  capture::CameraOptions camera;
  capture::SegmentOptions segment;
  reconstruct::ReconstructOptions reconstruct;
};

// Parses a whole document: every section, unknown tables and keys are errors naming
// file:line:column.
Expected<StationConfig> ParseStationConfig(const config::Document& document);

// Loads `path`, or the embedded default (the simulated rig) when `path` is empty.
Expected<StationConfig> LoadStationConfig(const std::optional<std::filesystem::path>& path);

}  // namespace revolve::station
