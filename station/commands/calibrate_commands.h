// `revolve calibrate [lens | axis | check | board]`: lens and turntable-axis calibration, the
// drift check and the printable board (station/calibrate_command.h, docs/calibration.md).
#pragma once

#include <iosfwd>
#include <memory>
#include <optional>
#include <stop_token>

#include <CLI/CLI.hpp>

namespace revolve::station {

class CalibrateCommands {
 public:
  virtual ~CalibrateCommands() = default;
  // After app.parse(): runs the chosen command if it is one of these and returns its exit code
  // (station/calibrate_command.h); nullopt otherwise. Prompts read `in`.
  virtual std::optional<int> Run(std::stop_token stop, std::istream& in, std::ostream& out,
                                 std::ostream& err) = 0;
};

// Adds `calibrate` and its verbs to `app`. Keep the result alive until Run().
std::unique_ptr<CalibrateCommands> AddCalibrateCommands(CLI::App& app);

}  // namespace revolve::station
