// systemd's service notifications (sd_notify): READY, STATUS, WATCHDOG, STOPPING. Without
// systemd (no NOTIFY_SOCKET) or in a build without libsystemd every call does nothing.
#pragma once

#include <chrono>
#include <optional>
#include <string_view>

namespace revolve::station {

class Notifier {
 public:
  // Reads WATCHDOG_USEC / WATCHDOG_PID (sd_watchdog_enabled).
  Notifier();

  // The interval systemd expects WATCHDOG=1 within (WatchdogSec=), when enabled for this process.
  std::optional<std::chrono::microseconds> watchdog_interval() const { return watchdog_; }

  void Ready(std::string_view status) const;     // READY=1 + STATUS=
  void Status(std::string_view status) const;    // STATUS=
  void Watchdog() const;                         // WATCHDOG=1
  void Stopping(std::string_view status) const;  // STOPPING=1 + STATUS=

 private:
  void Send(std::string_view message) const;
  std::optional<std::chrono::microseconds> watchdog_;
};

}  // namespace revolve::station
