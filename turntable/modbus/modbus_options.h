// Options of the Modbus turntable backend ([turntable.modbus]) and their parser. Always built,
// also without libmodbus, so that `revolve check-config` validates a real rig's config anywhere.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>

#include "base/error.h"
#include "config/config.h"

namespace revolve::turntable {

struct ModbusOptions {
  enum class Transport { kRtu, kTcp };
  Transport transport = Transport::kRtu;  // transport = "rtu" | "tcp"

  // RTU (serial line).
  std::string serial_port = "/dev/ttyUSB0";  // key `port` (a path) with transport = "rtu"
  int baud = 19200;    // a standard rate 1200..921600 (not 25000/256000: libmodbus falls
                       // back to 9600 for those)
  char parity = 'N';   // key parity = "none" | "even" | "odd"
  int data_bits = 8;   // 7 | 8
  int stop_bits = 1;   // 1 | 2
  int slave_id = 1;    // 1..247
  bool rs485 = false;  // kernel RS-485 mode (TIOCSRS485); only for UARTs that support it

  // TCP.
  std::string host;    // required with transport = "tcp"
  int tcp_port = 502;  // key `port` (a number) with transport = "tcp"
  int unit_id = 1;     // 0..255

  // Link timing.
  double connect_timeout_ms = 1000.0;  // [1, 60000]
  double response_timeout_ms = 300.0;  // [1, 60000]
  double byte_timeout_ms = 50.0;       // [0, 10000], 0 = off
  int retries = 2;                     // [0, 10], transient link errors only
  double poll_ms = 20.0;               // [1, 1000], status poll period during a move

  // The drive.
  std::string profile = "generic";     // a profile name, or a path to a profile file
  std::filesystem::path config_dir;    // directory of the config file: relative profile paths
  std::filesystem::path profile_path;  // resolved by ParseModbusOptions
  std::map<std::string, double, std::less<>> params;  // [turntable.modbus.params] overrides

  // Kinematics.
  std::int64_t steps_per_rev = 0;         // drive counts per motor rev; 0 = the profile's
  double gear_ratio = 1.0;                // motor revs per plate rev, (0, 1000]
  bool reverse = false;                   // direction = "forward" | "reverse"
  double speed_deg_per_s = 30.0;          // plate cruise speed, (0, 3600]
  double acceleration_deg_per_s2 = 90.0;  // plate acceleration, (0, 100000]
  double tolerance_deg = 0.05;            // in-position window on the read-back angle, [0, 5]
  double stall_timeout_ms = 1000.0;  // no progress this long during a move: stalled, [10, 600000]
  int in_position_polls = 1;         // consecutive in-position polls to finish a move, [1, 10]
  double idle_disable_s = 0.0;       // power the motor down after this idle time; 0 = never
};

// Parses [turntable.modbus] (`section`) and resolves and loads the profile it names (so a bad
// profile is a config error). Errors: bad_input with file:line:column and the key; the profile's
// own errors name the profile file.
Expected<ModbusOptions> ParseModbusOptions(const config::Section& section);

// "rtu /dev/ttyUSB0 38400 8N1 slave 1" or "tcp 10.0.0.5:502 unit 1".
std::string DescribeLink(const ModbusOptions& options);

}  // namespace revolve::turntable
