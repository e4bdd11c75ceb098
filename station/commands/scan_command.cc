#include "station/commands/scan_command.h"

#include <ostream>
#include <set>

#include <fmt/format.h>
#include <fmt/ostream.h>

#include "station/scan_folder.h"
#include "station/scan_session.h"
#include "station/station_config.h"

namespace revolve::station {
namespace {

std::string Seconds(double ms) { return fmt::format("{:.2f} s", ms / 1000.0); }

void PrintSummary(std::ostream& out, const ScanFolder& folder, const StationConfig& config,
                  const ScanResult& r) {
  const StageTimes& t = r.times;
  fmt::print(out, "\nrevolve scan: complete\n");
  fmt::print(out, "  scan folder  {}\n", folder.dir().string());
  fmt::print(out, "  stops        {}/{} at {} deg\n", r.stops_done, config.scan.stops,
             config.scan.step_deg);
  fmt::print(out,
             "  time         home {}, move {}, settle {}, capture {}, segment {}, integrate {}, "
             "save {}, mesh {}, write {}; total {}\n",
             Seconds(t.home_ms), Seconds(t.move_ms), Seconds(t.settle_ms), Seconds(t.capture_ms),
             Seconds(t.segment_ms), Seconds(t.integrate_ms), Seconds(t.save_ms), Seconds(t.mesh_ms),
             Seconds(t.write_ms), Seconds(t.total_ms));
  const nlohmann::json& model = r.report["model"];
  std::string files;
  for (const auto& f : r.model_files) files += (files.empty() ? "" : ", ") + f;
  fmt::print(out, "  model        {} ({} triangles, {} vertices, {})\n", files, r.triangles,
             r.vertices, model["watertight"].get<bool>() ? "watertight" : "NOT watertight");
  const std::string unit = r.report.value("units", std::string("mm"));
  const auto& dim = model["dimensions_" + unit];
  fmt::print(out, "  size         {:.1f} x {:.1f} x {:.1f} {}, volume {:.0f} {}^3{}\n",
             dim[0].get<double>(), dim[1].get<double>(), dim[2].get<double>(), unit,
             model["volume_" + unit + "3"].get<double>(), unit,
             unit == "mm" ? "" : " (no calibration: scale unknown)");
  if (r.report.contains("accuracy")) {
    const nlohmann::json& a = r.report["accuracy"];
    fmt::print(out, "  accuracy     against the true {}: volume {:+.2f}%",
               a["truth"].get<std::string>(), a["volume_error_percent"].get<double>());
    if (a.contains("mean_surface_distance_mm")) {
      fmt::print(out, ", surface distance mean {:.3f} mm, max {:.3f} mm",
                 a["mean_surface_distance_mm"].get<double>(),
                 a["max_surface_distance_mm"].get<double>());
    }
    if (a.contains("sphere_fitted_radius_mm")) {
      fmt::print(out, ", radius {:.3f} mm (true {:.3f}, {:+.3f}%)",
                 a["sphere_fitted_radius_mm"].get<double>(),
                 a["sphere_true_radius_mm"].get<double>(),
                 a["sphere_radius_error_percent"].get<double>());
    }
    fmt::print(out, "\n");
  }
  if (const auto& warnings = r.report.value("quality_warnings", nlohmann::json::array());
      !warnings.empty()) {
    std::set<int> stops;
    for (const auto& w : warnings) stops.insert(w["stop"].get<int>());
    fmt::print(out,
               "  warnings     {} quality warning(s) at {} stop(s); see \"quality\" in "
               "manifest.json and contact_sheet.png\n",
               warnings.size(), stops.size());
  }
  fmt::print(out, "  pictures     {}/frames, masks, contact_sheet.png; report.json\n",
             folder.dir().string());
}

}  // namespace

int RunScanCommand(const ScanCommandOptions& options, std::stop_token stop, std::ostream& out,
                   std::ostream& err) {
  auto base = LoadStationConfig(options.config);
  if (!base) {
    fmt::print(err, "revolve scan: {}\n", base.error().message);
    return kExitConfig;
  }
  auto config = ApplyRecipe(*base, options.recipe.value_or(""));
  if (!config) {
    fmt::print(err, "revolve scan: {}\n", config.error().message);
    return kExitConfig;
  }
  if (auto checked = CheckWithoutDevices(*config); !checked) {
    fmt::print(err, "revolve scan: {}\n", checked.error().message);
    return kExitConfig;
  }
  auto devices = OpenDevices(*config);
  if (!devices) {
    fmt::print(err, "revolve scan: {}\n", devices.error().message);
    return kExitConfig;
  }
  // Probe the camera before a folder is made: a missing device is a configuration error
  // (exit 78, nothing created) whatever the backend, as a missing drive is.
  if (auto started = devices->camera->Start(); !started) {
    fmt::print(err, "revolve scan: camera: {} (check [camera] in {})\n", started.error().message,
               config->origin);
    return started.error().code == ErrorCode::kBusy ? kExitBusy : kExitConfig;
  }
  devices->camera->Stop();
  const std::filesystem::path dir =
      options.out ? *options.out : "scans" / std::filesystem::path(NewScanId());
  auto folder = ScanFolder::Create(dir);
  if (!folder) {
    fmt::print(err, "revolve scan: {}\n", folder.error().message);
    return kExitFailed;
  }
  folder->SetByteLimit(config->station.simulate.disk_limit_bytes);
  fmt::print(out, "revolve scan: {} stops of {} deg (recipe {}), {} / {} -> {}\n",
             config->scan.stops, config->scan.step_deg, config->recipe,
             devices->turntable->Describe(), devices->camera->Describe(), dir.string());
  ScanSession session(*config, *devices, *folder);
  session.OnStop([&out](const StopProgress& p) {
    fmt::print(out,
               "[{:>3}/{}] {:6.1f} deg (read back {:7.2f})  silhouette {:>7} px  {:5.0f} ms  ETA "
               "{:5.1f} s\n",
               p.index + 1, p.stops, p.commanded_deg, p.readback_deg, p.mask_area_px, p.stop_ms,
               p.eta_s);
    out.flush();
  });
  session.OnEvent([&err](const ScanEvent& e) {
    if (!e.note.empty() && !IsTerminal(e.state)) fmt::print(err, "revolve scan: {}\n", e.note);
  });
  auto result = session.Run(stop);
  if (!result) {
    fmt::print(err, "revolve scan: {}: {} (the scan folder {} keeps what was captured)\n",
               result.error().code == ErrorCode::kAborted ? "aborted" : "failed",
               result.error().message, dir.string());
    return result.error().code == ErrorCode::kAborted ? kExitAborted : kExitFailed;
  }
  PrintSummary(out, *folder, *config, *result);
  return kExitOk;
}

}  // namespace revolve::station
