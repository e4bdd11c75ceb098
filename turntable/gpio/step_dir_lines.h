// The seams of the GPIO backend: the lines (STEP, DIR, ENABLE outputs and the optional home
// switch input) and the clock that times the steps. The real lines are libgpiod
// (libgpiod_lines.h); tests use a recording fake and a virtual clock.
#pragma once

#include <memory>
#include <string>

#include "base/error.h"
#include "turntable/turntable.h"

namespace revolve::turntable::gpio {

enum class Line { kStep, kDir, kEnable };

class StepDirLines {
 public:
  virtual ~StepDirLines() = default;

  // Drives an output to its logical level: `active` true is the asserted level (a STEP pulse,
  // DIR "forward", motor enabled); active-low wiring is applied below this seam. Setting
  // kEnable without an enable line does nothing. Errors: io, no_device.
  virtual Expected<void> Set(Line line, bool active) = 0;

  virtual bool HasEnable() const = 0;
  virtual bool HasHome() const = 0;

  // The home switch's logical level now (true: pressed / at home). False without a switch.
  virtual Expected<bool> HomeActive() = 0;

  // Reads and discards the switch's pending edge events without waiting: true when at least
  // one went toward active since the last call. False without a switch.
  virtual Expected<bool> TakeHomeEdge() = 0;

  virtual std::string Describe() const = 0;
};

// Monotonic time and absolute sleeps for the step emitter.
class StepClock {
 public:
  virtual ~StepClock() = default;
  virtual Clock::time_point Now() = 0;
  // Returns at or after `until` (immediately when it has passed).
  virtual void SleepUntil(Clock::time_point until) = 0;
};

// The steady clock with clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME).
std::shared_ptr<StepClock> SystemStepClock();

}  // namespace revolve::turntable::gpio
