#include "turntable/mock/mock_turntable.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "base/log.h"

namespace revolve::turntable {
namespace {

// How often (real time) a running move refreshes the plate angle.
constexpr auto kPlateRefresh = std::chrono::milliseconds(1);

std::string_view FaultName(MockFault::Kind kind) {
  switch (kind) {
    case MockFault::Kind::kStall:
      return "stall";
    case MockFault::Kind::kAlarm:
      return "alarm";
    case MockFault::Kind::kLinkDown:
      return "link down";
  }
  return "?";
}

// Clears a flag when it goes out of scope (the caller holds the mutex guarding it then).
class BusyScope {
 public:
  explicit BusyScope(bool& busy) : busy_(busy) { busy_ = true; }
  ~BusyScope() { busy_ = false; }
  BusyScope(const BusyScope&) = delete;
  BusyScope& operator=(const BusyScope&) = delete;

 private:
  bool& busy_;
};

}  // namespace

Expected<void> ValidateMockOptions(const MockOptions& options) {
  auto bad = [](std::string what) {
    return MakeError(ErrorCode::kBadInput, "mock turntable options: " + std::move(what));
  };
  if (!(options.speed_deg_per_s > 0.0 && options.speed_deg_per_s <= kMockMaxSpeedDegPerS)) {
    return bad(fmt::format("speed_deg_per_s {} is out of range (0, {}]", options.speed_deg_per_s,
                           kMockMaxSpeedDegPerS));
  }
  if (!(options.acceleration_deg_per_s2 > 0.0 &&
        options.acceleration_deg_per_s2 <= kMockMaxAccelerationDegPerS2)) {
    return bad(fmt::format("acceleration_deg_per_s2 {} is out of range (0, {}]",
                           options.acceleration_deg_per_s2, kMockMaxAccelerationDegPerS2));
  }
  if (!(options.settle_ms >= 0.0 && options.settle_ms <= kMockMaxSettleMs)) {
    return bad(
        fmt::format("settle_ms {} is out of range [0, {}]", options.settle_ms, kMockMaxSettleMs));
  }
  if (!(options.time_scale > 0.0 && options.time_scale <= kMockMaxTimeScale)) {
    return bad(fmt::format("time_scale {} is out of range (0, {}]", options.time_scale,
                           kMockMaxTimeScale));
  }
  if (!(options.tolerance_deg >= 0.0 && options.tolerance_deg <= kMockMaxToleranceDeg)) {
    return bad(fmt::format("tolerance_deg {} is out of range [0, {}]", options.tolerance_deg,
                           kMockMaxToleranceDeg));
  }
  for (const MockFault& fault : options.faults) {
    if (fault.move_index < 0 || fault.count < 1 ||
        !(fault.at_fraction >= 0.0 && fault.at_fraction <= 1.0)) {
      return bad(
          fmt::format("fault ({}, move_index {}, count {}, at_fraction {}): need "
                      "move_index >= 0, count >= 1, at_fraction in [0, 1]",
                      FaultName(fault.kind), fault.move_index, fault.count, fault.at_fraction));
    }
  }
  return {};
}

MockTurntable::MockTurntable(MockOptions options, std::shared_ptr<SimulatedPlate> plate)
    : options_(std::move(options)),
      limits_{options_.speed_deg_per_s, options_.acceleration_deg_per_s2},
      plate_(std::move(plate)) {
  if (plate_) position_deg_ = plate_->angle_deg.load();
  commanded_deg_ = position_deg_;
  std::lock_guard lock(mutex_);
  WritePlate();
}

std::string MockTurntable::Describe() const {
  return fmt::format("mock (speed {} deg/s, acceleration {} deg/s^2, settle {} ms, time scale {})",
                     options_.speed_deg_per_s, options_.acceleration_deg_per_s2, options_.settle_ms,
                     options_.time_scale);
}

double MockTurntable::SimulatedSeconds(Clock::duration real) const {
  return std::chrono::duration<double>(real).count() / options_.time_scale;
}

Clock::duration MockTurntable::RealDuration(double simulated_s) const {
  return std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(simulated_s * options_.time_scale));
}

Clock::duration MockTurntable::RealMoveDuration(double from_deg, double to_deg) const {
  const MotionProfile profile(from_deg, to_deg, limits_);
  const double settle_s = profile.distance_deg() > 0.0 ? options_.settle_ms / 1000.0 : 0.0;
  return RealDuration(profile.duration_s() + settle_s);
}

