// The scan as an explicit state machine. Pure: no I/O, time passed in.
//
//   idle -> homing -> { moving -> settling -> capturing -> integrating }* -> meshing -> writing
//        -> done
//   any non-terminal state -> failed | aborted
//   done | failed | aborted -> homing (the next scan)
//
// Every transition yields one ScanEvent, which the daemon streams on its socket and logs once.
// A note (a capture re-try, a resumed scan) is an event that keeps the state.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "base/error.h"

namespace revolve::station {

enum class ScanState {
  kIdle,
  kHoming,
  kMoving,
  kSettling,
  kCapturing,    // capture and segment
  kIntegrating,  // integrate the silhouette and save the stop (frame, mask, manifest)
  kMeshing,
  kWriting,
  kDone,
  kFailed,
  kAborted,
};

// "idle", "homing", ..., "aborted".
std::string_view ToString(ScanState state);
std::optional<ScanState> ScanStateFromString(std::string_view name);

bool IsTerminal(ScanState state);  // done, failed, aborted
bool IsActive(ScanState state);    // homing .. writing: a scan is running
bool IsPerStop(ScanState state);   // moving .. integrating

// Whether `from` -> `to` is a transition of the machine above.
bool IsAllowedTransition(ScanState from, ScanState to);

struct ScanEvent {
  std::uint64_t seq = 0;  // 1, 2, ... per machine
  ScanState state = ScanState::kIdle;
  std::string scan_id;
  int stop = -1;           // the stop being worked on (0-based), -1 outside the stops
  int stops = 0;           // planned
  int stops_done = 0;      // saved so far
  double angle_deg = 0.0;  // commanded angle of `stop`
  double progress = 0.0;   // 0..1
  double elapsed_s = 0.0;
  std::optional<double> eta_s;      // unknown before the first stop is done
  std::optional<int> mask_area_px;  // integrating: the stop's silhouette area
  std::string note;                 // a note event's text; a terminal event's reason or result
  std::optional<Error> error;       // failed / aborted
  std::optional<int> alarm_code;
  std::string alarm_text;
  std::string time;  // UTC ISO 8601, set by whoever emits the event

  nlohmann::json ToJson() const;
};

// Parses ToJson()'s output (for clients). Unknown fields are ignored.
Expected<ScanEvent> ScanEventFromJson(const nlohmann::json& json);

class ScanStateMachine {
 public:
  using Clock = std::chrono::steady_clock;

  // A scan `scan_id` of `stops` stops, `stops_done` of them already saved (a resumed scan).
  ScanStateMachine(std::string scan_id, int stops, int stops_done, Clock::time_point start);

  ScanState state() const { return state_; }
  int stops_done() const { return stops_done_; }

  // Enters `next` (for per-stop states: stop `stop` at `angle_deg`). Errors: internal for a
  // transition the machine does not have (the state is unchanged).
  Expected<ScanEvent> Enter(ScanState next, Clock::time_point now, int stop = -1,
                            double angle_deg = 0.0);

  // Enters failed or aborted (by `error.code`), with the reason and the drive's alarm if any.
  Expected<ScanEvent> Fail(const Error& error, Clock::time_point now,
                           std::optional<int> alarm_code = std::nullopt,
                           std::string alarm_text = {});

  // Counts a stop as saved (no event: the next one carries it).
  void StopSaved();

  // An event that keeps the state (a re-try, a warning).
  ScanEvent Note(std::string text, Clock::time_point now);

  // The current state as an event (seq of the last event).
  ScanEvent Snapshot(Clock::time_point now) const;

 private:
  ScanEvent Make(Clock::time_point now) const;

  std::string scan_id_;
  int stops_;
  int stops_done_;
  int resumed_stops_;
  Clock::time_point start_;
  std::optional<Clock::time_point> first_stop_start_;
  ScanState state_ = ScanState::kIdle;
  int stop_ = -1;
  double angle_deg_ = 0.0;
  std::uint64_t seq_ = 0;
  std::string note_;
  std::optional<Error> error_;
  std::optional<int> alarm_code_;
  std::string alarm_text_;
};

// Progress 0..1 of a scan in `state` with `stops_done` of `stops` saved: the stops weigh 90%,
// meshing and writing the rest.
double ScanProgress(ScanState state, int stops_done, int stops);

}  // namespace revolve::station
