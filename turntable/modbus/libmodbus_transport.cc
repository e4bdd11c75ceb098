#include "turntable/modbus/libmodbus_transport.h"

#include <sys/file.h>
#include <sys/ioctl.h>
#include <termios.h>

#include <cerrno>
#include <cmath>
#include <cstring>

#include <fmt/format.h>
#include <modbus/modbus.h>

#include "base/log.h"

namespace revolve::turntable::modbus {
namespace {

void SetTimeout(modbus_t* context, double ms, bool byte_timeout) {
  const auto us = static_cast<std::uint64_t>(std::llround(std::max(0.0, ms) * 1000.0));
  const auto sec = static_cast<std::uint32_t>(us / 1'000'000);
  const auto usec = static_cast<std::uint32_t>(us % 1'000'000);
  if (byte_timeout) {
    modbus_set_byte_timeout(context, sec, usec);
  } else {
    modbus_set_response_timeout(context, sec, usec);
  }
}

bool IsRtu(const ModbusOptions& options) {
  return options.transport == ModbusOptions::Transport::kRtu;
}

}  // namespace

void LibmodbusTransport::ContextDeleter::operator()(modbus_t* context) const {
  modbus_close(context);
  modbus_free(context);
}

LibmodbusTransport::LibmodbusTransport(ModbusOptions options) : options_(std::move(options)) {}

LibmodbusTransport::~LibmodbusTransport() { Close(); }

Expected<std::unique_ptr<LibmodbusTransport>> LibmodbusTransport::Open(
    const ModbusOptions& options) {
  std::unique_ptr<LibmodbusTransport> transport(new LibmodbusTransport(options));
  if (Expected<void> connected = transport->Connect(); !connected) {
    return std::unexpected(connected.error());
  }
  return transport;
}

std::string LibmodbusTransport::Describe() const { return DescribeLink(options_); }

void LibmodbusTransport::Close() {
  if (locked_fd_ >= 0) {
    // A pty keeps TIOCEXCL after we close it (the master stays open): clear it.
    ioctl(locked_fd_, TIOCNXCL);
    flock(locked_fd_, LOCK_UN);
    locked_fd_ = -1;
  }
  context_.reset();
}

Expected<void> LibmodbusTransport::Connect() {
  Close();
  const std::string where = Describe();
  modbus_t* raw = nullptr;
  if (IsRtu(options_)) {
    raw = modbus_new_rtu(options_.serial_port.c_str(), options_.baud, options_.parity,
                         options_.data_bits, options_.stop_bits);
  } else {
    const std::string service = std::to_string(options_.tcp_port);
    raw = modbus_new_tcp_pi(options_.host.c_str(), service.c_str());
  }
  if (raw == nullptr) {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("{}: libmodbus rejected the link settings: {}", where, modbus_strerror(errno)));
  }
  context_.reset(raw);
  modbus_set_error_recovery(raw, MODBUS_ERROR_RECOVERY_NONE);
  const int id = IsRtu(options_) ? options_.slave_id : options_.unit_id;
  if (modbus_set_slave(raw, id) != 0) {
    return MakeError(ErrorCode::kBadInput, fmt::format("{}: invalid slave/unit id {}", where, id));
  }
  // libmodbus bounds the TCP connect by the response timeout.
  SetTimeout(raw, options_.connect_timeout_ms, false);
  if (modbus_connect(raw) != 0) {
    const int error = errno;
    context_.reset();
    if (IsRtu(options_)) {
      if (error == ENOENT) {
        return MakeError(ErrorCode::kNotFound,
                         fmt::format("{}: no such serial device: check the cable and the path "
                                     "(prefer /dev/serial/by-id/...)",
                                     where));
      }
      if (error == EACCES) {
        return MakeError(ErrorCode::kIo,
                         fmt::format("{}: permission denied: add the user to the dialout group "
                                     "(sudo usermod -aG dialout $USER, then log in again)",
                                     where));
      }
      if (error == EBUSY) {
        return MakeError(ErrorCode::kBusy,
                         fmt::format("{}: the serial port is in use by another program", where));
      }
      return MakeError(ErrorCode::kNoDevice, fmt::format("{}: cannot open the serial port: {}",
                                                         where, std::strerror(error)));
    }
    return MakeError(ErrorCode::kLinkDown,
                     fmt::format("{}: cannot connect within {} ms: {} (is the drive or gateway "
                                 "powered, on the network, and listening on this port?)",
                                 where, options_.connect_timeout_ms, modbus_strerror(error)));
  }
  if (IsRtu(options_)) {
    const int fd = modbus_get_socket(raw);
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
      context_.reset();
      return MakeError(ErrorCode::kBusy,
                       fmt::format("{}: the serial port is locked by another process (another "
                                   "revolve, or a stale simulator?): find it with `fuser {}`",
                                   where, options_.serial_port));
    }
    locked_fd_ = fd;
    if (ioctl(fd, TIOCEXCL) != 0) {
      Logger("turntable")->debug("{}: TIOCEXCL failed: {}", where, std::strerror(errno));
    }
    if (options_.rs485) {
      if (modbus_rtu_set_serial_mode(raw, MODBUS_RTU_RS485) != 0) {
        const int error = errno;
        Close();
        return MakeError(ErrorCode::kUnsupported,
                         fmt::format("{}: the adapter has no kernel RS-485 mode ({}); most USB "
                                     "RS-485 adapters switch direction by themselves: set rs485 "
                                     "= false",
                                     where, std::strerror(error)));
      }
    }
  }
  SetTimeout(raw, options_.response_timeout_ms, false);
  SetTimeout(raw, options_.byte_timeout_ms, true);
  // Bytes sent toward the port while nobody listened would be read as the first reply.
  modbus_flush(raw);
  return {};
}

