#include "turntable/modbus/frame.h"

#include <cctype>

#include <fmt/format.h>

namespace revolve::turntable::modbus {
namespace {

void PutU16(std::vector<std::uint8_t>& out, std::uint16_t value) {
  out.push_back(static_cast<std::uint8_t>(value >> 8));
  out.push_back(static_cast<std::uint8_t>(value & 0xFF));
}

std::uint16_t GetU16(std::span<const std::uint8_t> bytes, std::size_t at) {
  return static_cast<std::uint16_t>((bytes[at] << 8) | bytes[at + 1]);
}

}  // namespace

std::string ExceptionName(std::uint8_t code) {
  switch (code) {
    case 0x01:
      return "illegal function";
    case 0x02:
      return "illegal data address";
    case 0x03:
      return "illegal data value";
    case 0x04:
      return "server device failure";
    case 0x05:
      return "acknowledge";
    case 0x06:
      return "server device busy";
    case 0x08:
      return "memory parity error";
    case 0x0A:
      return "gateway path unavailable";
    case 0x0B:
      return "gateway target device failed to respond";
    default:
      return fmt::format("exception 0x{:02X}", code);
  }
}

bool Request::IsRead() const {
  return function == FunctionCode::kReadHoldingRegisters ||
         function == FunctionCode::kReadInputRegisters;
}

std::string Describe(const Request& request) {
  switch (request.function) {
    case FunctionCode::kReadHoldingRegisters:
      return fmt::format("FC03 read holding 0x{:04X} x{}", request.address, request.count);
    case FunctionCode::kReadInputRegisters:
      return fmt::format("FC04 read input 0x{:04X} x{}", request.address, request.count);
    case FunctionCode::kWriteSingleCoil:
      return fmt::format("FC05 write coil 0x{:04X} = {}", request.address,
                         request.values.empty() ? 0 : request.values[0] != 0);
    case FunctionCode::kWriteSingleRegister:
      return fmt::format("FC06 write 0x{:04X} = 0x{:04X}", request.address,
                         request.values.empty() ? 0 : request.values[0]);
    case FunctionCode::kWriteMultipleRegisters: {
      std::string values;
      for (std::uint16_t v : request.values) {
        values += fmt::format("{}0x{:04X}", values.empty() ? "" : ", ", v);
      }
      return fmt::format("FC16 write 0x{:04X} = [{}]", request.address, values);
    }
  }
  return "unknown request";
}

std::vector<std::uint8_t> EncodeRequestPdu(const Request& request) {
  std::vector<std::uint8_t> pdu;
  pdu.push_back(static_cast<std::uint8_t>(request.function));
  PutU16(pdu, request.address);
  switch (request.function) {
    case FunctionCode::kReadHoldingRegisters:
    case FunctionCode::kReadInputRegisters:
      PutU16(pdu, request.count);
      break;
    case FunctionCode::kWriteSingleCoil:
      PutU16(pdu, request.values.at(0) != 0 ? 0xFF00 : 0x0000);
      break;
    case FunctionCode::kWriteSingleRegister:
      PutU16(pdu, request.values.at(0));
      break;
    case FunctionCode::kWriteMultipleRegisters:
      PutU16(pdu, static_cast<std::uint16_t>(request.values.size()));
      pdu.push_back(static_cast<std::uint8_t>(request.values.size() * 2));
      for (std::uint16_t v : request.values) PutU16(pdu, v);
      break;
  }
  return pdu;
}

std::uint16_t Crc16(std::span<const std::uint8_t> bytes) {
  std::uint16_t crc = 0xFFFF;
  for (std::uint8_t byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 1) != 0 ? static_cast<std::uint16_t>((crc >> 1) ^ 0xA001)
                           : static_cast<std::uint16_t>(crc >> 1);
    }
  }
  return crc;
}

std::vector<std::uint8_t> EncodeRtuAdu(std::uint8_t slave, std::span<const std::uint8_t> pdu) {
  std::vector<std::uint8_t> adu;
  adu.reserve(pdu.size() + 3);
  adu.push_back(slave);
  adu.insert(adu.end(), pdu.begin(), pdu.end());
  const std::uint16_t crc = Crc16(adu);
  adu.push_back(static_cast<std::uint8_t>(crc & 0xFF));
  adu.push_back(static_cast<std::uint8_t>(crc >> 8));
  return adu;
}

std::vector<std::uint8_t> EncodeTcpAdu(std::uint16_t transaction, std::uint8_t unit,
                                       std::span<const std::uint8_t> pdu) {
  std::vector<std::uint8_t> adu;
  PutU16(adu, transaction);
  PutU16(adu, 0);
  PutU16(adu, static_cast<std::uint16_t>(pdu.size() + 1));
  adu.push_back(unit);
  adu.insert(adu.end(), pdu.begin(), pdu.end());
  return adu;
}

