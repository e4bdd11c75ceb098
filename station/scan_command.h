// `revolve scan`: one scan on the configured rig, with a progress line per stop and a summary.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <optional>
#include <stop_token>
#include <string>

namespace revolve::station {

// Exit codes of the revolve commands.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailed = 1;        // the scan started but failed; its folder says why
inline constexpr int kExitUsage = 2;         // bad command line
inline constexpr int kExitUnavailable = 69;  // EX_UNAVAILABLE: revolved is not reachable
inline constexpr int kExitBusy = 75;    // EX_TEMPFAIL: revolved refused the start (a scan runs)
inline constexpr int kExitConfig = 78;  // EX_CONFIG: the configuration is missing or invalid
inline constexpr int kExitAborted = 130;

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
