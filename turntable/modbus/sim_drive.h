// A simulated Modbus motor drive that implements any drive profile: the model behind
// `revolve simulate-drive` and the in-process transport of the tests. No I/O and no clock of
// its own: every call gets the time, so tests are deterministic.
//
// How it reads a profile:
//  - Writes land in a holding-register (and coil) bank. A write that matches the last step of a
//    profile command (same function, address and register count, equal literal values) runs
//    that command; its variables are decoded back from the bank (so "move" may be one FC16 or
//    several writes then a trigger). enable/disable/move/home/stop/reset_alarm are understood;
//    other commands are accepted and ignored.
//  - Reads return the profile's fields: `position` (counts / scale), the alarm code field, and
//    for the fields the status rules read, values found by search so that the rules evaluate to
//    the drive's state (moving, in position, alarm, enabled, homed). Other holding registers
//    read back what was written; other input registers read 0.
//  - A move follows a trapezoidal profile (speed and acceleration decoded from the move
//    variables, else the defaults), then settles for settle_ms, then reports in position.
//    Moves are ignored while the drive is disabled or in alarm (as real drives do).
//  - "home" moves to count 0 and sets homed.
//  - A communication watchdog stops a moving motor when no request arrived for watchdog_ms.
// Faults (SimFault) model what real drives and buses do.
//
// Thread-safe (one mutex).
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"
#include "turntable/modbus/profile.h"
#include "turntable/motion_profile.h"
#include "turntable/turntable.h"

namespace revolve::turntable::modbus {

struct SimFault {
  enum class Kind {
    kAlarm,      // at_fraction of move `move_index`: the motor stops and the drive latches `code`
    kStall,      // at_fraction: the shaft stops turning while the drive still reports moving
    kLinkDrop,   // at_fraction: every later request is lost (TCP: connections are closed); the
                 // watchdog then stops the motor
    kNoReply,    // from the `move_index`-th move command on, `count` requests (0: all) are lost
    kCorrupt,    // ... are answered with a bad CRC (TCP: a wrong transaction id)
    kException,  // ... are rejected with exception `code` (not executed)
  };
  Kind kind = Kind::kAlarm;
  int move_index = 0;
  double at_fraction = 0.5;
  int count = 0;
  int code = 0x30;
};

// "KIND@MOVE[:ARG]" with KIND alarm | stall | link-drop | no-reply | corrupt | exception; ARG is
// the fraction for alarm, stall and link-drop, the exception code for exception, the request
// count for no-reply and corrupt. Examples: "alarm@3:0.5", "no-reply@0", "exception@1:2".
Expected<SimFault> ParseSimFault(std::string_view spec);
std::string Describe(const SimFault& fault);

struct SimDriveOptions {
  std::int64_t steps_per_rev = 0;   // counts per motor rev for rpm variables; 0: the profile's
  double default_speed_hz = 0.0;    // when the move gives none; 0: one motor rev per second
  double default_accel_hz_s = 0.0;  // when the move gives none; 0: ten motor revs per s^2
  double settle_ms = 2.0;           // after the profile ends, before "in position"
  double watchdog_ms = 500.0;       // 0: off
  int alarm_code = 0x30;            // default code for alarm faults
  std::vector<SimFault> faults;
};

// What the server does with one request.
struct SimReply {
  enum class Action { kReply, kDrop, kCorrupt };
  Action action = Action::kReply;
  std::vector<std::uint8_t> pdu;  // the response (possibly an exception) for kReply/kCorrupt
};

struct SimSnapshot {
  double position_counts = 0.0;
  std::int64_t target_counts = 0;
  bool moving = false;
  bool in_position = false;
  bool enabled = false;
  bool homed = false;
  std::optional<std::int64_t> alarm_code;
  int moves_started = 0;
  bool link_down = false;
};

class SimulatedDrive {
 public:
  using Clock = std::chrono::steady_clock;

  // Errors: bad_input when the profile's status rules cannot be simulated (too many field
  // combinations) or an option is out of range.
  static Expected<std::unique_ptr<SimulatedDrive>> Create(DriveProfile profile,
                                                          SimDriveOptions options);

  // Serves one request PDU received at `now`.
  SimReply Handle(std::span<const std::uint8_t> request_pdu, Clock::time_point now);

  SimSnapshot Inspect(Clock::time_point now);

  // True once a link-drop fault struck (the TCP server closes its sockets then).
  bool LinkDown(Clock::time_point now);

  const DriveProfile& profile() const { return profile_; }

 private:
  struct Motion {
    MotionProfile profile;  // in counts
    Clock::time_point start;
    double settle_s = 0.0;
    bool homing = false;
    std::optional<SimFault> fault;
    bool frozen = false;  // stalled
    double frozen_counts = 0.0;
  };
  // Desired status bits: the profile's rule outcomes.
  enum Bit { kMoving = 1, kInPosition = 2, kAlarm = 4, kEnabled = 8, kHomed = 16 };

  SimulatedDrive(DriveProfile profile, SimDriveOptions options);
  Expected<void> SolveStatus();
  void Advance(Clock::time_point now);
  double PositionAt(const Motion& motion, Clock::time_point t) const;
  std::optional<std::string> MatchCommand(const Request& request) const;
  Variables DecodeVariables(const Command& command) const;
  void Apply(const std::string& command, Clock::time_point now);
  void StartMotion(double target_counts, double speed_hz, double accel_hz_s, bool homing,
                   Clock::time_point now);
  std::vector<std::uint16_t> ReadRegisters(RegisterTable table, std::uint16_t address,
                                           std::uint16_t count);
  int StatusBits() const;

  const DriveProfile profile_;
  const SimDriveOptions options_;
  const double steps_per_rev_;
  std::mutex mutex_;
  std::map<int, FieldValues> solutions_;  // desired bits -> values of the searched fields
  std::map<std::uint16_t, std::uint16_t> holding_;
  std::map<std::uint16_t, bool> coils_;
  double position_counts_ = 0.0;
  double target_counts_ = 0.0;
  bool enabled_ = false;
  bool homed_ = false;
  std::optional<std::int64_t> alarm_code_;
  std::optional<Motion> motion_;
  int moves_started_ = 0;
  int move_requests_ = 0;
  std::optional<Clock::time_point> last_request_;
  std::optional<Clock::time_point> link_down_at_;
  std::optional<SimFault> protocol_fault_;  // active no-reply / corrupt / exception
  int protocol_fault_left_ = 0;             // requests still affected (-1: all)
};

}  // namespace revolve::turntable::modbus
