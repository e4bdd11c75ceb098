// `revolve reconstruct SCAN_DIR`: rebuilds the model of a scan folder from the stops it holds
// (a complete scan with other settings, or an interrupted one from the stops it got), with the
// camera geometry of the scan's own scan.toml.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <optional>
#include <stop_token>
#include <string>
#include <vector>

namespace revolve::station {

struct ReconstructCommandOptions {
  std::filesystem::path scan_dir;
  std::optional<std::filesystem::path> out;  // default: SCAN_DIR/model
  std::optional<std::string> method;         // default: the scan's [reconstruct]
  std::optional<int> resolution;
  std::optional<std::vector<std::string>> formats;
};

// Returns kExitOk, kExitFailed (not a scan folder, no usable stop, a write error), kExitConfig
// (the scan's scan.toml or an option is invalid) or kExitAborted.
int RunReconstructCommand(const ReconstructCommandOptions& options, std::stop_token stop,
                          std::ostream& out, std::ostream& err);

}  // namespace revolve::station
