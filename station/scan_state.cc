#include "station/scan_state.h"

#include <algorithm>
#include <array>
#include <utility>

#include <fmt/format.h>

namespace revolve::station {
namespace {

constexpr std::array<std::pair<ScanState, std::string_view>, 11> kNames = {{
    {ScanState::kIdle, "idle"},
    {ScanState::kHoming, "homing"},
    {ScanState::kMoving, "moving"},
    {ScanState::kSettling, "settling"},
    {ScanState::kCapturing, "capturing"},
    {ScanState::kIntegrating, "integrating"},
    {ScanState::kMeshing, "meshing"},
    {ScanState::kWriting, "writing"},
    {ScanState::kDone, "done"},
    {ScanState::kFailed, "failed"},
    {ScanState::kAborted, "aborted"},
}};

constexpr std::array<std::pair<ErrorCode, std::string_view>, 13> kCodes = {{
    {ErrorCode::kBadInput, "bad_input"},
    {ErrorCode::kNotFound, "not_found"},
    {ErrorCode::kIo, "io"},
    {ErrorCode::kTimeout, "timeout"},
    {ErrorCode::kLinkDown, "link_down"},
    {ErrorCode::kNoDevice, "no_device"},
    {ErrorCode::kStalled, "stalled"},
    {ErrorCode::kAlarm, "alarm"},
    {ErrorCode::kProtocol, "protocol"},
    {ErrorCode::kAborted, "aborted"},
    {ErrorCode::kBusy, "busy"},
    {ErrorCode::kUnsupported, "unsupported"},
    {ErrorCode::kInternal, "internal"},
}};

ErrorCode ErrorCodeFromString(std::string_view name) {
  for (const auto& [code, text] : kCodes) {
    if (text == name) return code;
  }
  return ErrorCode::kInternal;
}

double Seconds(ScanStateMachine::Clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

}  // namespace

std::string_view ToString(ScanState state) {
  for (const auto& [s, name] : kNames) {
    if (s == state) return name;
  }
  return "unknown";
}

std::optional<ScanState> ScanStateFromString(std::string_view name) {
  for (const auto& [s, text] : kNames) {
    if (text == name) return s;
  }
  return std::nullopt;
}

bool IsTerminal(ScanState state) {
  return state == ScanState::kDone || state == ScanState::kFailed || state == ScanState::kAborted;
}

bool IsActive(ScanState state) { return state != ScanState::kIdle && !IsTerminal(state); }

bool IsPerStop(ScanState state) {
  return state == ScanState::kMoving || state == ScanState::kSettling ||
         state == ScanState::kCapturing || state == ScanState::kIntegrating;
}

bool IsAllowedTransition(ScanState from, ScanState to) {
  using S = ScanState;
  if (to == S::kFailed || to == S::kAborted) return IsActive(from);
  switch (from) {
    case S::kIdle:
    case S::kDone:
    case S::kFailed:
    case S::kAborted:
      return to == S::kHoming;
    case S::kHoming:
      // A resumed scan whose stops are all saved goes straight to meshing.
      return to == S::kMoving || to == S::kMeshing;
    case S::kMoving:
      return to == S::kSettling;
    case S::kSettling:
      return to == S::kCapturing;
    case S::kCapturing:
      return to == S::kIntegrating;
    case S::kIntegrating:
      return to == S::kMoving || to == S::kMeshing;
    case S::kMeshing:
      return to == S::kWriting;
    case S::kWriting:
      return to == S::kDone;
  }
  return false;
}

double ScanProgress(ScanState state, int stops_done, int stops) {
  constexpr double kStopsShare = 0.9;
  switch (state) {
    case ScanState::kIdle:
      return 0.0;
    case ScanState::kMeshing:
      return kStopsShare;
    case ScanState::kWriting:
      return 0.97;
    case ScanState::kDone:
      return 1.0;
    default:
      break;
  }
  if (stops <= 0) return 0.0;
  return kStopsShare * std::clamp(static_cast<double>(stops_done) / stops, 0.0, 1.0);
}

nlohmann::json ScanEvent::ToJson() const {
  nlohmann::json j = {{"seq", seq},
                      {"state", ToString(state)},
                      {"scan_id", scan_id},
                      {"stop", stop},
                      {"stops", stops},
                      {"stops_done", stops_done},
                      {"angle_deg", angle_deg},
                      {"progress", progress},
                      {"elapsed_s", elapsed_s},
                      {"eta_s", eta_s ? nlohmann::json(*eta_s) : nlohmann::json(nullptr)}};
  if (mask_area_px) j["mask_area_px"] = *mask_area_px;
  if (!note.empty()) j["note"] = note;
  if (error) {
    j["error"] = {{"code", revolve::ToString(error->code)}, {"message", error->message}};
  }
  if (alarm_code) j["alarm"] = {{"code", *alarm_code}, {"text", alarm_text}};
  if (!time.empty()) j["time"] = time;
  return j;
}

Expected<ScanEvent> ScanEventFromJson(const nlohmann::json& j) {
  if (!j.is_object()) return MakeError(ErrorCode::kProtocol, "an event must be a JSON object");
  ScanEvent e;
  try {
    const auto state = ScanStateFromString(j.value("state", std::string()));
    if (!state) return MakeError(ErrorCode::kProtocol, "an event names no known state");
    e.state = *state;
    e.seq = j.value("seq", std::uint64_t{0});
    e.scan_id = j.value("scan_id", std::string());
    e.stop = j.value("stop", -1);
    e.stops = j.value("stops", 0);
    e.stops_done = j.value("stops_done", 0);
    e.angle_deg = j.value("angle_deg", 0.0);
    e.progress = j.value("progress", 0.0);
    e.elapsed_s = j.value("elapsed_s", 0.0);
    if (j.contains("eta_s") && j["eta_s"].is_number()) e.eta_s = j["eta_s"].get<double>();
    if (j.contains("mask_area_px") && j["mask_area_px"].is_number_integer()) {
      e.mask_area_px = j["mask_area_px"].get<int>();
    }
    e.note = j.value("note", std::string());
    if (j.contains("error") && j["error"].is_object()) {
      e.error = Error{ErrorCodeFromString(j["error"].value("code", std::string())),
                      j["error"].value("message", std::string())};
    }
    if (j.contains("alarm") && j["alarm"].is_object()) {
      e.alarm_code = j["alarm"].value("code", 0);
      e.alarm_text = j["alarm"].value("text", std::string());
    }
    e.time = j.value("time", std::string());
  } catch (const nlohmann::json::exception& ex) {
    return MakeError(ErrorCode::kProtocol, fmt::format("malformed event: {}", ex.what()));
  }
  return e;
}

ScanStateMachine::ScanStateMachine(std::string scan_id, int stops, int stops_done,
                                   Clock::time_point start)
    : scan_id_(std::move(scan_id)),
      stops_(stops),
      stops_done_(stops_done),
      resumed_stops_(stops_done),
      start_(start) {}

ScanEvent ScanStateMachine::Make(Clock::time_point now) const {
  ScanEvent e;
  e.seq = seq_;
  e.state = state_;
  e.scan_id = scan_id_;
  e.stop = stop_;
  e.stops = stops_;
  e.stops_done = stops_done_;
  e.angle_deg = angle_deg_;
  e.progress = ScanProgress(state_, stops_done_, stops_);
  e.elapsed_s = Seconds(now - start_);
  if (state_ == ScanState::kDone) {
    e.eta_s = 0.0;
  } else if (IsActive(state_) && first_stop_start_ && stops_done_ > resumed_stops_) {
    const double per_stop_s = Seconds(now - *first_stop_start_) / (stops_done_ - resumed_stops_);
    e.eta_s = per_stop_s * (stops_ - stops_done_);
  }
  e.note = note_;
  e.error = error_;
  e.alarm_code = alarm_code_;
  e.alarm_text = alarm_text_;
  return e;
}

Expected<ScanEvent> ScanStateMachine::Enter(ScanState next, Clock::time_point now, int stop,
                                            double angle_deg) {
  if (next == ScanState::kFailed || next == ScanState::kAborted) {
    return Fail(Error{next == ScanState::kAborted ? ErrorCode::kAborted : ErrorCode::kInternal,
                      std::string(ToString(next))},
                now);
  }
  if (!IsAllowedTransition(state_, next)) {
    return MakeError(ErrorCode::kInternal, fmt::format("scan state machine: no transition {} -> {}",
                                                       ToString(state_), ToString(next)));
  }
  if (IsTerminal(state_) || state_ == ScanState::kIdle) {
    // A new scan on the same machine.
    error_.reset();
    alarm_code_.reset();
    alarm_text_.clear();
  }
  if (next == ScanState::kMoving && !first_stop_start_) first_stop_start_ = now;
  state_ = next;
  stop_ = IsPerStop(next) ? stop : -1;
  angle_deg_ = IsPerStop(next) ? angle_deg : 0.0;
  note_.clear();
  ++seq_;
  return Make(now);
}

Expected<ScanEvent> ScanStateMachine::Fail(const Error& error, Clock::time_point now,
                                           std::optional<int> alarm_code, std::string alarm_text) {
  const ScanState next =
      error.code == ErrorCode::kAborted ? ScanState::kAborted : ScanState::kFailed;
  if (!IsAllowedTransition(state_, next)) {
    return MakeError(ErrorCode::kInternal, fmt::format("scan state machine: no transition {} -> {}",
                                                       ToString(state_), ToString(next)));
  }
  state_ = next;
  error_ = error;
  alarm_code_ = alarm_code;
  alarm_text_ = std::move(alarm_text);
  note_ = error.message;
  ++seq_;
  return Make(now);
}

void ScanStateMachine::StopSaved() { ++stops_done_; }

ScanEvent ScanStateMachine::Note(std::string text, Clock::time_point now) {
  ++seq_;
  ScanEvent e = Make(now);
  e.note = std::move(text);
  return e;
}

ScanEvent ScanStateMachine::Snapshot(Clock::time_point now) const { return Make(now); }

}  // namespace revolve::station
