#include "station/notify.h"

#include <cstdint>
#include <string>

#ifdef REVOLVE_HAVE_SYSTEMD
#include <systemd/sd-daemon.h>
#endif

namespace revolve::station {

Notifier::Notifier() {
#ifdef REVOLVE_HAVE_SYSTEMD
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) watchdog_ = std::chrono::microseconds(usec);
#endif
}

void Notifier::Send(std::string_view message) const {
#ifdef REVOLVE_HAVE_SYSTEMD
  const std::string text(message);
  (void)sd_notify(0, text.c_str());
#else
  (void)message;
#endif
}

void Notifier::Ready(std::string_view status) const {
  Send("READY=1\nSTATUS=" + std::string(status));
}

void Notifier::Status(std::string_view status) const { Send("STATUS=" + std::string(status)); }

void Notifier::Watchdog() const { Send("WATCHDOG=1"); }

void Notifier::Stopping(std::string_view status) const {
  Send("STOPPING=1\nSTATUS=" + std::string(status));
}

}  // namespace revolve::station
