// SIGINT and SIGTERM as a stop request for a command-line run (`revolve scan`, `reconstruct`,
// ...): the signals are blocked in every thread and read from a signalfd by a watcher thread, so
// no work happens in a signal handler.
#pragma once

#include <stop_token>
#include <thread>

#include "base/unique_fd.h"

namespace revolve::station {

class SignalStop {
 public:
  // Blocks SIGINT and SIGTERM in the calling thread (threads started after inherit the mask:
  // construct this before any other thread) and starts the watcher. When the signalfd or the
  // eventfd cannot be made, the signals are left as they were (they end the process as usual).
  SignalStop();
  // Wakes the watcher and joins it at once (no polling period to wait out at exit). The signals
  // stay blocked: one arriving after this stays pending until the process ends.
  ~SignalStop();
  SignalStop(const SignalStop&) = delete;
  SignalStop& operator=(const SignalStop&) = delete;

  // Requested once SIGINT or SIGTERM arrived.
  std::stop_token token() const { return source_.get_token(); }

 private:
  std::stop_source source_;
  UniqueFd signal_fd_;
  UniqueFd wake_fd_;
  std::jthread watcher_;
};

}  // namespace revolve::station
