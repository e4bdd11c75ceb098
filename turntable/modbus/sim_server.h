// The I/O shell of the drive simulator: serves a SimulatedDrive as a Modbus TCP server or as a
// Modbus RTU slave on a serial line (or one end of a pty pair). Framing is revolve's own codec
// (frame.h), not libmodbus, so client and server are independent implementations.
#pragma once

#include <filesystem>
#include <functional>
#include <stop_token>
#include <string>

#include "base/error.h"
#include "turntable/modbus/sim_drive.h"

namespace revolve::turntable::modbus {

struct SimServerOptions {
  enum class Transport { kTcp, kRtu };
  Transport transport = Transport::kTcp;
  // TCP: where to listen; port 0 picks a free port (reported through on_ready / port_file).
  std::string host = "127.0.0.1";
  int port = 0;
  // RTU: the serial device and line settings; only requests for slave_id are answered.
  std::string device;
  int baud = 19200;
  char parity = 'N';
  int data_bits = 8;
  int stop_bits = 1;
  int slave_id = 1;
  // When set, the TCP port actually bound is written here (atomically) once listening.
  std::filesystem::path port_file;
};

// Serves `drive` until `stop` is requested. `on_ready` is called once with a line such as
// "listening on tcp 127.0.0.1:40123" when requests can be served. Errors: bad_input, not_found,
// io (cannot bind or open the device).
Expected<void> RunSimServer(SimulatedDrive& drive, const SimServerOptions& options,
                            std::stop_token stop,
                            const std::function<void(const std::string&)>& on_ready);

}  // namespace revolve::turntable::modbus