void MockTurntable::WritePlate() {
  if (!plate_) return;
  bool moving = false;
  if (motion_) {
    moving = (motion_->phase == Phase::kMoving && !motion_->stalled) ||
             motion_->phase == Phase::kSettling;
  }
  plate_->angle_deg.store(position_deg_);
  plate_->moving.store(moving);
}

void MockTurntable::Advance(Clock::time_point now) {
  if (motion_ && (motion_->phase == Phase::kMoving || motion_->phase == Phase::kSettling)) {
    Motion& m = *motion_;
    const double t_s = SimulatedSeconds(now - m.start);
    if (m.fault && !m.stalled && t_s >= m.fault_time_s) {
      // The fault point lies within the motion time, so it strikes even when nobody looked at
      // the drive until after the move would have ended.
      position_deg_ = m.profile.PositionAt(m.fault_time_s);
      switch (m.fault->kind) {
        case MockFault::Kind::kStall:
          m.stalled = true;
          break;
        case MockFault::Kind::kAlarm:
          m.phase = Phase::kAlarm;
          alarm_code_ = m.fault->alarm_code;
          alarm_text_ = m.fault->alarm_text;
          enabled_ = false;
          break;
        case MockFault::Kind::kLinkDown:
          m.phase = Phase::kLinkLost;
          break;
      }
    } else if (m.stalled) {
      // The plate stays where it stalled; the drive still reports moving.
    } else if (t_s < m.profile.duration_s()) {
      position_deg_ = m.profile.PositionAt(t_s);
      m.phase = Phase::kMoving;
    } else if (t_s < m.profile.duration_s() + m.settle_s) {
      position_deg_ = m.profile.target_deg();
      m.phase = Phase::kSettling;
    } else {
      position_deg_ = m.profile.target_deg();
      m.phase = Phase::kDone;
    }
  }
  WritePlate();
}

void MockTurntable::Halt(Clock::time_point now) {
  Advance(now);
  if (motion_ && (motion_->phase == Phase::kMoving || motion_->phase == Phase::kSettling)) {
    motion_->phase = Phase::kStopped;
    WritePlate();
  }
}

std::optional<MockFault> MockTurntable::TakeFault() {
  const int index = moves_started_++;
  for (const MockFault& fault : options_.faults) {
    if (index >= fault.move_index && index - fault.move_index < fault.count) return fault;
  }
  return std::nullopt;
}

Expected<void> MockTurntable::RunMove(std::unique_lock<std::mutex>& lock, double target_deg,
                                      Clock::time_point deadline, std::optional<MockFault> fault) {
  const Clock::time_point start = Clock::now();
  Advance(start);
  if (start >= deadline) {
    return MakeError(
        ErrorCode::kTimeout,
        fmt::format("the deadline for the move to {} deg passed before it started", target_deg));
  }

  Motion motion;
  motion.profile = MotionProfile(position_deg_, target_deg, limits_);
  motion.start = start;
  motion.settle_s = motion.profile.distance_deg() > 0.0 ? options_.settle_ms / 1000.0 : 0.0;
  if (fault) {
    motion.fault_time_s = fault->at_fraction * motion.profile.duration_s();
    Logger("turntable")
        ->info("mock: injecting a {} fault into move {} ({} -> {} deg)", FaultName(fault->kind),
               moves_started_ - 1, position_deg_, target_deg);
  }
  motion.fault = std::move(fault);
  Logger("turntable")
      ->debug("mock: move {} -> {} deg, {:.3f} s simulated", position_deg_, target_deg,
              motion.profile.duration_s() + motion.settle_s);
  commanded_deg_ = target_deg;
  motion_ = std::move(motion);

  const Clock::time_point end =
      start + RealDuration(motion_->profile.duration_s() + motion_->settle_s);
  const Clock::time_point fault_at = start + RealDuration(motion_->fault_time_s);
  for (;;) {
    const Clock::time_point now = Clock::now();
    Advance(now);
    switch (motion_->phase) {
      case Phase::kDone:
        return {};
      case Phase::kStopped:
        return MakeError(
            ErrorCode::kAborted,
            fmt::format("the move to {} deg was stopped at {:.3f} deg", target_deg, position_deg_));
      case Phase::kAlarm:
        return MakeError(
            ErrorCode::kAlarm,
            fmt::format("drive alarm {:#x} at {:.3f} deg on the way to {} deg: {}",
                        alarm_code_.value_or(0), position_deg_, target_deg, alarm_text_));
      case Phase::kLinkLost:
        return MakeError(ErrorCode::kLinkDown,
                         fmt::format("lost the link to the (mock) drive during the move to {} "
                                     "deg; its watchdog stopped the motor at {:.3f} deg",
                                     target_deg, position_deg_));
      case Phase::kMoving:
      case Phase::kSettling:
        break;
    }
    if (now >= deadline) {
      const bool stalled = motion_->stalled;
      Halt(now);
      if (stalled) {
        return MakeError(ErrorCode::kStalled,
                         fmt::format("the plate stalled at {:.3f} deg on the way to {} deg and "
                                     "did not move by the deadline; motor stopped",
                                     position_deg_, target_deg));
      }
      return MakeError(ErrorCode::kTimeout,
                       fmt::format("the move to {} deg did not finish by the deadline; motor "
                                   "stopped at {:.3f} deg",
                                   target_deg, position_deg_));
    }
    Clock::time_point wake = deadline;
    if (!motion_->stalled) {
      wake = std::min(wake, end);
      if (motion_->fault) wake = std::min(wake, std::max(fault_at, now));
      if (motion_->phase == Phase::kMoving) wake = std::min(wake, now + kPlateRefresh);
    }
    wake_.wait_until(lock, wake);
  }
}

