// A simulated turntable drive: timing from a motion profile, settle time, fault injection.
//
// The mock behaves like a closed-loop servo in absolute position mode:
//  - A move follows a MotionProfile (trapezoid or triangle) from the current angle to the
//    target, then rings for settle_ms, then reports in position at exactly the target.
//    Simulated time runs on the steady clock scaled by MockOptions::time_scale.
//  - While a move runs it writes the interpolated angle and moving = true into the
//    SimulatedPlate; during the settle time the angle is the target and moving stays true; once
//    in position, moving = false. The plate angle is the multi-turn drive position (it does not
//    wrap; the synthetic camera only needs it modulo 360).
//  - The motor turns only while a MoveTo() or Home() call is in progress: every way out of such
//    a call (success, error, Stop(), Disable()) leaves the motor standing. The state is computed
//    from the clock on demand, so the mock owns no thread.
//  - It starts enabled (as many drives do at power-up) and not homed, at the plate's angle.
//  - Disable() keeps the position and `homed` (the encoder keeps counting); MoveTo() on a
//    disabled drive fails with bad_input until Home() enables it.
//  - State() never fails. open_loop is false.
//
// All members are thread-safe. The object must outlive any call in progress on another thread.
#pragma once

#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "base/error.h"
#include "base/sim_plate.h"
#include "turntable/motion_profile.h"
#include "turntable/turntable.h"

namespace revolve::turntable {

// Ranges of MockOptions (ParseOptions and ValidateMockOptions share them). Lower bounds of speed,
// acceleration and time_scale are exclusive.
inline constexpr double kMockMaxSpeedDegPerS = 3600.0;
inline constexpr double kMockMaxAccelerationDegPerS2 = 100000.0;
inline constexpr double kMockMaxSettleMs = 10000.0;
inline constexpr double kMockMaxTimeScale = 100.0;
inline constexpr double kMockMaxToleranceDeg = 5.0;

class MockTurntable final : public Turntable {
 public:
  // Contract: `options` valid (see ValidateMockOptions); `plate` may be null.
  MockTurntable(MockOptions options, std::shared_ptr<SimulatedPlate> plate);

  Expected<void> Home(Clock::time_point deadline) override;
  Expected<void> MoveTo(double angle_deg, Clock::time_point deadline) override;
  Expected<TurntableState> State() override;
  void Stop() noexcept override;
  Expected<void> Disable() override;
  std::string Describe() const override;

  // How long (real time) a move from `from_deg` to `to_deg` takes with these options,
  // including the settle time (none for a zero-length move). For tests and diagnostics.
  Clock::duration RealMoveDuration(double from_deg, double to_deg) const;

 private:
  // Where the current (or last) move is.
  enum class Phase {
    kMoving,    // following the profile (or stalled: the drive still thinks it is moving)
    kSettling,  // profile done, ringing for settle_ms
    kDone,      // in position
    kStopped,   // halted by Stop(), Disable() or the deadline
    kAlarm,     // halted by an injected alarm
    kLinkLost,  // halted by an injected link loss
  };

  struct Motion {
    MotionProfile profile;
    Clock::time_point start;
    double settle_s = 0.0;  // simulated
    Phase phase = Phase::kMoving;
    std::optional<MockFault> fault;
    double fault_time_s = 0.0;  // simulated time of the fault after `start`
    bool stalled = false;
  };

  // Runs one move to `target_deg` until it ends or the deadline passes. Requires `lock` held
  // and busy_ set by the caller.
  Expected<void> RunMove(std::unique_lock<std::mutex>& lock, double target_deg,
                         Clock::time_point deadline, std::optional<MockFault> fault);
  // Brings position_deg_ and the phase of motion_ up to `now`, and writes the plate.
  // Requires mutex_ held.
  void Advance(Clock::time_point now);
  // Freezes the motor where it is now (phase kStopped). Requires mutex_ held.
  void Halt(Clock::time_point now);
  // Requires mutex_ held.
  void WritePlate();
  double SimulatedSeconds(Clock::duration real) const;
  Clock::duration RealDuration(double simulated_s) const;
  // The fault for the next counted MoveTo(), if any; advances the move counter.
  std::optional<MockFault> TakeFault();

  const MockOptions options_;
  const MotionLimits limits_;
  const std::shared_ptr<SimulatedPlate> plate_;

  mutable std::mutex mutex_;
  std::condition_variable wake_;  // signalled by Stop() and Disable()
  double position_deg_ = 0.0;
  double commanded_deg_ = 0.0;
  bool enabled_ = true;
  bool homed_ = false;
  bool busy_ = false;  // a MoveTo() or Home() is in progress
  std::optional<int> alarm_code_;
  std::string alarm_text_;
  std::optional<Motion> motion_;
  int moves_started_ = 0;
};

// bad_input naming the first option outside its documented range (see MockOptions, MockFault).
Expected<void> ValidateMockOptions(const MockOptions& options);

}  // namespace revolve::turntable
