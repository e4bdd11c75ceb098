#include "base/error.h"

namespace revolve {

std::string_view ToString(ErrorCode code) {
  switch (code) {
    case ErrorCode::kBadInput:
      return "bad_input";
    case ErrorCode::kNotFound:
      return "not_found";
    case ErrorCode::kIo:
      return "io";
    case ErrorCode::kTimeout:
      return "timeout";
    case ErrorCode::kLinkDown:
      return "link_down";
    case ErrorCode::kNoDevice:
      return "no_device";
    case ErrorCode::kStalled:
      return "stalled";
    case ErrorCode::kAlarm:
      return "alarm";
    case ErrorCode::kProtocol:
      return "protocol";
    case ErrorCode::kAborted:
      return "aborted";
    case ErrorCode::kBusy:
      return "busy";
    case ErrorCode::kUnsupported:
      return "unsupported";
    case ErrorCode::kInternal:
      return "internal";
  }
  return "internal";
}

std::string Error::ToString() const {
  return std::string(revolve::ToString(code)) + ": " + message;
}

}  // namespace revolve
