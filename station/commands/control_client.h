// The client side of the control socket (station/protocol.h) and the pure formatting of what
// `revolve status | watch | list` print.
#pragma once

#include <chrono>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "base/unique_fd.h"

namespace revolve::station {

// Where `revolve` finds revolved: $REVOLVE_SOCKET, else the default [daemon] socket.
std::filesystem::path DefaultControlSocket();

class ControlClient {
 public:
  // Errors: link_down naming the path and what to check (is revolved running? permissions?).
  static Expected<ControlClient> Connect(const std::filesystem::path& socket);

  // Sends one request line.
  Expected<void> Send(const nlohmann::json& request);
  // Sends raw bytes (for tests of malformed input).
  Expected<void> SendRaw(std::string_view bytes);
  // The next line from the daemon as JSON. Errors: timeout, link_down (the daemon closed the
  // connection), protocol (not JSON).
  Expected<nlohmann::json> Receive(std::chrono::milliseconds timeout);
  // Send + Receive.
  Expected<nlohmann::json> Call(const nlohmann::json& request, std::chrono::milliseconds timeout);

  int fd() const { return fd_.get(); }

 private:
  explicit ControlClient(UniqueFd fd) : fd_(std::move(fd)) {}
  UniqueFd fd_;
  std::string buffer_;
};

// "[##########----------]" of `width` characters for progress 0..1.
std::string ProgressBar(double progress, int width);

// "1:05" / "12 s" / "--" for an ETA in seconds (negative or NaN: "--").
std::string FormatEta(double seconds);

// One line for an event or a status (station/scan_state.h's JSON):
//   "capturing   stop 12/36  [######--------]  30%  ETA 0:42  scan 20261121-230105"
std::string FormatProgressLine(const nlohmann::json& event);

// `revolve status`: several lines (state, scan, progress, error, alarm, devices).
std::string FormatStatus(const nlohmann::json& status);

// `revolve list`: a table of the scans.
std::string FormatScanList(const nlohmann::json& scans);

}  // namespace revolve::station
