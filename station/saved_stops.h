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
  int manifest_position = 0;  // its place in the manifest's "stops" (stops[i]), for messages
  cv::Mat frame;              // CV_8UC3; empty unless loaded
  cv::Mat mask;               // CV_8UC1
  nlohmann::json entry;       // the manifest's entry, as saved
};

// The stops listed in `manifest` (a scan folder's manifest.json) whose mask (and, with
// `load_frames`, frame of the mask's size) can be read from `dir`, by index. Stops listed but
// unreadable (missing, cut short, damaged: base/image_read.h) are left out and named, with the
// file and why, in `skipped` (may be null): a resumed scan captures them again. Errors:
// bad_input naming the file and field when the manifest fails CheckManifest (station/manifest.h:
// wrong types, a stop listed twice, ...), or naming the mask whose size differs from the others.
Expected<std::vector<SavedStop>> ReadSavedStops(const std::filesystem::path& dir,
                                                const nlohmann::json& manifest, bool load_frames,
                                                std::vector<std::string>* skipped);

}  // namespace revolve::station
