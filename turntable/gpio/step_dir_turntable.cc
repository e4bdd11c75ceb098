#include "turntable/gpio/step_dir_turntable.h"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <cmath>

#include <fmt/format.h>

#include "base/log.h"
#include "turntable/gpio/step_plan.h"

namespace revolve::turntable::gpio {
namespace {

Clock::duration Us(double us) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::micro>(us));
}

class SystemClock final : public StepClock {
 public:
  Clock::time_point Now() override { return Clock::now(); }
  void SleepUntil(Clock::time_point until) override {
    // steady_clock is CLOCK_MONOTONIC on Linux.
    const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(until.time_since_epoch());
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(ns.count() / 1'000'000'000);
    ts.tv_nsec = static_cast<long>(ns.count() % 1'000'000'000);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
  }
};

// Runs the calling thread under SCHED_FIFO while in scope, when asked and allowed.
class RealtimeScope {
 public:
  explicit RealtimeScope(bool wanted) {
    if (!wanted) return;
    if (pthread_getschedparam(pthread_self(), &old_policy_, &old_param_) != 0) return;
    sched_param param{};
    param.sched_priority = 50;
    active_ = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
    if (!active_) {
      Logger("turntable")
          ->warn(
              "realtime = true but SCHED_FIFO is not allowed (set LimitRTPRIO= in the service, or "
              "grant CAP_SYS_NICE): step timing may jitter");
    }
  }
  ~RealtimeScope() {
    if (active_) pthread_setschedparam(pthread_self(), old_policy_, &old_param_);
  }
  RealtimeScope(const RealtimeScope&) = delete;
  RealtimeScope& operator=(const RealtimeScope&) = delete;

 private:
  bool active_ = false;
  int old_policy_ = SCHED_OTHER;
  sched_param old_param_{};
};

}  // namespace

std::shared_ptr<StepClock> SystemStepClock() { return std::make_shared<SystemClock>(); }

StepDirTurntable::StepDirTurntable(GpioOptions options, std::unique_ptr<StepDirLines> lines,
                                   std::shared_ptr<StepClock> clock,
                                   std::shared_ptr<SimulatedPlate> plate, bool disable_at_end)
    : options_(std::move(options)),
      lines_(std::move(lines)),
      clock_(std::move(clock)),
      plate_(std::move(plate)),
      disable_at_end_(disable_at_end),
      idle_(
          lines_->HasEnable() ? options_.idle_disable_s : 0.0, op_mutex_,
          [this] {
            std::lock_guard lock(mutex_);
            return enabled_;
          },
          [this] { PowerDownIdle(); }) {}

StepDirTurntable::~StepDirTurntable() {
  idle_.Shutdown();
  abort_.store(true);
  std::lock_guard op(op_mutex_);
  if (disable_at_end_) (void)lines_->Set(Line::kEnable, false);
}

std::string StepDirTurntable::Describe() const {
  return fmt::format(
      "gpio step/dir (open loop) {}: {} full steps x {} microsteps x gear {} = {:.0f} steps/rev, "
      "{} deg/s",
      lines_->Describe(), options_.full_steps_per_rev, options_.microsteps, options_.gear_ratio,
      options_.StepsPerPlateRev(), options_.speed_deg_per_s);
}

double StepDirTurntable::AngleOf(std::int64_t steps) const {
  return (options_.reverse ? -1.0 : 1.0) * static_cast<double>(steps) /
         options_.StepsPerPlateRev() * 360.0;
}

Expected<void> StepDirTurntable::EnsureEnabled() {
  {
    std::lock_guard lock(mutex_);
    if (enabled_) return {};
  }
  if (Expected<void> on = lines_->Set(Line::kEnable, true); !on) return on;
  {
    std::lock_guard lock(mutex_);
    enabled_ = true;
  }
  if (lines_->HasEnable()) {
    clock_->SleepUntil(clock_->Now() + Us(options_.enable_settle_ms * 1000.0));
  }
  return {};
}

StepDirTurntable::EmitResult StepDirTurntable::Emit(std::int64_t delta, double speed_deg_per_s,
                                                    Clock::time_point deadline,
                                                    bool stop_at_home_edge) {
  EmitResult result;
  if (delta == 0) return result;
  // Counts are motor steps (the config's direction is applied when converting angles); logical
  // DIR "active" turns the motor forward.
  const bool forward = delta > 0;
  bool set_dir = false;
  {
    std::lock_guard lock(mutex_);
    set_dir = !dir_known_ || dir_forward_ != forward;
  }
  if (set_dir) {
    if (Expected<void> ok = lines_->Set(Line::kDir, forward); !ok) {
      return EmitResult{EmitEnd::kError, ok.error()};
    }
    std::lock_guard lock(mutex_);
    dir_known_ = true;
    dir_forward_ = forward;
  }
  const Clock::time_point dir_ready = clock_->Now() + Us(options_.dir_setup_us);
  if (Expected<void> on = EnsureEnabled(); !on) return EmitResult{EmitEnd::kError, on.error()};
  clock_->SleepUntil(dir_ready);

  const double steps_per_deg = options_.StepsPerPlateRev() / 360.0;
  const double rate_hz = std::min(speed_deg_per_s * steps_per_deg, options_.max_step_rate_hz);
  const double accel_hz_s = options_.acceleration_deg_per_s2 * steps_per_deg;
  const StepPlan plan = PlanSteps(std::llabs(delta), rate_hz, accel_hz_s);
  const std::int64_t sign = delta > 0 ? 1 : -1;
  const auto late = std::chrono::milliseconds(1);

  RealtimeScope realtime(options_.realtime);
  moving_.store(true);
  if (plate_) plate_->moving.store(true);
  const Clock::time_point start = clock_->Now();
  for (std::int64_t due_ns : plan.step_ns) {
    const Clock::time_point due = start + std::chrono::nanoseconds(due_ns);
    if (abort_.load()) {
      result.end = EmitEnd::kAborted;
      break;
    }
    if (due > deadline) {
      result.end = EmitEnd::kDeadline;
      break;
    }
    clock_->SleepUntil(due);
    if (clock_->Now() - due > late) overruns_.fetch_add(1);
    if (Expected<void> high = lines_->Set(Line::kStep, true); !high) {
      result = EmitResult{EmitEnd::kError, high.error()};
      break;
    }
    clock_->SleepUntil(clock_->Now() + Us(options_.pulse_us));
    if (Expected<void> low = lines_->Set(Line::kStep, false); !low) {
      result = EmitResult{EmitEnd::kError, low.error()};
      break;
    }
    const std::int64_t position = position_steps_.fetch_add(sign) + sign;
    if (plate_) plate_->angle_deg.store(AngleOf(position));
    if (stop_at_home_edge) {
      Expected<bool> edge = lines_->TakeHomeEdge();
      if (!edge) {
        result = EmitResult{EmitEnd::kError, edge.error()};
        break;
      }
      if (*edge) {
        result.end = EmitEnd::kHome;
        break;
      }
    }
  }
  moving_.store(false);
  if (plate_) plate_->moving.store(false);
  return result;
}

Expected<void> StepDirTurntable::HomeWithSwitch(Clock::time_point deadline) {
  // The search direction is given in plate terms; counts are motor steps.
  const std::int64_t direction =
      std::int64_t{options_.home_reverse ? -1 : 1} * (options_.reverse ? -1 : 1);
  const auto debounce = Us(options_.home_debounce_ms * 1000.0);
  const auto search_steps = static_cast<std::int64_t>(
      std::ceil(options_.home_max_deg / 360.0 * options_.StepsPerPlateRev()));
  // Starting on the switch: leave it first, so the edge is found from a known side.
  Expected<bool> active = lines_->HomeActive();
  if (!active) return std::unexpected(active.error());
  if (*active) {
    const auto away =
        static_cast<std::int64_t>(std::ceil(10.0 / 360.0 * options_.StepsPerPlateRev()));
    EmitResult left = Emit(-direction * away, options_.home_speed_deg_per_s, deadline, false);
    if (left.end == EmitEnd::kError) return std::unexpected(left.error);
  }
  (void)lines_->TakeHomeEdge();  // forget edges from before the search
  std::int64_t searched = 0;
  while (searched < search_steps) {
    const std::int64_t before = position_steps_.load();
    EmitResult r =
        Emit(direction * (search_steps - searched), options_.home_speed_deg_per_s, deadline, true);
    searched += std::llabs(position_steps_.load() - before);
    switch (r.end) {
      case EmitEnd::kError:
        return std::unexpected(r.error);
      case EmitEnd::kAborted:
        return MakeError(ErrorCode::kAborted, "homing was stopped on request");
      case EmitEnd::kDeadline:
        return MakeError(ErrorCode::kTimeout,
                         "homing did not find the switch by its deadline: lower home_max_deg or "
                         "raise home_speed_deg_per_s / scan.move_timeout_s");
      case EmitEnd::kDone:
        break;
      case EmitEnd::kHome: {
        clock_->SleepUntil(clock_->Now() + debounce);
        Expected<bool> confirmed = lines_->HomeActive();
        if (!confirmed) return std::unexpected(confirmed.error());
        if (*confirmed) {
          (void)lines_->TakeHomeEdge();
          position_steps_.store(0);
          target_steps_.store(0);
          return {};
        }
        Logger("turntable")->debug("home switch bounced at step {}; searching on", searched);
        break;
      }
    }
  }
  return MakeError(ErrorCode::kNotFound,
                   fmt::format("the home switch did not trigger within {} deg: check its wiring "
                               "(line {}), home_active_low and home_direction",
                               options_.home_max_deg, options_.home.Describe()));
}

Expected<void> StepDirTurntable::Home(Clock::time_point deadline) {
  std::unique_lock op(op_mutex_, std::try_to_lock);
  if (!op.owns_lock()) return std::unexpected(BusyError());
  abort_.store(false);
  idle_.Touch();
  {
    std::lock_guard lock(mutex_);
    explicitly_disabled_ = false;
  }
  auto fail = [](Error error) { return std::unexpected(WithContext(std::move(error), "homing")); };
  if (lines_->HasHome()) {
    if (Expected<void> homed = HomeWithSwitch(deadline); !homed) return fail(homed.error());
  } else {
    const double per_rev = options_.StepsPerPlateRev();
    const std::int64_t position = position_steps_.load();
    const auto target = static_cast<std::int64_t>(
        std::llround(std::round(static_cast<double>(position) / per_rev) * per_rev));
    EmitResult r = Emit(target - position, options_.speed_deg_per_s, deadline, false);
    if (r.end == EmitEnd::kError) return fail(r.error);
    if (r.end == EmitEnd::kAborted) return fail(Error{ErrorCode::kAborted, "stopped on request"});
    if (r.end == EmitEnd::kDeadline) {
      return fail(
          Error{ErrorCode::kTimeout, "the move to the nearest whole turn missed its deadline"});
    }
    position_steps_.fetch_sub(target);
    target_steps_.store(0);
  }
  if (plate_) plate_->angle_deg.store(AngleOf(position_steps_.load()));
  {
    std::lock_guard lock(mutex_);
    homed_ = true;
  }
  idle_.Touch();
  return {};
}

Expected<void> StepDirTurntable::MoveTo(double angle_deg, Clock::time_point deadline) {
  std::unique_lock op(op_mutex_, std::try_to_lock);
  if (!op.owns_lock()) return std::unexpected(BusyError());
  if (Expected<void> usable = CheckTargetAngle(angle_deg); !usable) return usable;
  {
    std::lock_guard lock(mutex_);
    if (explicitly_disabled_) {
      return MakeError(ErrorCode::kBadInput,
                       "the motor is disabled (ENABLE released): home the table to enable it");
    }
  }
  abort_.store(false);
  idle_.Touch();
  const auto target = static_cast<std::int64_t>(std::llround(
      (options_.reverse ? -1.0 : 1.0) * angle_deg / 360.0 * options_.StepsPerPlateRev()));
  target_steps_.store(target);
  const EmitResult r =
      Emit(target - position_steps_.load(), options_.speed_deg_per_s, deadline, false);
  idle_.Touch();
  auto context = [angle_deg](ErrorCode code, std::string message) {
    return std::unexpected(WithContext(Error{code, std::move(message)},
                                       fmt::format("moving to {:.3f} deg", angle_deg)));
  };
  switch (r.end) {
    case EmitEnd::kDone:
    case EmitEnd::kHome:
      return {};
    case EmitEnd::kAborted:
      return context(ErrorCode::kAborted,
                     fmt::format("stopped on request at {:.3f} deg", AngleOf(position_steps_)));
    case EmitEnd::kDeadline:
      return context(ErrorCode::kTimeout,
                     fmt::format("the move would end after its deadline; stopped at {:.3f} deg: "
                                 "raise speed_deg_per_s or scan.move_timeout_s",
                                 AngleOf(position_steps_)));
    case EmitEnd::kError:
      return std::unexpected(WithContext(r.error, fmt::format("moving to {:.3f} deg", angle_deg)));
  }
  return {};
}

Expected<TurntableState> StepDirTurntable::State() {
  TurntableState state;
  const std::int64_t position = position_steps_.load();
  state.angle_deg = AngleOf(position);
  state.moving = moving_.load();
  state.in_position = !state.moving && position == target_steps_.load();
  state.open_loop = true;
  std::lock_guard lock(mutex_);
  state.enabled = enabled_ || !lines_->HasEnable();
  state.homed = homed_;
  return state;
}

void StepDirTurntable::Stop() noexcept { abort_.store(true); }

Expected<void> StepDirTurntable::Disable() {
  abort_.store(true);
  std::lock_guard op(op_mutex_);  // the emitter ends after its current step
  Expected<void> off = lines_->Set(Line::kEnable, false);
  std::lock_guard lock(mutex_);
  explicitly_disabled_ = true;
  if (!off) return std::unexpected(WithContext(off.error(), "releasing ENABLE"));
  enabled_ = false;
  return {};
}

void StepDirTurntable::PowerDownIdle() {
  std::lock_guard lock(mutex_);
  if (!enabled_) return;
  Logger("turntable")
      ->info("idle for {} s: releasing ENABLE (the next move asserts it)", options_.idle_disable_s);
  if (Expected<void> off = lines_->Set(Line::kEnable, false); !off) {
    Logger("turntable")->warn("idle power-down failed: {}", off.error().message);
  }
  enabled_ = false;
}

}  // namespace revolve::turntable::gpio
