// Pieces shared by the turntables that drive real motors (modbus, gpio): the checks every
// Home()/MoveTo() makes first, and the idle power-down watcher.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <stop_token>
#include <thread>

#include "base/error.h"
#include "turntable/turntable.h"

namespace revolve::turntable {

// busy: another Home()/MoveTo() holds the drive.
Error BusyError();

// bad_input when `angle_deg` is not a finite number within +-1e6 deg.
Expected<void> CheckTargetAngle(double angle_deg);

// Powers the motor down once the table has been idle (no Touch()) for `idle_s` seconds while it
// is powered. A watcher thread checks `powered` (true while the motor is on and no move runs;
// polled every 200 ms while false), then, holding `op_mutex` (taken with try_lock: a running
// Home()/MoveTo() defers the power-down) and only if no Touch() came in the meantime, calls
// `power_down`, which removes motor power and logs. With idle_s <= 0 no thread runs.
// `powered` and `power_down` run on the watcher thread with none of its locks held. Touch() may be
// called with op_mutex held, from any thread.
class IdlePowerDown {
 public:
  IdlePowerDown(double idle_s, std::mutex& op_mutex, std::function<bool()> powered,
                std::function<void()> power_down);
  // Shutdown().
  ~IdlePowerDown();
  IdlePowerDown(const IdlePowerDown&) = delete;
  IdlePowerDown& operator=(const IdlePowerDown&) = delete;

  // Records activity now: the idle time starts again.
  void Touch();
  // Stops and joins the watcher; no callback runs after it returns. Idempotent.
  void Shutdown();

 private:
  void Watch(std::stop_token stop);

  const Clock::duration idle_;
  std::mutex& op_mutex_;
  const std::function<bool()> powered_;
  const std::function<void()> power_down_;

  std::mutex mutex_;  // guards last_activity_
  Clock::time_point last_activity_;
  std::condition_variable_any wake_;
  std::jthread thread_;  // last: started once the fields above exist
};

}  // namespace revolve::turntable
