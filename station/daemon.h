// revolved: loads the configuration, brings the devices up, serves the control socket
// (station/protocol.h) and the operator panel, runs one scan at a time on its own thread, and
// talks to systemd (READY, STATUS per stage, WATCHDOG from the main loop).
//
// Threads: the main loop (poll(): socket, clients, panel, signals, wake-ups) and, during a scan,
// one scanning thread. The scanning thread only queues events; the main loop logs them once,
// streams them to watchers and drives the LED. A stop (abort, SIGTERM) is requested from the main
// loop, which stops the motor at once through ScanSession's stop callback.
#pragma once

#include <atomic>
#include <filesystem>
#include <memory>

#include "base/error.h"
#include "station/operator_panel.h"
#include "station/station_config.h"

namespace revolve::station {

struct DaemonHooks {
  // The operator panel's lines; null: opened from [operator] through libgpiod (when configured).
  std::unique_ptr<OperatorLines> panel_lines;
  // Take SIGTERM, SIGINT and SIGHUP through a signalfd. The caller must have blocked them in
  // every thread (revolved's main() does so before any thread starts).
  bool handle_signals = false;
};

class Daemon {
 public:
  // Brings the devices up (a failure is reported in the status, and retried at the next start),
  // opens the panel and binds the socket ([daemon] socket, socket_mode, socket_group).
  // Errors: busy (another revolved serves the socket), io / bad_input (the socket, the scans
  // folder, the socket group), the panel's errors.
  static Expected<std::unique_ptr<Daemon>> Create(StationConfig config, DaemonHooks hooks);
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  // Serves until SIGTERM/SIGINT or RequestShutdown(). A running scan is aborted (motor stopped
  // and disabled at once, manifest "aborted") before it returns. Returns the exit code (0).
  int Run();

  // Thread-safe; Run() returns soon after.
  void RequestShutdown();

  const std::filesystem::path& socket_path() const;
  const std::filesystem::path& scans_dir() const;

  class Impl;

 private:
  explicit Daemon(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// [station] scans_dir made absolute: relative to $STATE_DIRECTORY when set, else to the working
// directory.
std::filesystem::path ResolveScansDir(const StationOptions& options);

}  // namespace revolve::station
