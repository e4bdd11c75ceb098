// A turntable driven by a Modbus drive, described by a data-only profile (profile.h).
//
// Positions: the plate angle maps to drive counts through steps_per_rev (counts per motor rev,
// from the profile unless the config overrides it), gear_ratio (motor revs per plate rev) and
// direction:  counts = offset + sign * round(angle_deg / 360 * steps_per_rev * gear_ratio).
// `offset` is the drive count at the plate's 0 deg, set by Home().
//
// A move: "init" (once per process, when the profile has it) and "enable" (when the drive is not
// known to be enabled), then "move" rendered with
// MoveVariables(), then the status fields are polled every poll_ms until the drive reports not
// moving, in position (its in_position rule, when the profile has one) and the read-back is
// within tolerance_deg of the target count for in_position_polls polls in a row (the angle
// itself is quantized to whole counts: up to half a count more). It fails with:
//   alarm     the alarm rule holds (the drive's code and the profile's words for it; latched
//             until Home(), which runs "reset_alarm");
//   stalled   no progress (the read-back moved less than the tolerance) for stall_timeout_ms
//             while not at the target, or at the deadline with no progress in the last
//             min(stall_timeout_ms, 200 ms);
//   timeout   the deadline passed while the plate still progressed (or sat at the target while
//             the drive did not report in position);
//   link_down / protocol   a transaction failed after `retries` more tries (only no-reply,
//             lost-connection, bad-CRC and busy answers are retried);
//   aborted   Stop() or Disable() from another thread.
// Every failure sends "stop" before returning (best effort when the link is down: drives stop
// on their own communication watchdog).
//
// Home(): "reset_alarm" and "enable" (when defined), then "home" and a wait until the homed rule
// (or, without one, not moving) holds; the read-back becomes 0 deg. A profile without "home"
// moves to the nearest whole plate revolution instead, which then becomes 0 deg.
//
// Idle power-down: with idle_disable_s > 0 a watcher runs "disable" once the table has been idle
// that long; the next move enables it again (unlike Disable(), after which MoveTo fails until
// Home()).
//
// When `plate` is given, every status read publishes the read-back angle and the moving flag to
// it, so a simulated camera renders the plate where the drive says it is.
//
// Thread-safety: every member may be called from any thread. One Home()/MoveTo() at a time (a
// second one fails with busy); State(), Stop() and Disable() may run concurrently with them.
#pragma once

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "base/error.h"
#include "base/sim_plate.h"
#include "turntable/drive_support.h"
#include "turntable/modbus/modbus_options.h"
#include "turntable/modbus/profile.h"
#include "turntable/modbus/transport.h"
#include "turntable/turntable.h"

namespace revolve::turntable::modbus {

// The plate/motor/drive unit conversions of one installation.
struct Kinematics {
  double steps_per_rev = 1.0;  // drive counts per motor revolution
  double gear_ratio = 1.0;     // motor revolutions per plate revolution
  bool reverse = false;

  double CountsPerPlateRev() const { return steps_per_rev * gear_ratio; }
  // Signed counts for a plate angle (not rounded, no offset), and back.
  double CountsFromDeg(double angle_deg) const;
  double DegFromCounts(double counts) const;
};

// The move command's variables (see profile.h) for a move from `from_counts` to `target_counts`
// at the plate speed and acceleration given; `params` (the profile's, with config overrides)
// are added. Pure.
//   target, delta        counts (absolute target; target - from)
//   speed_rpm, speed_hz  motor rev/min; counts/s
//   accel_rpm_s, accel_hz_s   motor rpm per second; counts/s^2
//   accel_ms             time to reach the cruise speed, ms
//   accel_ms_per_krpm    ms to change the motor speed by 1000 rpm
Variables MoveVariables(const Kinematics& kinematics, std::int64_t target_counts,
                        std::int64_t from_counts, double speed_deg_per_s,
                        double acceleration_deg_per_s2, const Variables& params);

// The words for an alarm: the profile's [alarms] text for the code, or a generic sentence.
std::string AlarmText(const DriveProfile& profile, std::optional<std::int64_t> code);

class ModbusTurntable final : public Turntable {
 public:
  // Contract: `options` parsed by ParseModbusOptions; `profile` loaded from
  // options.profile_path; `transport` open. `plate` may be null. With `disable_at_end`, the
  // destructor removes motor power after stopping the motor.
  ModbusTurntable(ModbusOptions options, DriveProfile profile,
                  std::unique_ptr<ModbusTransport> transport, std::shared_ptr<SimulatedPlate> plate,
                  bool disable_at_end);
  // Stops the motor (and disables it, see above). Never throws.
  ~ModbusTurntable() override;

