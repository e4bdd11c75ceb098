// Vocabulary shared by every revolve library: errors as values.
//
// Errors cross module boundaries as `Expected<T>` (std::expected<T, Error>). `code` is what a
// caller acts on (retry, abort, report); `message` is for people and names the file, key or
// device involved and what to do about it.
#pragma once

#include <expected>
#include <string>
#include <string_view>

namespace revolve {

enum class ErrorCode {
  kBadInput,     // a file, option or argument is wrong; fix the input
  kNotFound,     // a file or device does not exist
  kIo,           // reading or writing failed (disk full, permissions)
  kTimeout,      // a deadline passed before the operation finished
  kLinkDown,     // a device connection was lost (transient: may be retried)
  kNoDevice,     // the device is gone (unplugged)
  kStalled,      // a move did not reach its target by the deadline
  kAlarm,        // a drive reported an alarm
  kProtocol,     // a peer answered something malformed
  kAborted,      // the operation was cancelled on request
  kBusy,         // the resource is in use
  kUnsupported,  // the build or the device lacks the feature
  kInternal,     // a bug: an invariant did not hold
};

// Stable lower-case name of a code ("bad_input", "timeout", ...), used in logs and JSON.
std::string_view ToString(ErrorCode code);

struct Error {
  ErrorCode code = ErrorCode::kInternal;
  std::string message;

  // "<code>: <message>"
  std::string ToString() const;
};

template <class T>
using Expected = std::expected<T, Error>;

// Shorthand for `std::unexpected(Error{code, message})`.
inline std::unexpected<Error> MakeError(ErrorCode code, std::string message) {
  return std::unexpected(Error{code, std::move(message)});
}

// Prefixes the message of an error with context ("while reading <file>: ...").
inline Error WithContext(Error error, std::string_view context) {
  error.message = std::string(context) + ": " + error.message;
  return error;
}

}  // namespace revolve

// Inside a function returning Expected<...>: evaluates `expr` (an Expected); on error returns it
// from the enclosing function, else assigns its value to `out`.
#define REVOLVE_ASSIGN_OR_RETURN(out, expr)              \
  do {                                                   \
    auto value_ = (expr);                                \
    if (!value_) return std::unexpected(value_.error()); \
    (out) = *std::move(value_);                          \
  } while (false)

// Inside a function returning Expected<...>: evaluates `expr` (an Expected<void> or any
// Expected); on error returns it from the enclosing function.
#define REVOLVE_RETURN_IF_ERROR(expr)                      \
  do {                                                     \
    if (auto checked_ = (expr); !checked_) {               \
      return std::unexpected(std::move(checked_).error()); \
    }                                                      \
  } while (false)
