#include "station/saved_stops.h"

#include <map>
#include <optional>

#include <fmt/format.h>

#include "base/image_read.h"
#include "station/manifest.h"

namespace revolve::station {

Expected<std::vector<SavedStop>> ReadSavedStops(const std::filesystem::path& dir,
                                                const nlohmann::json& manifest, bool load_frames,
                                                std::vector<std::string>* skipped) {
  const std::string manifest_file = (dir / "manifest.json").string();
  if (auto checked = CheckManifest(manifest, manifest_file); !checked) {
    return std::unexpected(checked.error());
  }
  std::map<int, SavedStop> by_index;
  std::optional<cv::Size> mask_size;
  std::string first_mask;
  for (std::size_t position = 0; position < manifest["stops"].size(); ++position) {
    const nlohmann::json& entry = manifest["stops"][position];
    SavedStop stop;
    stop.manifest_position = static_cast<int>(position);
    stop.index = entry["index"].get<int>();
    stop.commanded_deg = entry.value("commanded_deg", 0.0);
    stop.readback_deg = entry.value("readback_deg", stop.commanded_deg);
    stop.frame_file = entry.value("frame", std::string());
    stop.mask_file = entry.value("mask", std::string());
    stop.entry = entry;
    const std::string what =
        fmt::format("stop {} ({} stops[{}].mask)", stop.index, manifest_file, position);
    if (stop.mask_file.empty()) {
      if (skipped) skipped->push_back(what + ": no mask listed");
      continue;
    }
    ImageReadOptions read;
    read.imread_flags = cv::IMREAD_GRAYSCALE;
    read.expected_size = mask_size;
    Expected<cv::Mat> mask = ReadImageFile(dir / stop.mask_file, read);
    if (!mask) {
      // Masks of one scan share one size: another size is a contradiction, not a lost stop.
      if (mask_size && mask.error().code == ErrorCode::kBadInput) {
        if (auto header = ReadImageHeader(dir / stop.mask_file);
            header &&
            (header->width_px != mask_size->width || header->height_px != mask_size->height)) {
          return MakeError(
              ErrorCode::kBadInput,
              fmt::format("{}: {} x {} pixels, but {} is {} x {}: the masks of one "
                          "scan have one size (a mask was replaced?)",
                          (dir / stop.mask_file).string(), header->width_px, header->height_px,
                          first_mask, mask_size->width, mask_size->height));
        }
      }
      if (skipped) skipped->push_back(what + ": " + mask.error().message);
      continue;
    }
    stop.mask = std::move(*mask);
    if (!mask_size) {
      mask_size = stop.mask.size();
      first_mask = (dir / stop.mask_file).string();
    }
    if (load_frames) {
      ImageReadOptions frame_read;
      frame_read.imread_flags = cv::IMREAD_COLOR;
      frame_read.expected_size = stop.mask.size();
      Expected<cv::Mat> frame = ReadImageFile(dir / stop.frame_file, frame_read);
      if (!frame) {
        if (skipped) {
          skipped->push_back(fmt::format("stop {} ({} stops[{}].frame): {}", stop.index,
                                         manifest_file, position, frame.error().message));
        }
        continue;
      }
      stop.frame = std::move(*frame);
    }
    by_index[stop.index] = std::move(stop);
  }
  std::vector<SavedStop> stops;
  stops.reserve(by_index.size());
  for (auto& [index, stop] : by_index) stops.push_back(std::move(stop));
  return stops;
}

}  // namespace revolve::station
