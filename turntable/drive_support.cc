#include "turntable/drive_support.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <fmt/format.h>

namespace revolve::turntable {

Error BusyError() {
  return Error{ErrorCode::kBusy, "the turntable is already moving (another call runs)"};
}

Expected<void> CheckTargetAngle(double angle_deg) {
  if (!std::isfinite(angle_deg) || std::fabs(angle_deg) > 1e6) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("target angle {} deg is not a usable number", angle_deg));
  }
  return {};
}

IdlePowerDown::IdlePowerDown(double idle_s, std::mutex& op_mutex, std::function<bool()> powered,
                             std::function<void()> power_down)
    : idle_(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(idle_s))),
      op_mutex_(op_mutex),
      powered_(std::move(powered)),
      power_down_(std::move(power_down)),
      last_activity_(Clock::now()) {
  if (idle_s > 0.0) thread_ = std::jthread([this](std::stop_token stop) { Watch(stop); });
}

IdlePowerDown::~IdlePowerDown() { Shutdown(); }

void IdlePowerDown::Shutdown() {
  thread_.request_stop();
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void IdlePowerDown::Touch() {
  {
    std::lock_guard lock(mutex_);
    last_activity_ = Clock::now();
  }
  wake_.notify_all();
}

void IdlePowerDown::Watch(std::stop_token stop) {
  std::unique_lock lock(mutex_);
  while (!stop.stop_requested()) {
    lock.unlock();
    const bool powered = powered_();
    lock.lock();
    if (!powered) {
      wake_.wait_for(lock, stop, std::chrono::milliseconds(200), [] { return false; });
      continue;
    }
    const Clock::time_point due = last_activity_ + idle_;
    if (Clock::now() < due) {
      wake_.wait_until(lock, stop, due, [] { return false; });
      continue;
    }
    lock.unlock();
    std::unique_lock op(op_mutex_, std::try_to_lock);
    lock.lock();
    if (op.owns_lock() && Clock::now() >= last_activity_ + idle_) {
      lock.unlock();
      power_down_();
      lock.lock();
      last_activity_ = Clock::now();
    } else {
      // A move runs or just ran: look again shortly.
      last_activity_ =
          std::max(last_activity_, Clock::now() - idle_ + std::chrono::milliseconds(200));
    }
  }
}

}  // namespace revolve::turntable