std::string ToHex(std::span<const std::uint8_t> bytes) {
  std::string out;
  for (std::uint8_t b : bytes) out += fmt::format("{}{:02X}", out.empty() ? "" : " ", b);
  return out;
}

std::vector<std::uint8_t> FromHex(std::string_view hex) {
  std::vector<std::uint8_t> out;
  int high = -1;
  for (char c : hex) {
    if (std::isxdigit(static_cast<unsigned char>(c)) == 0) continue;
    const int nibble = std::isdigit(static_cast<unsigned char>(c)) != 0
                           ? c - '0'
                           : std::tolower(static_cast<unsigned char>(c)) - 'a' + 10;
    if (high < 0) {
      high = nibble;
    } else {
      out.push_back(static_cast<std::uint8_t>(high << 4 | nibble));
      high = -1;
    }
  }
  return out;
}

std::expected<Request, PduRejection> DecodeRequestPdu(std::span<const std::uint8_t> pdu) {
  auto reject = [](ExceptionCode code) { return std::unexpected(PduRejection{code}); };
  if (pdu.empty()) return reject(ExceptionCode::kIllegalFunction);
  Request request;
  const std::uint8_t function = pdu[0];
  switch (function) {
    case 0x03:
    case 0x04: {
      if (pdu.size() != 5) return reject(ExceptionCode::kIllegalDataValue);
      request.function = static_cast<FunctionCode>(function);
      request.address = GetU16(pdu, 1);
      request.count = GetU16(pdu, 3);
      if (request.count < 1 || request.count > kMaxReadRegisters) {
        return reject(ExceptionCode::kIllegalDataValue);
      }
      return request;
    }
    case 0x05: {
      if (pdu.size() != 5) return reject(ExceptionCode::kIllegalDataValue);
      const std::uint16_t value = GetU16(pdu, 3);
      if (value != 0xFF00 && value != 0x0000) return reject(ExceptionCode::kIllegalDataValue);
      request.function = FunctionCode::kWriteSingleCoil;
      request.address = GetU16(pdu, 1);
      request.values = {static_cast<std::uint16_t>(value != 0 ? 1 : 0)};
      return request;
    }
    case 0x06: {
      if (pdu.size() != 5) return reject(ExceptionCode::kIllegalDataValue);
      request.function = FunctionCode::kWriteSingleRegister;
      request.address = GetU16(pdu, 1);
      request.values = {GetU16(pdu, 3)};
      return request;
    }
    case 0x10: {
      if (pdu.size() < 6) return reject(ExceptionCode::kIllegalDataValue);
      const std::uint16_t count = GetU16(pdu, 3);
      const std::size_t byte_count = pdu[5];
      if (count < 1 || count > kMaxWriteRegisters || byte_count != std::size_t{count} * 2u ||
          pdu.size() != 6 + byte_count) {
        return reject(ExceptionCode::kIllegalDataValue);
      }
      request.function = FunctionCode::kWriteMultipleRegisters;
      request.address = GetU16(pdu, 1);
      for (std::size_t i = 0; i < count; ++i) request.values.push_back(GetU16(pdu, 6 + 2 * i));
      return request;
    }
    default:
      return reject(ExceptionCode::kIllegalFunction);
  }
}

std::vector<std::uint8_t> EncodeResponsePdu(const Request& request,
                                            std::span<const std::uint16_t> read_values) {
  std::vector<std::uint8_t> pdu;
  pdu.push_back(static_cast<std::uint8_t>(request.function));
  switch (request.function) {
    case FunctionCode::kReadHoldingRegisters:
    case FunctionCode::kReadInputRegisters:
      pdu.push_back(static_cast<std::uint8_t>(read_values.size() * 2));
      for (std::uint16_t v : read_values) PutU16(pdu, v);
      break;
    case FunctionCode::kWriteSingleCoil:
    case FunctionCode::kWriteSingleRegister: {
      // The response echoes the request.
      return EncodeRequestPdu(request);
    }
    case FunctionCode::kWriteMultipleRegisters:
      PutU16(pdu, request.address);
      PutU16(pdu, static_cast<std::uint16_t>(request.values.size()));
      break;
  }
  return pdu;
}

std::vector<std::uint8_t> EncodeExceptionPdu(std::uint8_t function, ExceptionCode code) {
  return {static_cast<std::uint8_t>(function | 0x80), static_cast<std::uint8_t>(code)};
}

std::optional<std::size_t> RtuRequestLength(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < 2) return std::nullopt;
  switch (bytes[1]) {
    case 0x03:
    case 0x04:
    case 0x05:
    case 0x06:
      return 8;  // slave, function, 2 x u16, CRC
    case 0x10:
      if (bytes.size() < 7) return std::nullopt;
      return 7 + static_cast<std::size_t>(bytes[6]) + 2;
    default:
      return 0;
  }
}

}  // namespace revolve::turntable::modbus
