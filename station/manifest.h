// The checks of a scan folder's manifest.json when revolve reads it back (`revolve reconstruct
// SCAN_DIR`, `revolve start --resume`, `revolve list`): every field revolve reads has the type
// and range it wrote, and the stops do not contradict each other. Pure: no files.
#pragma once

#include <string_view>

#include <nlohmann/json.hpp>

#include "base/error.h"

namespace revolve::station {

// The most stops a manifest may list (a scan has at most 3600: [scan] stops).
inline constexpr int kMaxManifestStops = 3600;

// The most a stop's read-back angle may differ from its commanded one (any drive's tolerance is
// smaller).
inline constexpr double kMaxReadbackErrorDeg = 5.0;

// The states a manifest's "state" may hold.
inline constexpr std::string_view kManifestStates[] = {"running", "complete", "failed", "aborted"};

// OK when `manifest` is what revolve writes as far as revolve reads it:
// - an object; "stops" an array of at most kMaxManifestStops objects;
// - each stop: "index" an integer in [0, stops_planned) (or [0, kMaxManifestStops)), listed
//   once; "commanded_deg" and "readback_deg" finite numbers, "frame" and "mask" strings naming a
//   file inside the scan folder (relative, no ".."), "quality" an array of {"code", "message"}
//   strings, when present; "commanded_deg" is index * step_deg, and "readback_deg" within
//   kMaxReadbackErrorDeg of it;
// - "stops_planned" an integer in [1, kMaxManifestStops], "step_deg" a finite number in
//   (0, 360], "stops_done" a non-negative integer, "state" one of kManifestStates, "scan_id",
//   "recipe", "started", "finished", "config" strings, "resumed" an array, "error" an object
//   whose "message" and "code" are strings, when present.
// Else bad_input "<origin>: <field path>: <what is wrong>" (e.g. "scans/x/manifest.json:
// stops[3].readback_deg: expected a finite number, got null"). Once it passes, reading those
// fields with nlohmann::json::value() cannot throw.
Expected<void> CheckManifest(const nlohmann::json& manifest, std::string_view origin);

}  // namespace revolve::station
