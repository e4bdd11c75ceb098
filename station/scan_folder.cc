#include "station/scan_folder.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "base/atomic_file.h"
#include "base/image_codecs.h"
#include "base/png_encode.h"
#include "base/text_file.h"
#include "station/manifest.h"

namespace revolve::station {

Expected<ScanFolder> ScanFolder::Create(const std::filesystem::path& dir) {
  std::error_code ec;
  if (std::filesystem::exists(dir, ec) && !std::filesystem::is_empty(dir, ec)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{}: already exists and is not empty; a scan never overwrites "
                                 "an earlier one (choose another --out or remove it)",
                                 dir.string()));
  }
  for (const char* sub : {"frames", "masks", "model"}) {
    std::filesystem::create_directories(dir / sub, ec);
    if (ec) {
      return MakeError(ErrorCode::kIo, fmt::format("{}: cannot create the scan folder: {}",
                                                   (dir / sub).string(), ec.message()));
    }
  }
  return ScanFolder(dir);
}

Expected<ScanFolder> ScanFolder::Open(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(dir / "manifest.json", ec)) {
    return MakeError(ErrorCode::kNotFound,
                     fmt::format("{}: not a scan folder (no manifest.json)", dir.string()));
  }
  for (const char* sub : {"frames", "masks", "model"}) {
    std::filesystem::create_directories(dir / sub, ec);
    if (ec) {
      return MakeError(ErrorCode::kIo,
                       fmt::format("{}: cannot create: {}", (dir / sub).string(), ec.message()));
    }
  }
  return ScanFolder(dir);
}

Expected<void> ScanFolder::Write(const std::string& relative, std::span<const char> bytes) const {
  if (limit_bytes_ > 0) {
    const auto size = static_cast<std::int64_t>(bytes.size());
    if (written_bytes_->load() + size > limit_bytes_) {
      return MakeError(ErrorCode::kIo,
                       fmt::format("{}: write failed: {} (simulated: station.simulate."
                                   "disk_limit_bytes)",
                                   (dir_ / relative).string(), std::strerror(ENOSPC)));
    }
    written_bytes_->fetch_add(size);
  }
  return WriteFileAtomically(dir_ / relative, bytes);
}

Expected<void> ScanFolder::WriteImage(const std::string& relative, const cv::Mat& image) const {
  // Frames and masks (8-bit BGR or grey) by revolve's own encoder; anything else by OpenCV's.
  if (image.depth() == CV_8U && (image.channels() == 3 || image.channels() == 1)) {
    const Expected<std::string> own = EncodePng(image);
    if (!own) {
      return MakeError(own.error().code,
                       fmt::format("{}: {}", (dir_ / relative).string(), own.error().message));
    }
    return Write(relative, std::span<const char>(own->data(), own->size()));
  }
  const Expected<std::vector<std::uint8_t>> png = EncodeImage(".png", image);
  if (!png) {
    return MakeError(png.error().code,
                     fmt::format("{}: cannot encode the image as PNG: {}",
                                 (dir_ / relative).string(), png.error().message));
  }
  return Write(relative,
               std::span<const char>(reinterpret_cast<const char*>(png->data()), png->size()));
}

Expected<void> ScanFolder::WriteText(const std::string& relative, std::string_view text) const {
  return Write(relative, std::span<const char>(text.data(), text.size()));
}

Expected<void> ScanFolder::WriteJson(const std::string& relative,
                                     const nlohmann::json& json) const {
  return WriteText(relative, json.dump(2) + "\n");
}

Expected<nlohmann::json> ReadManifest(const std::filesystem::path& dir) {
  const std::filesystem::path path = dir / "manifest.json";
  // At most kMaxManifestStops stops of a few hundred bytes; a device or FIFO is refused.
  auto text = ReadRegularFile(path, std::uintmax_t{64} << 20);
  if (!text) {
    return MakeError(
        text.error().code == ErrorCode::kBadInput ? ErrorCode::kBadInput : ErrorCode::kNotFound,
        fmt::format("{} (not a scan folder?)", text.error().message));
  }
  nlohmann::json manifest = nlohmann::json::parse(*text, nullptr, false);
  if (manifest.is_discarded() || !manifest.is_object()) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{}: not a JSON object (damaged manifest)", path.string()));
  }
  if (auto checked = CheckManifest(manifest, path.string()); !checked) {
    return std::unexpected(checked.error());
  }
  return manifest;
}

std::string StopFileName(int index) { return fmt::format("stop_{:03d}.png", index); }

std::string NewScanId() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm local{};
  localtime_r(&now, &local);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y%m%d-%H%M%S", &local);
  return buf;
}

nlohmann::json ListScanFolders(const std::filesystem::path& scans_dir, std::string_view running_id,
                               std::size_t max_scans) {
  std::vector<std::string> ids;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(scans_dir, ec)) {
    if (entry.is_directory(ec)) ids.push_back(entry.path().filename().string());
  }
  std::sort(ids.begin(), ids.end());
  if (ids.size() > max_scans) ids.erase(ids.begin(), ids.end() - static_cast<long>(max_scans));
  nlohmann::json scans = nlohmann::json::array();
  for (const std::string& id : ids) {
    nlohmann::json s = {{"id", id}};
    auto manifest = ReadManifest(scans_dir / id);
    if (!manifest) {
      s["state"] = "unknown";
      s["error"] = manifest.error().message;
    } else {
      std::string state = manifest->value("state", std::string("unknown"));
      if (state == "running" && id != running_id) state = "interrupted";
      s["state"] = state;
      s["recipe"] = manifest->value("recipe", std::string("default"));
      s["stops_done"] = manifest->value("stops_done", 0);
      s["stops_planned"] = manifest->value("stops_planned", 0);
      s["started"] = manifest->value("started", std::string());
      s["finished"] = manifest->value("finished", std::string());
      if (manifest->contains("model")) s["model"] = (*manifest)["model"];
      if (manifest->contains("error") && (*manifest)["error"].is_object()) {
        s["error"] = (*manifest)["error"].value("message", std::string());
      }
    }
    scans.push_back(std::move(s));
  }
  return scans;
}

}  // namespace revolve::station
