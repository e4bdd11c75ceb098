// `revolve start | abort | status | watch | list` (talk to revolved), `revolve reconstruct
// SCAN_DIR` and `revolve check-config FILE`.
#pragma once

#include <iosfwd>
#include <memory>
#include <optional>
#include <stop_token>

#include <CLI/CLI.hpp>

namespace revolve::station {

class StationCommands {
 public:
  virtual ~StationCommands() = default;
  // After app.parse(): runs the chosen command if it is one of these and returns its exit code;
  // nullopt otherwise.
  virtual std::optional<int> Run(std::stop_token stop, std::ostream& out, std::ostream& err) = 0;
};

// Adds the subcommands to `app`; keep the returned object alive until Run().
std::unique_ptr<StationCommands> AddStationCommands(CLI::App& app);

}  // namespace revolve::station
