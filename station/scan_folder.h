// A scan folder (layout in docs/reconstruction.md, "The scan folder"): every file is written to a
// temporary name, fsynced and renamed, so the folder never holds a half-written file.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "base/error.h"

namespace revolve::station {

class ScanFolder {
 public:
  // Creates `dir` with frames/, masks/ and model/. Refuses (bad_input) a `dir` that exists and
  // is not empty, so an earlier scan is never overwritten.
  static Expected<ScanFolder> Create(const std::filesystem::path& dir);

  // An existing scan folder (to resume or rebuild it): `dir` must hold a manifest.json.
  // Errors: not_found.
  static Expected<ScanFolder> Open(const std::filesystem::path& dir);

  // Simulates a disk that fills after `bytes` more bytes (0: unlimited): a write that would pass
  // it fails with io "No space left on device" and writes nothing. For fault injection.
  void SetByteLimit(std::int64_t bytes) { limit_bytes_ = bytes; }

  const std::filesystem::path& dir() const { return dir_; }
  std::filesystem::path model_dir() const { return dir_ / "model"; }

  // Writes an image (PNG) at `relative` (e.g. "frames/stop_000.png").
  Expected<void> WriteImage(const std::string& relative, const cv::Mat& image) const;
  Expected<void> WriteText(const std::string& relative, std::string_view text) const;
  Expected<void> WriteJson(const std::string& relative, const nlohmann::json& json) const;

 private:
  explicit ScanFolder(std::filesystem::path dir) : dir_(std::move(dir)) {}
  Expected<void> Write(const std::string& relative, std::span<const char> bytes) const;

  std::filesystem::path dir_;
  std::int64_t limit_bytes_ = 0;
  std::shared_ptr<std::atomic<std::int64_t>> written_bytes_ =
      std::make_shared<std::atomic<std::int64_t>>(0);
};

// Reads `dir`/manifest.json and checks it (station/manifest.h: CheckManifest). Errors:
// not_found, bad_input (not JSON, a field of the wrong type or range, a stop listed twice: names
// the file and the field).
Expected<nlohmann::json> ReadManifest(const std::filesystem::path& dir);

// The scans in `scans_dir` (at most `max_scans`, the newest by id), oldest first: per scan its
// id, state ("running" only for `running_id`; another "running" manifest is "interrupted"),
// recipe, stops_done, stops_planned, started, finished, model (files) and error, from its
// manifest; a folder whose manifest cannot be read is listed with state "unknown" and the error.
nlohmann::json ListScanFolders(const std::filesystem::path& scans_dir, std::string_view running_id,
                               std::size_t max_scans);

// "stop_007.png"
std::string StopFileName(int index);

// A new scan id from the local time: "20261121-230105".
std::string NewScanId();

}  // namespace revolve::station
