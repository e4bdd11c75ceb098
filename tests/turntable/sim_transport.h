// An in-process ModbusTransport over a SimulatedDrive: the libmodbus seam of the fault tests.
// Lost requests become "no reply" (instantly: no timeout is waited), corrupt replies a bad CRC,
// exception replies protocol errors, exactly as LibmodbusTransport reports them.
#pragma once

#include <atomic>
#include <memory>

#include "turntable/modbus/sim_drive.h"
#include "turntable/modbus/transport.h"

namespace revolve::turntable::modbus::test_support {

class SimTransport final : public ModbusTransport {
 public:
  explicit SimTransport(std::shared_ptr<SimulatedDrive> drive) : drive_(std::move(drive)) {}

  TransactionResult<std::vector<std::uint16_t>> Execute(const Request& request) override {
    ++requests_;
    const std::vector<std::uint8_t> pdu = EncodeRequestPdu(request);
    const SimReply reply = drive_->Handle(pdu, std::chrono::steady_clock::now());
    auto fail = [this, &request](ErrorCode code, std::string what, bool transient) {
      ++failures_;
      return std::unexpected(TransactionError{
          Error{code, "sim: " + modbus::Describe(request) + ": " + std::move(what)}, transient,
          false});
    };
    if (reply.action == SimReply::Action::kDrop)
      return fail(ErrorCode::kLinkDown, "no reply", true);
    if (reply.action == SimReply::Action::kCorrupt) {
      return fail(ErrorCode::kProtocol, "a reply with a bad CRC", true);
    }
    if (reply.pdu.size() == 2 && (reply.pdu[0] & 0x80) != 0) {
      return fail(ErrorCode::kProtocol, "exception " + ExceptionName(reply.pdu[1]),
                  reply.pdu[1] == 0x06);
    }
    std::vector<std::uint16_t> values;
    if (request.IsRead()) {
      for (std::size_t i = 0; i < request.count; ++i) {
        values.push_back(
            static_cast<std::uint16_t>(reply.pdu[2 + 2 * i] << 8 | reply.pdu[3 + 2 * i]));
      }
    }
    return values;
  }

  Expected<void> Recover(bool /*reopen*/) override {
    ++recoveries_;
    return {};
  }

  std::string Describe() const override { return "in-process simulated drive"; }

  int requests() const { return requests_.load(); }
  int failures() const { return failures_.load(); }
  int recoveries() const { return recoveries_.load(); }

 private:
  std::shared_ptr<SimulatedDrive> drive_;
  std::atomic<int> requests_{0};
  std::atomic<int> failures_{0};
  std::atomic<int> recoveries_{0};
};

}  // namespace revolve::turntable::modbus::test_support
