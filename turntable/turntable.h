// The turntable: a plate turned by a drive to absolute angles.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "base/error.h"
#include "base/sim_plate.h"
#include "config/config.h"
#include "turntable/gpio/gpio_options.h"
#include "turntable/modbus/modbus_options.h"

namespace revolve::turntable {

using Clock = std::chrono::steady_clock;

// What the drive reports right now.
struct TurntableState {
  double angle_deg = 0.0;  // position read back from the drive (open loop: counted steps)
  bool moving = false;
  bool in_position = false;  // stopped within tolerance of the last commanded target
  bool enabled = false;
  bool homed = false;
  bool open_loop = false;  // true when the position is counted, not measured
  std::optional<int> alarm_code;
  std::string alarm_text;  // words an operator can act on; empty without an alarm
};

class Turntable {
 public:
  virtual ~Turntable() = default;

  // Resets a latched alarm, enables the drive and moves to the home position (the nearest whole
  // revolution), where the position counter becomes 0 deg. Returns when homed and in position.
  virtual Expected<void> Home(Clock::time_point deadline) = 0;

  // Moves to the absolute, multi-turn plate angle `angle_deg` (any finite real number) and
  // returns only when the drive reports stopped and in position within tolerance of the target,
  // or with an error. Angles do not wrap: from 350, a target of 360 turns 10 deg forward (one
  // full turn past 0), and a target of 0 turns 350 deg back. Callers normally pass k * step_deg.
  // Allowed before Home() (State().homed stays false). On a disabled drive (after Disable())
  // it fails with bad_input without moving, like a real drive that ignores position commands
  // while de-energized: Home() enables it again.
  // Errors: timeout (deadline passed; the motor is stopped), stalled (no progress by the
  // deadline; stopped), alarm (latched until Home()), link_down (transient), aborted (Stop() or
  // Disable() from another thread), busy (another move is in progress), bad_input, protocol.
  virtual Expected<void> MoveTo(double angle_deg, Clock::time_point deadline) = 0;

  virtual Expected<TurntableState> State() = 0;

  // Stops the motor as fast as the drive allows, where it is now (the drive stays enabled). Safe
  // to call at any time, from any thread; a MoveTo() or Home() blocked on another thread returns
  // aborted promptly.
  virtual void Stop() noexcept = 0;

  // Stops any motion and removes motor power (the plate may then turn freely). A latched alarm
  // stays latched.
  virtual Expected<void> Disable() = 0;

  // One line for logs and the report ("mock (speed 120 deg/s)", "modbus tcp 10.0.0.5:502 ...").
  virtual std::string Describe() const = 0;
};

// A fault the mock drive injects into chosen MoveTo() calls, for tests of the callers' error
// handling. Home() is never faulted (it is how a station recovers). Not settable from TOML.
struct MockFault {
  enum class Kind {
    kStall,     // the plate stops at the fault point while the drive still reports moving; the
                // move never completes: stalled at the deadline, motor stopped
    kAlarm,     // the drive stops at the fault point, latches alarm_code/alarm_text and
                // de-energizes: MoveTo returns alarm; later moves fail with alarm until Home()
    kLinkDown,  // the link drops at the fault point: MoveTo returns link_down, the drive's
                // communication watchdog stops the motor there; the next call works again
  };
  Kind kind = Kind::kStall;
  // Which MoveTo() calls get the fault: the `move_index`-th move since creation (0 = the first)
  // and the `count` - 1 moves after it. Calls rejected before moving (busy, disabled, latched
  // alarm, bad angle) are not counted.
  int move_index = 0;
  int count = 1;
  // When the fault strikes, as a fraction [0, 1] of the move's motion time (0: before the plate
  // moves at all; 0.5: halfway, which is also the halfway angle since profiles are symmetric).
  double at_fraction = 0.5;
  int alarm_code = 0x31;  // kAlarm only
  std::string alarm_text = "overcurrent: check the motor wiring and the load";
};

// The mock drive's motion parameters (see [turntable.mock] in docs/configuration.md).
//
// Time: the mock simulates a drive on the steady clock slowed or sped up by `time_scale`:
//   real_seconds = simulated_seconds * time_scale.
// time_scale = 1 is real time; 0.1 makes a move that takes 1 s on a real table (speed,
// acceleration and settle_ms are real-table values) take 0.1 s. Deadlines passed to MoveTo() and
// Home() are real steady-clock times and are never scaled.
struct MockOptions {
  double speed_deg_per_s = 120.0;          // cruise speed, (0, 3600]
  double acceleration_deg_per_s2 = 720.0;  // = deceleration, (0, 100000]
  double settle_ms = 20.0;                 // ringing after the motion profile ends, simulated ms
  double time_scale = 0.1;                 // (0, 100], see above
  double tolerance_deg = 0.01;             // in-position window, [0, 5]
  std::vector<MockFault> faults;           // fault injection for tests; not in TOML
};

struct TurntableOptions {
  std::string backend = "mock";  // mock | modbus | gpio
  // Remove motor power when a scan ends (completed, failed or aborted) and when the turntable
  // object is destroyed; false keeps the plate held by the motor. The station calls Disable()
  // after a scan only when this is true.
  bool disable_at_end = true;
  MockOptions mock;
  ModbusOptions modbus;  // [turntable.modbus], parsed when present or when backend = "modbus"
  GpioOptions gpio;      // [turntable.gpio], parsed when present or when backend = "gpio"
};

// Parses [turntable] (`section`, as returned by Root().Child("turntable")) and its backends'
// sub-tables; a missing table gives the defaults. [turntable.modbus] resolves and loads its drive
// profile, so a missing or broken profile is a config error. Errors (bad_input, with
// file:line:column and the key): unknown keys in any table, wrong types, values out of range, an
// unknown backend; not_found/bad_input for the profile. Options are parsed even when this build
// lacks a backend (Create() reports that).
Expected<TurntableOptions> ParseOptions(const config::Section& section);

// The descriptions of the keys of [turntable] and its backends' tables, for the configuration
// reference (config/reference.h).
config::OptionDocs ReferenceDocs();

// Creates the configured turntable and opens its device (the serial port or TCP connection,
// the GPIO lines). `plate` is the simulated rig's plate: the mock writes its angle; the modbus
// and gpio backends publish their read-back (or counted) angle and moving flag to it, so the
// synthetic camera also works with them (a drive simulator, a bench rig). May be null. Errors:
// bad_input when the options are out of the ranges above; unsupported for a backend this build
// lacks (the message names the CMake option, REVOLVE_WITH_MODBUS or REVOLVE_WITH_GPIO);
// not_found, busy, link_down, no_device when the device cannot be opened.
Expected<std::unique_ptr<Turntable>> Create(const TurntableOptions& options,
                                            std::shared_ptr<SimulatedPlate> plate);

}  // namespace revolve::turntable