Expected<void> LibmodbusTransport::Recover(bool reopen) {
  if (!reopen && context_) {
    modbus_flush(context_.get());
    return {};
  }
  return Connect();
}

TransactionResult<std::vector<std::uint16_t>> LibmodbusTransport::Execute(const Request& request) {
  if (!context_) {
    return std::unexpected(TransactionError{
        Error{ErrorCode::kLinkDown, fmt::format("{}: the link is closed", Describe())}, true,
        true});
  }
  modbus_t* ctx = context_.get();
  std::vector<std::uint16_t> values;
  int rc = -1;
  int expected = 1;
  switch (request.function) {
    case FunctionCode::kReadHoldingRegisters:
      values.resize(request.count);
      expected = request.count;
      rc = modbus_read_registers(ctx, request.address, request.count, values.data());
      break;
    case FunctionCode::kReadInputRegisters:
      values.resize(request.count);
      expected = request.count;
      rc = modbus_read_input_registers(ctx, request.address, request.count, values.data());
      break;
    case FunctionCode::kWriteSingleRegister:
      rc = modbus_write_register(ctx, request.address, request.values.at(0));
      break;
    case FunctionCode::kWriteMultipleRegisters:
      expected = static_cast<int>(request.values.size());
      rc = modbus_write_registers(ctx, request.address, expected, request.values.data());
      break;
    case FunctionCode::kWriteSingleCoil:
      rc = modbus_write_bit(ctx, request.address, request.values.at(0) != 0 ? 1 : 0);
      break;
  }
  if (rc == expected) {
    if (!request.IsRead()) values.clear();
    return values;
  }
  const int error = rc == -1 ? errno : EMBBADDATA;
  TransactionError failure;
  failure.transient = true;
  failure.error.code = ErrorCode::kProtocol;
  std::string what;
  if (error == ETIMEDOUT) {
    failure.error.code = ErrorCode::kLinkDown;
    what = fmt::format(
        "no reply within {} ms (check the drive's power, the wiring, baud, "
        "parity and {} id)",
        options_.response_timeout_ms, IsRtu(options_) ? "slave" : "unit");
  } else if (error == EMBBADCRC) {
    what =
        "a reply with a bad CRC (noise on the line: check termination, grounding and that "
        "only one master is on the bus)";
  } else if (error == EMBBADDATA || error == EMBMDATA || error == EMBBADSLAVE ||
             error == EMBBADEXC || error == EMBUNKEXC) {
    what = fmt::format("a malformed reply ({})", modbus_strerror(error));
  } else if (error > MODBUS_ENOBASE && error <= EMBXGTAR) {
    const auto code = static_cast<std::uint8_t>(error - MODBUS_ENOBASE);
    failure.transient = error == EMBXSBUSY || error == EMBXACK;
    what = fmt::format("the drive answered exception 0x{:02X} ({}){}", code, ExceptionName(code),
                       code == 0x01 || code == 0x02 || code == 0x03
                           ? ": the profile does not match this drive or its firmware/settings"
                           : "");
  } else {
    failure.error.code = ErrorCode::kLinkDown;
    failure.reconnect = true;
    what = fmt::format("the link failed: {}", modbus_strerror(error));
  }
  failure.error.message = fmt::format("{}: {}: {}", Describe(), modbus::Describe(request), what);
  return std::unexpected(std::move(failure));
}

}  // namespace revolve::turntable::modbus
