#include "turntable/modbus/modbus_options.h"

#include <algorithm>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "config/reader.h"
#include "turntable/drive_options.h"
#include "turntable/modbus/profile.h"
#include "turntable/modbus/profile_library.h"

namespace revolve::turntable {
namespace {

constexpr int kStandardBauds[] = {1200,  2400,   4800,   9600,   19200,  38400,
                                  57600, 115200, 230400, 460800, 500000, 921600};

}  // namespace

Expected<ModbusOptions> ParseModbusOptions(const config::Section& section) {
  ModbusOptions o;
  config::Reader r(section);
  std::string transport = "rtu";
  r.String("transport", transport, {"rtu", "tcp"});
  o.transport =
      transport == "tcp" ? ModbusOptions::Transport::kTcp : ModbusOptions::Transport::kRtu;
  if (o.transport == ModbusOptions::Transport::kRtu) {
    r.String("port", o.serial_port);
    if (!r.error() && o.serial_port.empty()) {
      r.Fail(section.BadValue("port",
                              "the serial device must not be empty (e.g. "
                              "\"/dev/serial/by-id/usb-FTDI_...\")"));
    }
    r.Integer("baud", o.baud, 300, 4'000'000);
    if (!r.error() && std::find(std::begin(kStandardBauds), std::end(kStandardBauds), o.baud) ==
                          std::end(kStandardBauds)) {
      r.Fail(section.BadValue(
          "baud", fmt::format("{} is not a standard rate (1200 ... 921600); libmodbus would "
                              "silently use 9600: set the drive to a standard rate",
                              o.baud)));
    }
    std::string parity = "none";
    r.String("parity", parity, {"none", "even", "odd"});
    o.parity = parity == "even" ? 'E' : parity == "odd" ? 'O' : 'N';
    r.Integer("data_bits", o.data_bits, 7, 8);
    r.Integer("stop_bits", o.stop_bits, 1, 2);
    r.Integer("slave_id", o.slave_id, 1, 247);
    r.Boolean("rs485", o.rs485);
  } else {
    r.String("host", o.host);
    if (!r.error() && o.host.empty()) {
      r.Fail(section.BadValue("host",
                              "is required with transport = \"tcp\" (the drive's or "
                              "gateway's address)"));
    }
    r.Integer("port", o.tcp_port, 1, 65535);
    r.Integer("unit_id", o.unit_id, 0, 255);
  }
  r.Number("connect_timeout_ms", o.connect_timeout_ms, 1.0, 60000.0);
  r.Number("response_timeout_ms", o.response_timeout_ms, 1.0, 60000.0);
  r.Number("byte_timeout_ms", o.byte_timeout_ms, 0.0, 10000.0);
  r.Integer("retries", o.retries, 0, 10);
  r.Number("poll_ms", o.poll_ms, 1.0, 1000.0);
  r.String("profile", o.profile);
  if (!r.error() && o.profile.empty()) {
    r.Fail(section.BadValue("profile", "must name a profile (e.g. \"generic\") or a file"));
  }
  if (section.origin() != config::kEmbeddedOrigin) {
    o.config_dir = std::filesystem::path(section.origin()).parent_path();
  }
  r.Integer("steps_per_rev", o.steps_per_rev, 0, 100'000'000);
  ReadDriveMotion(r, o);
  r.Number("tolerance_deg", o.tolerance_deg, 0.0, 5.0);
  r.Number("stall_timeout_ms", o.stall_timeout_ms, 10.0, 600000.0);
  r.Integer("in_position_polls", o.in_position_polls, 1, 10);
  r.Number("idle_disable_s", o.idle_disable_s, 0.0, 86400.0);
  if (const auto& error = r.error()) return std::unexpected(*error);

  // The profile is resolved and checked now, so that a config check reports a missing or
  // broken profile, and so that [params] overrides can be checked against its [params].
  Expected<std::filesystem::path> path = modbus::FindProfile(o.profile, o.config_dir);
  if (!path) return std::unexpected(section.BadValue("profile", path.error().message));
  o.profile_path = *path;
  Expected<modbus::DriveProfile> profile = modbus::LoadProfileFile(*path);
  if (!profile) return std::unexpected(profile.error());
  Expected<config::Section> params = section.Child("params");
  if (!params) return std::unexpected(params.error());
  for (const auto& [name, fallback] : profile->params) {
    if (!params->Has(name)) continue;
    Expected<double> value = params->Number(name, fallback, -1e12, 1e12);
    if (!value) return std::unexpected(value.error());
    o.params[name] = *value;
  }
  if (Expected<void> known = params->CheckNoUnknownKeys(); !known) {
    Error error = known.error();
    std::vector<std::string> names;
    for (const auto& [name, value] : profile->params) names.push_back(name);
    error.message +=
        fmt::format(" (profile {} has params: {})", profile->name,
                    names.empty() ? "none" : fmt::format("{}", fmt::join(names, ", ")));
    return std::unexpected(error);
  }
  if (Expected<void> known = section.CheckNoUnknownKeys(); !known) {
    return std::unexpected(known.error());
  }
  return o;
}

std::string DescribeLink(const ModbusOptions& options) {
  if (options.transport == ModbusOptions::Transport::kTcp) {
    return fmt::format("tcp {}:{} unit {}", options.host, options.tcp_port, options.unit_id);
  }
  return fmt::format("rtu {} {} {}{}{} slave {}{}", options.serial_port, options.baud,
                     options.data_bits, options.parity, options.stop_bits, options.slave_id,
                     options.rs485 ? " rs485" : "");
}

}  // namespace revolve::turntable
