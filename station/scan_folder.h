// A scan folder (layout in README "Scan folder"): every file is written to a temporary name,
// fsynced and renamed, so the folder never holds a half-written file.
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "base/error.h"

namespace revolve::station {

class ScanFolder {
 public:
  // Creates `dir` with frames/, masks/ and model/. Refuses (bad_input) a `dir` that exists and
  // is not empty, so an earlier scan is never overwritten.
  static Expected<ScanFolder> Create(const std::filesystem::path& dir);

  const std::filesystem::path& dir() const { return dir_; }
  std::filesystem::path model_dir() const { return dir_ / "model"; }

  // Writes an image (PNG) at `relative` (e.g. "frames/stop_000.png").
  Expected<void> WriteImage(const std::string& relative, const cv::Mat& image) const;
  Expected<void> WriteText(const std::string& relative, std::string_view text) const;
  Expected<void> WriteJson(const std::string& relative, const nlohmann::json& json) const;

 private:
  explicit ScanFolder(std::filesystem::path dir) : dir_(std::move(dir)) {}
  std::filesystem::path dir_;
};

// "stop_007.png"
std::string StopFileName(int index);

// A new scan id from the local time: "20261121-230105".
std::string NewScanId();

}  // namespace revolve::station
