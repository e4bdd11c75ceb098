// Calls from other threads run on one loop thread (the daemon's main loop), so the state that
// loop owns is never shared: the web console's requests take the same path as the control
// socket's. Thread-safe.
#pragma once

#include <chrono>
#include <deque>
#include <functional>
#include <mutex>

#include <nlohmann/json.hpp>

#include "base/error.h"

namespace revolve::station {

class LoopCalls {
 public:
  using Call = std::function<Expected<nlohmann::json>()>;

  // `wake` makes the loop call RunPending() soon (it must be thread-safe).
  explicit LoopCalls(std::function<void()> wake) : wake_(std::move(wake)) {}

  // Any thread but the loop's: queues `call`, wakes the loop and waits up to `timeout` for the
  // result. Errors: timeout (the loop did not get to it; it still runs later), busy after
  // Close().
  Expected<nlohmann::json> Run(Call call, std::chrono::milliseconds timeout);

  // The loop thread: runs every queued call.
  void RunPending();

  // From now on Run() fails with busy at once; queued calls are dropped (their callers get busy).
  void Close();

 private:
  std::function<void()> wake_;
  std::mutex mutex_;
  std::deque<std::function<void()>> pending_;
  bool closed_ = false;
};

}  // namespace revolve::station
