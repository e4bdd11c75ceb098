// `revolve scan`: one scan on the configured rig, with a progress line per stop and a summary.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <optional>
#include <stop_token>
#include <string>

#include "station/exit_codes.h"

namespace revolve::station {

struct ScanCommandOptions {
  std::optional<std::filesystem::path> config;  // empty: the embedded default (simulated rig)
  std::optional<std::filesystem::path> out;     // empty: scans/<id> in the working directory
  std::optional<std::string> recipe;            // empty: [station] recipe
};

// Runs the scan; progress and the summary go to `out`, errors to `err`. A bad config is
// reported before anything is created. Returns one of the exit codes above.
int RunScanCommand(const ScanCommandOptions& options, std::stop_token stop, std::ostream& out,
                   std::ostream& err);

}  // namespace revolve::station
