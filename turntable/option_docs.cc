// The descriptions of [turntable] and its backends' tables for the configuration reference
// (docs/configuration.md, made by `revolve check-config --reference`). The types, defaults and
// ranges come from the parser itself; a key it reads with no description here fails the test
// config_reference.
#include "turntable/turntable.h"

namespace revolve::turntable {
namespace {

constexpr config::TableDoc kTables[] = {
    {"turntable", ""},
    {"turntable.mock",
     "The simulated drive: a trapezoidal motion profile, then a settle time, then \"in position\". "
     "It reports the position it reached exactly. Faults: "
     "[`[station.simulate]`](#stationsimulate)."},
    {"turntable.modbus",
     "Keys marked (rtu) are accepted only with `transport = \"rtu\"`, (tcp) only with `\"tcp\"`. "
     "The profile is loaded when the configuration is read."},
    {"turntable.modbus.params",
     "Overrides of the Modbus profile's `[params]` (numbers, ±10¹²); a name the profile does not "
     "have is an error that lists the ones it has. See [Modbus drive "
     "profiles](operator-guide.md#modbus-drive-profiles)."},
    {"turntable.gpio", ""},
};

constexpr config::KeyDoc kKeys[] = {
    {"turntable", "backend", "", "which drive turns the plate"},
    {"turntable", "disable_at_end", "",
     "remove motor power when a scan ends (completed, failed, aborted, SIGTERM) and when revolve "
     "exits; false keeps the plate held"},
    {"turntable.mock", "speed_deg_per_s", "deg/s", "top speed of the plate"},
    {"turntable.mock", "acceleration_deg_per_s2", "deg/s²", "acceleration and deceleration"},
    {"turntable.mock", "settle_ms", "ms",
     "mechanical settling after the move before \"in position\" (simulated time)"},
    {"turntable.mock", "time_scale", "",
     "real seconds per simulated second: 1 = real time, 0.1 = ten times faster"},
    {"turntable.mock", "tolerance_deg", "degrees", "in-position window"},
    {"turntable.modbus", "transport", "",
     "how the drive is reached: a serial RS-485 line or Modbus TCP"},
    {"turntable.modbus", "port", "",
     "(rtu) the serial device, prefer `/dev/serial/by-id/...`; (tcp) the TCP port",
     "string (rtu) or integer (tcp)", "`\"/dev/ttyUSB0\"` (rtu), `502` (tcp)",
     "rtu: non-empty; tcp: [1, 65535]"},
    {"turntable.modbus", "baud", "bit/s",
     "(rtu) other rates are refused (libmodbus would silently use 9600)", "", "",
     "1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 921600"},
    {"turntable.modbus", "parity", "", "(rtu) serial parity, as set on the drive"},
    {"turntable.modbus", "data_bits", "", "(rtu) serial data bits"},
    {"turntable.modbus", "stop_bits", "", "(rtu) serial stop bits"},
    {"turntable.modbus", "slave_id", "", "(rtu) the drive's address on the bus"},
    {"turntable.modbus", "rs485", "",
     "(rtu) kernel RS-485 mode (TIOCSRS485) for UARTs that need it; USB adapters switch direction "
     "themselves and refuse it"},
    {"turntable.modbus", "host", "", "(tcp) drive or gateway address or name", "",
     "(required with tcp)", ""},
    {"turntable.modbus", "unit_id", "",
     "(tcp) the drive's unit id (behind a gateway: its RS-485 address)"},
    {"turntable.modbus", "connect_timeout_ms", "ms", "TCP connect"},
    {"turntable.modbus", "response_timeout_ms", "ms", "per transaction"},
    {"turntable.modbus", "byte_timeout_ms", "ms", "gap allowed inside a reply; 0 = off"},
    {"turntable.modbus", "retries", "count",
     "extra tries, only for no reply, a lost connection, a bad CRC or \"busy\""},
    {"turntable.modbus", "poll_ms", "ms", "status poll period during a move"},
    {"turntable.modbus", "profile", "",
     "see [Modbus drive profiles](operator-guide.md#modbus-drive-profiles)", "", "",
     "a profile name or a TOML file"},
    {"turntable.modbus", "steps_per_rev", "counts",
     "drive counts per motor turn; 0 = the profile's"},
    {"turntable.modbus", "gear_ratio", "", "motor turns per plate turn"},
    {"turntable.modbus", "direction", "", "flips the sign of every position"},
    {"turntable.modbus", "speed_deg_per_s", "deg/s", "plate cruise speed"},
    {"turntable.modbus", "acceleration_deg_per_s2", "deg/s²",
     "plate acceleration and deceleration"},
    {"turntable.modbus", "tolerance_deg", "degrees",
     "read-back window around the target (the angle is also quantized to half a count)"},
    {"turntable.modbus", "stall_timeout_ms", "ms",
     "no progress this long before the target: *stalled*"},
    {"turntable.modbus", "in_position_polls", "count",
     "consecutive in-position polls that end a move"},
    {"turntable.modbus", "idle_disable_s", "s",
     "power the motor down after this idle time; 0 = never"},
    {"turntable.gpio", "chip", "",
     "chip label (`\"pinctrl-bcm2711\"`, stable), name or `/dev` path", "", "", "non-empty"},
    {"turntable.gpio", "step", "line", "STEP output (a line other than `dir`)", "integer or string",
     "(required)", "a line offset 0–1023 or a line name (`\"GPIO17\"`)"},
    {"turntable.gpio", "dir", "line", "DIR output (a line other than `step`)", "integer or string",
     "(required)", "a line offset 0–1023 or a line name (`\"GPIO17\"`)"},
    {"turntable.gpio", "enable", "line", "ENABLE output, optional", "integer or string", "none",
     "a line offset 0–1023 or a line name (`\"GPIO17\"`)"},
    {"turntable.gpio", "home", "line",
     "home switch input, optional (none: the position at start is home)", "integer or string",
     "none", "a line offset 0–1023 or a line name (`\"GPIO17\"`)"},
    {"turntable.gpio", "step_active_low", "", "STEP is active low"},
    {"turntable.gpio", "dir_active_low", "", "DIR is active low"},
    {"turntable.gpio", "enable_active_low", "", "ENABLE is active low"},
    {"turntable.gpio", "home_active_low", "", "a switch to GND with pull-up"},
    {"turntable.gpio", "home_bias", "", "bias of the home input (kernel ≥ 5.5)"},
    {"turntable.gpio", "full_steps_per_rev", "steps", "motor full steps per turn"},
    {"turntable.gpio", "microsteps", "", "as set on the driver"},
    {"turntable.gpio", "gear_ratio", "", "motor turns per plate turn"},
    {"turntable.gpio", "direction", "", "flips the sign of every move"},
    {"turntable.gpio", "speed_deg_per_s", "deg/s", "plate cruise speed"},
    {"turntable.gpio", "acceleration_deg_per_s2", "deg/s²", "plate acceleration and deceleration"},
    {"turntable.gpio", "max_step_rate_hz", "Hz",
     "cap on the step rate; at most 1 / (2 × `pulse_us`)"},
    {"turntable.gpio", "pulse_us", "µs", "STEP high time (driver minimum, e.g. 2.5 µs for DM542T)"},
    {"turntable.gpio", "dir_setup_us", "µs", "DIR stable before the first STEP edge"},
    {"turntable.gpio", "enable_settle_ms", "ms", "ENABLE asserted before the first step"},
    {"turntable.gpio", "home_speed_deg_per_s", "deg/s", "homing speed"},
    {"turntable.gpio", "home_debounce_ms", "ms", "switch level confirmed this long after its edge"},
    {"turntable.gpio", "home_max_deg", "degrees",
     "search range before \"home switch did not trigger\""},
    {"turntable.gpio", "home_direction", "", "search direction"},
    {"turntable.gpio", "idle_disable_s", "s", "release ENABLE after this idle time; 0 = never"},
    {"turntable.gpio", "realtime", "",
     "step emission under SCHED_FIFO (needs `LimitRTPRIO=` or CAP_SYS_NICE)"},
};

}  // namespace

config::OptionDocs ReferenceDocs() { return {kTables, kKeys}; }

}  // namespace revolve::turntable
