// Modbus application protocol framing: pure byte encoding and decoding, no I/O.
//
// The client side of revolve talks through libmodbus; this codec is used to render golden
// frames (what a profile command puts on the wire) and by the drive simulator's server, which
// is deliberately a second, independent implementation of the protocol.
//
// References: "MODBUS Application Protocol Specification V1.1b3" (PDUs, exception codes) and
// "MODBUS over Serial Line V1.02" (RTU ADU, CRC-16 0xA001 reflected, low byte first).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"

namespace revolve::turntable::modbus {

enum class FunctionCode : std::uint8_t {
  kReadHoldingRegisters = 0x03,
  kReadInputRegisters = 0x04,
  kWriteSingleCoil = 0x05,
  kWriteSingleRegister = 0x06,
  kWriteMultipleRegisters = 0x10,
};

// Exception codes a server puts in an exception response (function | 0x80, code).
enum class ExceptionCode : std::uint8_t {
  kIllegalFunction = 0x01,
  kIllegalDataAddress = 0x02,
  kIllegalDataValue = 0x03,
  kServerDeviceFailure = 0x04,
  kAcknowledge = 0x05,
  kServerDeviceBusy = 0x06,
};

// Human words for an exception code ("illegal data address"); "exception 0x.." for others.
std::string ExceptionName(std::uint8_t code);

// Protocol limits (spec §6.3, §6.12).
inline constexpr int kMaxReadRegisters = 125;
inline constexpr int kMaxWriteRegisters = 123;

// One request, independent of the transport.
//  - reads (0x03, 0x04): `address`, `count` registers; `values` empty.
//  - write single register (0x06): `address`, `values` = {value}.
//  - write multiple registers (0x10): `address`, `values` (1..123 of them).
//  - write single coil (0x05): `address`, `values` = {0 or 1} (sent as 0x0000 / 0xFF00).
struct Request {
  FunctionCode function = FunctionCode::kReadHoldingRegisters;
  std::uint16_t address = 0;
  std::uint16_t count = 0;
  std::vector<std::uint16_t> values;

  bool IsRead() const;
  bool operator==(const Request&) const = default;
};

// "FC16 write 0x00FE = [0x00F0, 0x0014, 0x0000, 0x3039]" style, for logs and test failures.
std::string Describe(const Request& request);

// Request PDU bytes (function code + data). Contract: `request` well-formed as described above.
std::vector<std::uint8_t> EncodeRequestPdu(const Request& request);

// CRC-16/MODBUS of `bytes` (polynomial 0xA001 reflected, initial 0xFFFF).
std::uint16_t Crc16(std::span<const std::uint8_t> bytes);

// RTU ADU: slave address, PDU, CRC (low byte first).
std::vector<std::uint8_t> EncodeRtuAdu(std::uint8_t slave, std::span<const std::uint8_t> pdu);

// TCP ADU: MBAP header (transaction id, protocol 0, length, unit id) then the PDU.
std::vector<std::uint8_t> EncodeTcpAdu(std::uint16_t transaction, std::uint8_t unit,
                                       std::span<const std::uint8_t> pdu);

// Upper-case hex with spaces ("01 06 00 F3 00 01 79 F9"); and back (spaces optional).
std::string ToHex(std::span<const std::uint8_t> bytes);
std::vector<std::uint8_t> FromHex(std::string_view hex);

// --- Server side (the drive simulator) ---

// A request PDU the server could not accept: the exception to answer with.
struct PduRejection {
  ExceptionCode exception = ExceptionCode::kIllegalFunction;
};

// Decodes a request PDU. Unknown function codes give kIllegalFunction; wrong lengths, counts or
// coil values give kIllegalDataValue.
std::expected<Request, PduRejection> DecodeRequestPdu(std::span<const std::uint8_t> pdu);

// Response PDU for a served request: reads carry `read_values` (request.count of them); writes
// echo address and value/count as the spec says.
std::vector<std::uint8_t> EncodeResponsePdu(const Request& request,
                                            std::span<const std::uint16_t> read_values);

// Exception response PDU: (function | 0x80, code).
std::vector<std::uint8_t> EncodeExceptionPdu(std::uint8_t function, ExceptionCode code);

// Length in bytes of the RTU request ADU at the start of `bytes` (slave, PDU, CRC), computed
// from the function code: nullopt while too few bytes are there to tell; 0 when the function
// code is unknown (the server then waits for the line to go quiet and drops the bytes).
std::optional<std::size_t> RtuRequestLength(std::span<const std::uint8_t> bytes);

}  // namespace revolve::turntable::modbus
