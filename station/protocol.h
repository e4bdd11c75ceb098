// The control socket's protocol: one JSON object per line, both ways (UTF-8, "\n"-terminated).
//
// Requests (an optional "id" of any JSON scalar is echoed in the reply):
//   {"cmd": "status"}
//   {"cmd": "start", "recipe": "quick"}        recipe optional ([station] recipe by default)
//   {"cmd": "start", "resume": "<scan id>"}    finish an interrupted scan
//   {"cmd": "abort"}
//   {"cmd": "watch"}                            the status, then every event until disconnect
//   {"cmd": "list"}                             the scans in the scans folder
// Replies:
//   {"ok": true, ...}                           "status": {...} | "scan": {...} | "scans": [...]
//   {"ok": false, "error": {"code": "busy", "message": "..."}}
// Events (after watch):
//   {"event": {"seq": 7, "state": "capturing", "stop": 3, "stops": 36, ...}}
//
// Pure: parsing and formatting only; the daemon does the I/O.
#pragma once

#include <cstddef>
#include <deque>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "station/scan_state.h"

namespace revolve::station {

enum class RequestKind { kStatus, kStart, kAbort, kWatch, kList };

struct Request {
  RequestKind kind = RequestKind::kStatus;
  std::optional<std::string> recipe;  // start
  std::optional<std::string> resume;  // start: a scan id
  nlohmann::json id;                  // echoed; null when absent
};

// Longest recipe name or scan id accepted.
inline constexpr std::size_t kMaxNameBytes = 128;

// True for a scan id that is a plain folder name: [A-Za-z0-9._-]+, not "." or "..", at most
// kMaxNameBytes. (A resumed scan's id becomes a path.)
bool IsValidScanId(std::string_view id);

// Parses one request line (without its "\n"). Errors: protocol (not JSON, not an object, a
// field of the wrong type), bad_input (an unknown command, a bad scan id, resume with recipe).
// The error's Request id, when one could be read, is put in `id` (may be null).
Expected<Request> ParseRequest(std::string_view line, nlohmann::json* id);

// A reply line ("...\n"): {"ok": true, "id": ..., fields...} / {"ok": false, "id": ..., "error"}.
std::string OkLine(const nlohmann::json& id, nlohmann::json fields = nlohmann::json::object());
std::string ErrorLine(const nlohmann::json& id, const Error& error);
// {"event": {...}}\n
std::string EventLine(const ScanEvent& event);

// Splits a byte stream into lines of at most `max_line_bytes` (without the "\n"). A longer line
// is reported once as too long and skipped up to its "\n".
class LineSplitter {
 public:
  explicit LineSplitter(std::size_t max_line_bytes) : max_(max_line_bytes) {}

  void Append(std::string_view bytes);

  enum class Kind { kLine, kTooLong };
  struct Item {
    Kind kind;
    std::string line;
  };
  // The next complete line (or too-long notice), if any.
  std::optional<Item> Next();

  // Bytes held: the incomplete line.
  std::size_t partial_bytes() const { return partial_.size(); }

 private:
  std::size_t max_;
  std::string partial_;
  std::deque<Item> items_;
  bool skipping_ = false;  // inside a too-long line, dropping up to its "\n"
};

}  // namespace revolve::station
