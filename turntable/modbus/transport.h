// The seam between the Modbus turntable and the wire: one request, one answer. The real
// implementation is libmodbus (libmodbus_transport.h); tests substitute an in-process simulated
// drive and inject faults a real peer cannot produce on demand.
#pragma once

#include <cstdint>
#include <expected>
#include <string>
#include <vector>

#include "base/error.h"
#include "turntable/modbus/frame.h"

namespace revolve::turntable::modbus {

// A failed transaction and what may help.
struct TransactionError {
  Error error;             // link_down (no reply, connection lost, device gone) or protocol
  bool transient = false;  // worth another try: no reply, a lost connection, a bad CRC, busy
  bool reconnect = false;  // the link should be re-opened before trying again
};

template <class T>
using TransactionResult = std::expected<T, TransactionError>;

class ModbusTransport {
 public:
  virtual ~ModbusTransport() = default;

  // Sends `request` and waits (bounded by the transport's response timeout) for the answer.
  // Reads return request.count registers; writes return an empty vector. An exception
  // response is a protocol error naming the exception. Not thread-safe: callers serialize.
  virtual TransactionResult<std::vector<std::uint16_t>> Execute(const Request& request) = 0;

  // Gets the link usable again after a transient error: drops stale input and, when
  // `reopen`, closes and re-opens the connection. Errors: link_down, no_device, busy.
  virtual Expected<void> Recover(bool reopen) = 0;

  // "rtu /dev/ttyUSB0 38400 8N1 slave 1" style.
  virtual std::string Describe() const = 0;
};

}  // namespace revolve::turntable::modbus
