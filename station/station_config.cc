#include "station/station_config.h"

namespace revolve::station {
namespace {

Expected<ScanOptions> ParseScanOptions(const config::Section& s) {
  ScanOptions o;
  auto stops = s.Integer("stops", o.stops, 1, 3600);
  if (!stops) return std::unexpected(stops.error());
  o.stops = static_cast<int>(*stops);
  auto step = s.Number("step_deg", o.step_deg, 0.01, 360.0);
  if (!step) return std::unexpected(step.error());
  o.step_deg = *step;
  auto settle = s.Number("settle_ms", o.settle_ms, 0.0, 60000.0);
  if (!settle) return std::unexpected(settle.error());
  o.settle_ms = *settle;
  auto move_timeout = s.Number("move_timeout_s", o.move_timeout_s, 0.1, 3600.0);
  if (!move_timeout) return std::unexpected(move_timeout.error());
  o.move_timeout_s = *move_timeout;
  auto capture_timeout = s.Number("capture_timeout_s", o.capture_timeout_s, 0.1, 600.0);
  if (!capture_timeout) return std::unexpected(capture_timeout.error());
  o.capture_timeout_s = *capture_timeout;
  if (o.stops * o.step_deg > 360.0 + 1e-9) {
    return std::unexpected(s.BadValue(
        "stops", "stops * step_deg exceeds one revolution (360 deg); lower one of them"));
  }
  if (auto unknown = s.CheckNoUnknownKeys(); !unknown) return std::unexpected(unknown.error());
  return o;
}

}  // namespace

Expected<StationConfig> ParseStationConfig(const config::Document& document) {
  StationConfig cfg;
  cfg.origin = document.origin;
  cfg.text = document.text;
  const config::Section root = config::Section::Root(document);

  // Parses root.<key> with `parse` into `out`. (g++ 12's std::expected has no and_then.)
  auto section = [&root](std::string_view key, auto parse, auto& out) -> Expected<void> {
    auto child = root.Child(key);
    if (!child) return std::unexpected(child.error());
    auto parsed = parse(*child);
    if (!parsed) return std::unexpected(parsed.error());
    out = std::move(*parsed);
    return {};
  };
  for (auto parsed : {section("scan", ParseScanOptions, cfg.scan),
                      section("turntable", turntable::ParseOptions, cfg.turntable),
                      section("camera", capture::ParseOptions, cfg.camera),
                      section("segment", capture::ParseSegmentOptions, cfg.segment),
                      section("reconstruct", reconstruct::ParseOptions, cfg.reconstruct)}) {
    if (!parsed) return std::unexpected(parsed.error());
  }
  if (auto unknown = root.CheckNoUnknownKeys(); !unknown) return std::unexpected(unknown.error());
  return cfg;
}

Expected<StationConfig> LoadStationConfig(const std::optional<std::filesystem::path>& path) {
  auto document = path ? config::LoadFile(*path)
                       : config::Parse(std::string(config::EmbeddedDefault()),
                                       std::string(config::kEmbeddedOrigin));
  if (!document) return std::unexpected(document.error());
  return ParseStationConfig(*document);
}

}  // namespace revolve::station
