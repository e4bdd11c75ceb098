#include "station/event_hub.h"

#include <algorithm>

namespace revolve::station {

EventHub::EventHub(std::size_t history) : capacity_(std::max<std::size_t>(history, 1)) {}

std::uint64_t EventHub::Publish(const ScanEvent& event) {
  HubEvent entry;
  std::vector<std::function<void(const HubEvent&)>> subscribers;
  {
    std::lock_guard lock(mutex_);
    entry.id = ++last_id_;
    entry.event = event;
    history_.push_back(entry);
    if (history_.size() > capacity_) history_.pop_front();
    subscribers = subscribers_;
  }
  changed_.notify_all();
  for (const auto& subscriber : subscribers) subscriber(entry);
  return entry.id;
}

void EventHub::Subscribe(std::function<void(const HubEvent&)> subscriber) {
  std::lock_guard lock(mutex_);
  subscribers_.push_back(std::move(subscriber));
}

EventHub::Batch EventHub::Wait(std::uint64_t after_id, std::chrono::milliseconds timeout) const {
  std::unique_lock lock(mutex_);
  changed_.wait_for(lock, timeout, [&] { return closed_ || last_id_ > after_id; });
  Batch batch;
  batch.closed = closed_;
  if (last_id_ <= after_id) return batch;
  // The history holds ids [front, last_id_]; a reader past the front missed some.
  const std::uint64_t front = history_.empty() ? last_id_ + 1 : history_.front().id;
  batch.gap = after_id + 1 < front;
  for (const HubEvent& e : history_) {
    if (e.id > after_id) batch.events.push_back(e);
  }
  return batch;
}

std::uint64_t EventHub::last_id() const {
  std::lock_guard lock(mutex_);
  return last_id_;
}

void EventHub::Close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  changed_.notify_all();
}

}  // namespace revolve::station
