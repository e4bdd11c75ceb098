// The commands that talk to revolved over its control socket (`revolve start | abort | status |
// watch | list`) and `revolve check-config`. Each returns an exit code of scan_command.h.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <optional>
#include <stop_token>
#include <string>

namespace revolve::station {

struct ClientOptions {
  std::optional<std::filesystem::path> socket;  // default: --config's [daemon] socket, else
                                                // DefaultControlSocket()
  std::optional<std::filesystem::path> config;  // a revolved config to take the socket from
  bool json = false;                            // print the daemon's JSON lines as they come
  bool tty = false;  // redraw one progress line instead of printing a line per event
};

// Sends start; with `watch`, follows the scan to its end (exit code by its result: kExitOk,
// kExitFailed, kExitAborted). A refused start (a scan runs) is kExitBusy.
int RunStartCommand(const ClientOptions& options, const std::optional<std::string>& recipe,
                    const std::optional<std::string>& resume, bool watch, std::stop_token stop,
                    std::ostream& out, std::ostream& err);
int RunAbortCommand(const ClientOptions& options, std::ostream& out, std::ostream& err);
int RunStatusCommand(const ClientOptions& options, std::ostream& out, std::ostream& err);
// Prints the status, then every event until the current scan ends (with `follow`: until
// interrupted). Exit code by the scan's result (kExitOk when idle).
int RunWatchCommand(const ClientOptions& options, bool follow, std::stop_token stop,
                    std::ostream& out, std::ostream& err);
int RunListCommand(const ClientOptions& options, std::ostream& out, std::ostream& err);

// Validates FILE (every section, every recipe) and prints the effective configuration.
int RunCheckConfigCommand(const std::filesystem::path& file, std::ostream& out, std::ostream& err);

}  // namespace revolve::station
