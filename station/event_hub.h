// The station's event stream, published once and read by every listener: the control socket's
// watchers (station/protocol.h, through Subscribe) and the web console's event streams
// (station/web_server.h, through Wait). Each published ScanEvent gets an id, 1, 2, ... for the
// daemon's life (ScanEvent::seq restarts with each scan), so a reader that reconnects with the
// last id it saw gets exactly what it missed, as long as it is still in the history.
//
// Thread-safe. Publish never blocks on a reader: subscribers are called in the publishing thread
// (keep them short: queue and return), and Wait readers copy from the history under the lock.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <vector>

#include "station/scan_state.h"

namespace revolve::station {

struct HubEvent {
  std::uint64_t id = 0;
  ScanEvent event;
};

class EventHub {
 public:
  // Keeps the last `history` events (at least 1) for readers that fall behind or reconnect.
  explicit EventHub(std::size_t history = 4096);

  // Adds `event` with the next id, calls the subscribers, wakes the waiting readers.
  // Returns the id.
  std::uint64_t Publish(const ScanEvent& event);

  // Called (in the publishing thread) for every event published from now on.
  void Subscribe(std::function<void(const HubEvent&)> subscriber);

  struct Batch {
    std::vector<HubEvent> events;  // ids after `after_id`, in order
    // True when events after `after_id` were dropped from the history before they were read:
    // the reader should take a fresh status.
    bool gap = false;
    bool closed = false;
  };
  // The events after `after_id`, waiting up to `timeout` for the first one. Returns at once
  // when there are some, or when the hub is closed.
  Batch Wait(std::uint64_t after_id, std::chrono::milliseconds timeout) const;

  // The id of the last event published (0: none yet).
  std::uint64_t last_id() const;

  // Wakes every waiting reader; Wait returns closed from now on. Publish still works.
  void Close();

 private:
  std::size_t capacity_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  std::deque<HubEvent> history_;
  std::uint64_t last_id_ = 0;
  bool closed_ = false;
  std::vector<std::function<void(const HubEvent&)>> subscribers_;
};

}  // namespace revolve::station
