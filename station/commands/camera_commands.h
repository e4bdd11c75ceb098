// `revolve camera list` (the cameras this machine has) and `revolve camera snapshot FILE`
// (one frame from the configured camera, optionally with its silhouette): camera bring-up.
#pragma once

#include <iosfwd>
#include <memory>
#include <optional>
#include <stop_token>

#include <CLI/CLI.hpp>

namespace revolve::station {

class CameraCommands {
 public:
  virtual ~CameraCommands() = default;
  // After app.parse(): runs the chosen command if it is one of these and returns its exit code
  // (kExitOk, kExitFailed, kExitConfig; see scan_command.h); nullopt otherwise.
  virtual std::optional<int> Run(std::stop_token stop, std::ostream& out, std::ostream& err) = 0;
};

// Adds `camera list` and `camera snapshot` to `app`. Keep the result alive until Run().
std::unique_ptr<CameraCommands> AddCameraCommands(CLI::App& app);

}  // namespace revolve::station
