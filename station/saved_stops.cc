#include "station/saved_stops.h"

#include <map>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

namespace revolve::station {

Expected<std::vector<SavedStop>> ReadSavedStops(const std::filesystem::path& dir,
                                                const nlohmann::json& manifest, bool load_frames,
                                                std::vector<std::string>* skipped) {
  if (!manifest.contains("stops") || !manifest["stops"].is_array()) {
    return MakeError(ErrorCode::kBadInput, fmt::format("{}: the manifest lists no stops",
                                                       (dir / "manifest.json").string()));
  }
  std::map<int, SavedStop> by_index;
  for (const nlohmann::json& entry : manifest["stops"]) {
    if (!entry.is_object() || !entry.contains("index") || !entry["index"].is_number_integer()) {
      if (skipped) skipped->push_back("a manifest entry without an index");
      continue;
    }
    SavedStop stop;
    stop.index = entry["index"].get<int>();
    stop.commanded_deg = entry.value("commanded_deg", 0.0);
    stop.readback_deg = entry.value("readback_deg", stop.commanded_deg);
    stop.frame_file = entry.value("frame", std::string());
    stop.mask_file = entry.value("mask", std::string());
    stop.entry = entry;
    const std::string what = fmt::format("stop {}", stop.index);
    if (stop.mask_file.empty()) {
      if (skipped) skipped->push_back(what + ": no mask listed");
      continue;
    }
    stop.mask = cv::imread((dir / stop.mask_file).string(), cv::IMREAD_GRAYSCALE);
    if (stop.mask.empty()) {
      if (skipped) skipped->push_back(what + ": cannot read " + stop.mask_file);
      continue;
    }
    if (load_frames) {
      stop.frame = cv::imread((dir / stop.frame_file).string(), cv::IMREAD_COLOR);
      if (stop.frame.empty() || stop.frame.size() != stop.mask.size()) {
        if (skipped) skipped->push_back(what + ": cannot read " + stop.frame_file);
        continue;
      }
    }
    by_index[stop.index] = std::move(stop);
  }
  std::vector<SavedStop> stops;
  stops.reserve(by_index.size());
  for (auto& [index, stop] : by_index) stops.push_back(std::move(stop));
  return stops;
}

}  // namespace revolve::station
