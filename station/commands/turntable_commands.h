// `revolve simulate-drive` (a Modbus drive simulator for tests and for trying a config without
// hardware) and `revolve turntable (home | move DEG | status)` (bring-up on a real rig).
#pragma once

#include <iosfwd>
#include <memory>
#include <optional>
#include <stop_token>

#include <CLI/CLI.hpp>

namespace revolve::station {

class TurntableCommands {
 public:
  virtual ~TurntableCommands() = default;
  // After app.parse(): runs the chosen command if it is one of these and returns its exit code
  // (kExitOk, kExitFailed, kExitConfig, kExitAborted; see scan_command.h); nullopt otherwise.
  virtual std::optional<int> Run(std::stop_token stop, std::ostream& out, std::ostream& err) = 0;
};

// Adds the subcommands to `app`. The returned object holds their parsed options: keep it alive
// until Run().
std::unique_ptr<TurntableCommands> AddTurntableCommands(CLI::App& app);

}  // namespace revolve::station