Expected<void> MockTurntable::MoveTo(double angle_deg, Clock::time_point deadline) {
  if (!std::isfinite(angle_deg)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("target angle {} deg is not a finite number", angle_deg));
  }
  std::unique_lock lock(mutex_);
  if (busy_) {
    return MakeError(ErrorCode::kBusy,
                     fmt::format("cannot move to {} deg: another move is in progress", angle_deg));
  }
  if (alarm_code_) {
    return MakeError(ErrorCode::kAlarm,
                     fmt::format("drive alarm {:#x} is latched ({}); Home() resets it",
                                 *alarm_code_, alarm_text_));
  }
  if (!enabled_) {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("cannot move to {} deg: the drive is disabled; Home() enables it", angle_deg));
  }
  std::optional<MockFault> fault = TakeFault();
  BusyScope busy(busy_);
  return RunMove(lock, angle_deg, deadline, std::move(fault));
}

Expected<void> MockTurntable::Home(Clock::time_point deadline) {
  std::unique_lock lock(mutex_);
  if (busy_) return MakeError(ErrorCode::kBusy, "cannot home: a move is in progress");
  BusyScope busy(busy_);
  // Homing resets the alarm, energizes the motor and re-establishes the reference.
  alarm_code_.reset();
  alarm_text_.clear();
  enabled_ = true;
  homed_ = false;
  const double home_deg = std::round(position_deg_ / 360.0) * 360.0;
  if (Expected<void> moved = RunMove(lock, home_deg, deadline, std::nullopt); !moved) {
    return std::unexpected(WithContext(std::move(moved.error()), "homing"));
  }
  position_deg_ = 0.0;
  commanded_deg_ = 0.0;
  homed_ = true;
  WritePlate();
  return {};
}

Expected<TurntableState> MockTurntable::State() {
  std::lock_guard lock(mutex_);
  Advance(Clock::now());
  const bool active =
      motion_ && (motion_->phase == Phase::kMoving || motion_->phase == Phase::kSettling);
  TurntableState state;
  state.angle_deg = position_deg_;
  state.moving = motion_ && motion_->phase == Phase::kMoving;
  state.in_position =
      !active && !alarm_code_ && std::abs(position_deg_ - commanded_deg_) <= options_.tolerance_deg;
  state.enabled = enabled_;
  state.homed = homed_;
  state.open_loop = false;
  state.alarm_code = alarm_code_;
  state.alarm_text = alarm_text_;
  return state;
}

void MockTurntable::Stop() noexcept {
  try {
    std::lock_guard lock(mutex_);
    Halt(Clock::now());
  } catch (...) {
    // std::mutex::lock only throws when the system is broken; nothing sensible is left to do.
  }
  wake_.notify_all();
}

Expected<void> MockTurntable::Disable() {
  {
    std::lock_guard lock(mutex_);
    Halt(Clock::now());
    enabled_ = false;
  }
  wake_.notify_all();
  return {};
}

}  // namespace revolve::turntable
