// Drive profiles: what a Modbus motor drive's registers mean, as data (TOML files in
// turntable/modbus/profiles/, or any file a user points at). Pure: parsing, rendering commands
// to requests, decoding fields; no I/O beyond reading the profile file.
//
// File format (docs/operator-guide.md, "Modbus drive profiles", walks through it):
//
//   [profile]
//   description = "..."          # one line for logs
//   steps_per_rev = 3200         # drive counts per motor revolution (config may override)
//   word_order = "high_first"    # default for 32-bit fields and values: high_first | low_first
//
//   [params]                     # named numbers commands may use as ${name}; config
//   acc = 240                    # [turntable.modbus.params] overrides them
//
//   [fields.position]            # "position" is required: the read-back in drive counts
//   table = "input"              # holding (FC03) | input (FC04)
//   address = 0x0033             # PDU address (0-based), 0..0xFFFF
//   type = "i32"                 # u16 | i16 | u32 | i32 (32-bit: two registers)
//   word_order = "high_first"    # optional, defaults to [profile] word_order
//   scale = 1.0                  # counts = raw * scale (position only)
//
//   [commands]                   # ordered steps; names: init (once, before the first enable),
//   move = ["write_registers 0x00FE ${acc} ${speed_rpm} ${target:i32}"]   # enable, disable,
//                                # move, home, stop, reset_alarm
//
//   [status]                     # expressions over fields (see expression.h)
//   moving = "status in [2, 3, 4, 5, 6]"
//   alarm_code = "stall"         # the field holding the drive's alarm code
//
//   [alarms]                     # optional: words for alarm codes, for the operator
//   0x31 = "overcurrent: check the motor wiring"
//
// Steps:  write_register ADDR VALUE        FC06, exactly one 16-bit value
//         write_registers ADDR VALUE...    FC16, 1..123 registers (32-bit values take two)
//         write_coil ADDR 0|1              FC05
//         sleep_ms N                       pause between steps (0..10000)
// Values: a literal (decimal, 0x hex, may be negative) or ${variable}, optionally with a scale
//         factor and a type: 1000, 0x40:u32, ${target:i32}, ${speed_rpm*10:u16}. The default
//         type is u16. A value that does not fit its type is an error when rendered.
// Variables of the move command (see MoveVariables in modbus_turntable.h): target, delta,
//         speed_rpm, speed_hz, accel_rpm_s, accel_hz_s, accel_ms, accel_ms_per_krpm; plus every
//         [params] name (all commands).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"
#include "config/config.h"
#include "turntable/modbus/expression.h"
#include "turntable/modbus/frame.h"

namespace revolve::turntable::modbus {

enum class RegisterTable { kHolding, kInput };
enum class ValueType { kU16, kI16, kU32, kI32 };
enum class WordOrder { kHighFirst, kLowFirst };

int RegisterCount(ValueType type);
std::string_view ToString(ValueType type);

// Encodes `value` (already rounded) as registers of `type` in `order`. Errors: bad_input when it
// does not fit the type.
Expected<std::vector<std::uint16_t>> EncodeValue(std::int64_t value, ValueType type,
                                                 WordOrder order);
// Decodes RegisterCount(type) registers (signed types sign-extend).
std::int64_t DecodeValue(std::span<const std::uint16_t> registers, ValueType type, WordOrder order);

struct Field {
  std::string name;
  RegisterTable table = RegisterTable::kHolding;
  std::uint16_t address = 0;
  ValueType type = ValueType::kU16;
  WordOrder word_order = WordOrder::kHighFirst;
  double scale = 1.0;
};

// One value of a write step.
struct ValueTemplate {
  std::string variable;  // empty: a literal
  std::int64_t literal = 0;
  double factor = 1.0;  // variables only: multiplied before rounding
  ValueType type = ValueType::kU16;
  WordOrder word_order = WordOrder::kHighFirst;
};

struct Step {
  enum class Kind { kWriteRegister, kWriteRegisters, kWriteCoil, kSleep };
  Kind kind = Kind::kWriteRegister;
  std::uint16_t address = 0;
  std::vector<ValueTemplate> values;
  int sleep_ms = 0;
  std::string text;  // as written in the profile
};

struct Command {
  std::string name;
  std::vector<Step> steps;
};

// The normalized status rules. Absent rules are nullopt (see ModbusTurntable for the defaults).
struct StatusRules {
  StatusExpression moving;  // required
  std::optional<StatusExpression> in_position;
  std::optional<StatusExpression> alarm;
  std::optional<StatusExpression> enabled;
  std::optional<StatusExpression> homed;
  std::optional<std::string> alarm_code_field;
};

// Commands a profile may define. "move" and "stop" are required.
inline constexpr std::string_view kCommandNames[] = {"enable", "disable",     "move", "home",
                                                     "stop",   "reset_alarm", "init"};

// Variables the move command may use, besides [params].
inline constexpr std::string_view kMoveVariables[] = {
    "target",      "delta",      "speed_rpm", "speed_hz",
    "accel_rpm_s", "accel_hz_s", "accel_ms",  "accel_ms_per_krpm"};

struct DriveProfile {
  std::string name;    // file stem
  std::string origin;  // the file it came from
  std::string description;
  std::int64_t steps_per_rev = 0;
  WordOrder word_order = WordOrder::kHighFirst;
  std::map<std::string, double, std::less<>> params;
  std::map<std::string, Field, std::less<>> fields;
  std::map<std::string, Command, std::less<>> commands;
  StatusRules status;
  std::map<std::int64_t, std::string> alarm_texts;

  const Command* FindCommand(std::string_view name) const;
  const Field& position() const { return fields.find("position")->second; }
};

// Parses a profile document; `name` is how it is called (the file stem). Errors: bad_input with
// file:line:column and the key for every mistake: unknown keys, bad addresses, steps, values,
// expressions naming unknown fields, variables no command can resolve, a missing position
// field, move or stop command.
Expected<DriveProfile> ParseProfile(const config::Document& document, std::string name);

// Loads and parses a profile file.
Expected<DriveProfile> LoadProfileFile(const std::filesystem::path& path);

using Variables = std::map<std::string, double, std::less<>>;

// One rendered step: a request to send, or a pause.
struct RenderedStep {
  std::optional<Request> request;
  int sleep_ms = 0;
};

// Renders `command` with `variables` (params are added by the caller). Errors: bad_input naming
// the profile, command, step and value when a variable is missing or a value does not fit.
Expected<std::vector<RenderedStep>> RenderCommand(const DriveProfile& profile,
                                                  const Command& command,
                                                  const Variables& variables);

// A plain read of one or more whole fields.
struct FieldRead {
  RegisterTable table = RegisterTable::kHolding;
  std::uint16_t address = 0;
  std::uint16_t count = 0;
  std::vector<std::string> fields;  // the fields it covers
};

// The reads that fetch every field, merging fields that sit next to each other in the same table
// (never reading a register no field names, since drives reject unmapped addresses).
std::vector<FieldRead> PlanFieldReads(const DriveProfile& profile);

// Decodes the fields of `read` from its registers into `out` (raw values, before scale).
void DecodeFields(const DriveProfile& profile, const FieldRead& read,
                  std::span<const std::uint16_t> registers, FieldValues& out);

}  // namespace revolve::turntable::modbus
