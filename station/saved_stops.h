// The stops a scan folder holds: what `revolve start --resume` and `revolve reconstruct
// SCAN_DIR` build on.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "base/error.h"

namespace revolve::station {

struct SavedStop {
  int index = 0;
  double commanded_deg = 0.0;
  double readback_deg = 0.0;
  std::string frame_file;  // relative to the scan folder
  std::string mask_file;
  cv::Mat frame;         // CV_8UC3; empty unless loaded
  cv::Mat mask;          // CV_8UC1
  nlohmann::json entry;  // the manifest's entry, as saved
};

// The stops listed in `manifest` (a scan folder's manifest.json) whose mask (and, with
// `load_frames`, frame) can be read from `dir`, by index, each index once (the last entry wins).
// Stops listed but unreadable are left out and named in `skipped` (may be null): a resumed scan
// captures them again. Errors: bad_input when the manifest has no "stops" array.
Expected<std::vector<SavedStop>> ReadSavedStops(const std::filesystem::path& dir,
                                                const nlohmann::json& manifest, bool load_frames,
                                                std::vector<std::string>* skipped);

}  // namespace revolve::station
