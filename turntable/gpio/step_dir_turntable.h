// A turntable driven by a step/dir stepper driver through GPIO lines. Open loop: the position is
// the count of emitted steps (exact, but blind to lost steps), which State() says with
// open_loop = true.
//
// A move plans its step times with PlanSteps() (trapezoid at speed_deg_per_s and
// acceleration_deg_per_s2 converted to steps, capped at max_step_rate_hz), then emits them:
// DIR is set and held dir_setup_us before the first STEP edge; ENABLE is asserted
// enable_settle_ms before it when the motor was off; each STEP pulse is pulse_us high. Stop(),
// Disable() and the deadline end the emission after the current step; the count stays exact.
//
// Home(): with a home switch, the plate turns at home_speed_deg_per_s in home_direction (up to
// home_max_deg) until the switch's edge; the level is confirmed after home_debounce_ms (a bounce
// does not count) and that spot becomes 0 deg. Without a switch, the nearest whole revolution of
// the count becomes 0 deg.
//
// Idle power-down: with idle_disable_s > 0 ENABLE is released after that long without motion
// and asserted again by the next move.
//
// Thread-safety: every member may be called from any thread; one Home()/MoveTo() at a time.
#pragma once

#include <atomic>
#include <memory>
#include <mutex>

#include "base/sim_plate.h"
#include "turntable/drive_support.h"
#include "turntable/gpio/gpio_options.h"
#include "turntable/gpio/step_dir_lines.h"
#include "turntable/turntable.h"

namespace revolve::turntable::gpio {

class StepDirTurntable final : public Turntable {
 public:
  // Contract: `options` parsed by ParseGpioOptions; `lines` requested (ENABLE inactive). `plate`
  // may be null. With `disable_at_end` the destructor releases ENABLE.
  StepDirTurntable(GpioOptions options, std::unique_ptr<StepDirLines> lines,
                   std::shared_ptr<StepClock> clock, std::shared_ptr<SimulatedPlate> plate,
                   bool disable_at_end);
  ~StepDirTurntable() override;

  Expected<void> Home(Clock::time_point deadline) override;
  Expected<void> MoveTo(double angle_deg, Clock::time_point deadline) override;
  Expected<TurntableState> State() override;
  void Stop() noexcept override;
  Expected<void> Disable() override;
  std::string Describe() const override;

  // Steps counted from the plate's 0 deg (for diagnostics and tests).
  std::int64_t position_steps() const { return position_steps_.load(); }
  // Steps emitted more than 1 ms late since creation (a sign of a loaded CPU).
  int overruns() const { return overruns_.load(); }

 private:
  enum class EmitEnd { kDone, kAborted, kDeadline, kHome, kError };
  struct EmitResult {
    EmitEnd end = EmitEnd::kDone;
    Error error;  // kError
  };

  // Emits `delta` steps (signed). Requires op_mutex_ held.
  EmitResult Emit(std::int64_t delta, double speed_deg_per_s, Clock::time_point deadline,
                  bool stop_at_home_edge);
  Expected<void> EnsureEnabled();
  Expected<void> HomeWithSwitch(Clock::time_point deadline);
  double AngleOf(std::int64_t steps) const;
  // Releases ENABLE after idle_disable_s without motion (IdlePowerDown's callback).
  void PowerDownIdle();

  const GpioOptions options_;
  const std::unique_ptr<StepDirLines> lines_;
  const std::shared_ptr<StepClock> clock_;
  const std::shared_ptr<SimulatedPlate> plate_;
  const bool disable_at_end_;

  std::mutex op_mutex_;
  std::atomic<bool> abort_{false};
  std::atomic<std::int64_t> position_steps_{0};
  std::atomic<std::int64_t> target_steps_{0};
  std::atomic<bool> moving_{false};
  std::atomic<int> overruns_{0};

  mutable std::mutex mutex_;  // guards the fields below
  bool enabled_ = false;
  bool explicitly_disabled_ = false;
  bool homed_ = false;
  bool dir_forward_ = true;
  bool dir_known_ = false;

  IdlePowerDown idle_;  // last: its thread uses the fields above
};

}  // namespace revolve::turntable::gpio