  Expected<void> Home(Clock::time_point deadline) override;
  Expected<void> MoveTo(double angle_deg, Clock::time_point deadline) override;
  Expected<TurntableState> State() override;
  void Stop() noexcept override;
  Expected<void> Disable() override;
  std::string Describe() const override;

 private:
  struct DriveStatus {
    std::int64_t position_counts = 0;
    bool moving = false;
    bool in_position = true;  // the profile's rule (true without one)
    bool alarm = false;
    std::optional<bool> enabled;  // nullopt: the profile cannot tell
    std::optional<bool> homed;
    std::optional<std::int64_t> alarm_code;
  };

  // One transaction with bounded retries of transient errors. Takes io_mutex_.
  Expected<std::vector<std::uint16_t>> Transact(const Request& request);
  // Runs a profile command; a missing optional command is a no-op when `optional`.
  Expected<void> RunCommand(std::string_view name, const Variables& variables, bool optional);
  Expected<DriveStatus> ReadStatus();
  // One poll of a wait: the status, published. Stops the motor and fails with aborted (message
  // `aborted`) after Stop(), with the read's error, or with alarm.
  Expected<DriveStatus> PollStatus(std::string_view aborted);
  // Polls until the move to `target_counts` completes or fails (see the header comment).
  Expected<void> WaitForMove(std::int64_t target_counts, Clock::time_point deadline);
  Expected<void> WaitForHome(Clock::time_point deadline);
  Expected<void> EnsureEnabled();
  // Sends "stop", logging (not returning) a failure.
  void StopMotor() noexcept;
  // Sleeps until `until` or an abort; false when aborted.
  bool Pause(Clock::time_point until);
  void Publish(const DriveStatus& status);
  double AngleOf(std::int64_t counts) const;
  // Runs "disable" after idle_disable_s without motion (IdlePowerDown's callback).
  void PowerDownIdle();
  Error AlarmError(const DriveStatus& status);

  const ModbusOptions options_;
  const DriveProfile profile_;
  const Kinematics kinematics_;
  const Variables params_;
  const std::shared_ptr<SimulatedPlate> plate_;
  const bool disable_at_end_;
  const std::int64_t tolerance_counts_;

  std::mutex op_mutex_;  // one Home()/MoveTo() at a time
  std::mutex io_mutex_;  // guards transport_
  std::unique_ptr<ModbusTransport> transport_;

  std::atomic<bool> abort_{false};
  std::mutex wait_mutex_;
  std::condition_variable wake_;

  mutable std::mutex mutex_;  // guards the fields below
  std::int64_t offset_counts_ = 0;
  std::optional<std::int64_t> commanded_counts_;  // none before the first move or home
  bool init_done_ = false;  // the profile's "init" ran (once, before the first "enable")
  bool enabled_ = false;    // "enable" was sent and no "disable" since
  bool explicitly_disabled_ = false;
  bool homed_ = false;
  bool busy_ = false;
  std::optional<Error> latched_alarm_;
  std::optional<std::int64_t> alarm_code_;

  IdlePowerDown idle_;  // last: its thread uses the fields above
};

}  // namespace revolve::turntable::modbus
