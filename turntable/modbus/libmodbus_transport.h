// ModbusTransport over libmodbus 3.1 (RTU on a serial line, or TCP).
//
// Opening: RTU sets the line (baud, parity, data and stop bits), connects, locks the port
// against a second process (flock, which also holds against root, and TIOCEXCL against other
// programs), switches to kernel RS-485 mode when asked, and drops stale input. TCP connects
// within connect_timeout_ms. Then the response and byte timeouts apply to every transaction.
// libmodbus's own error recovery is off: the caller retries and calls Recover().
#pragma once

#include <memory>
#include <string>

#include "base/error.h"
#include "turntable/modbus/modbus_options.h"
#include "turntable/modbus/transport.h"

typedef struct _modbus modbus_t;  // NOLINT: libmodbus's own declaration

namespace revolve::turntable::modbus {

class LibmodbusTransport final : public ModbusTransport {
 public:
  // Opens the link. Errors: not_found (no such serial device), no_device, busy (the port is
  // locked by another process), link_down (TCP refused or unreachable, connect timeout),
  // unsupported (rs485 = true on an adapter without kernel RS-485 support), bad_input.
  static Expected<std::unique_ptr<LibmodbusTransport>> Open(const ModbusOptions& options);

  ~LibmodbusTransport() override;
  LibmodbusTransport(const LibmodbusTransport&) = delete;
  LibmodbusTransport& operator=(const LibmodbusTransport&) = delete;

  TransactionResult<std::vector<std::uint16_t>> Execute(const Request& request) override;
  Expected<void> Recover(bool reopen) override;
  std::string Describe() const override;

 private:
  struct ContextDeleter {
    void operator()(modbus_t* context) const;
  };

  explicit LibmodbusTransport(ModbusOptions options);
  Expected<void> Connect();
  void Close();

  const ModbusOptions options_;
  std::unique_ptr<modbus_t, ContextDeleter> context_;
  int locked_fd_ = -1;  // the serial fd we hold flock/TIOCEXCL on
};

}  // namespace revolve::turntable::modbus
