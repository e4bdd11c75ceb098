// Small steady-clock helpers for the station's commands and sessions.
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stop_token>

namespace revolve::station {

// Milliseconds from `start` to now.
inline double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

// The steady-clock time `seconds` from now.
inline std::chrono::steady_clock::time_point DeadlineIn(double seconds) {
  return std::chrono::steady_clock::now() +
         std::chrono::duration_cast<std::chrono::steady_clock::duration>(
             std::chrono::duration<double>(seconds));
}

// Sleeps `ms`, returning early when a stop is requested.
inline void SleepFor(std::stop_token stop, double ms) {
  if (ms <= 0.0) return;
  std::mutex mutex;
  std::condition_variable_any wake;
  std::unique_lock lock(mutex);
  (void)wake.wait_for(lock, stop, std::chrono::duration<double, std::milli>(ms),
                      [] { return false; });
}

}  // namespace revolve::station
