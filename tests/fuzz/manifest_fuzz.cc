// Fuzzes the manifest check: no input may throw, and once CheckManifest passes, the reads
// revolve makes of a manifest (reconstruct, resume, list) must not throw either.
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "station/manifest.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const nlohmann::json manifest = nlohmann::json::parse(data, data + size, nullptr, false);
  if (manifest.is_discarded()) return 0;
  if (!revolve::station::CheckManifest(manifest, "fuzz/manifest.json")) return 0;
  // What station/saved_stops.cc, scan_session.cc and daemon.cc read.
  (void)manifest.value("state", std::string());
  (void)manifest.value("recipe", std::string("default"));
  (void)manifest.value("stops_done", 0);
  (void)manifest.value("stops_planned", 0);
  (void)manifest.value("step_deg", -1.0);
  (void)manifest.value("started", std::string());
  (void)manifest.value("finished", std::string());
  if (manifest.contains("error")) (void)manifest["error"].value("message", std::string());
  for (const nlohmann::json& entry : manifest["stops"]) {
    (void)entry["index"].get<int>();
    const double commanded = entry.value("commanded_deg", 0.0);
    (void)entry.value("readback_deg", commanded);
    (void)entry.value("frame", std::string());
    (void)entry.value("mask", std::string());
    if (entry.contains("quality")) {
      for (const nlohmann::json& w : entry["quality"]) {
        (void)w["code"].get<std::string>();
        (void)w["message"].get<std::string>();
      }
    }
  }
  return 0;
}
