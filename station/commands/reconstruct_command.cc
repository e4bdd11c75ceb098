#include "station/commands/reconstruct_command.h"

#include <ostream>

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <opencv2/imgcodecs.hpp>

#include "reconstruct/io/mesh_io.h"
#include "reconstruct/metrics/metrics.h"
#include "station/commands/scan_command.h"
#include "station/saved_stops.h"
#include "station/scan_folder.h"
#include "station/scan_geometry.h"
#include "station/station_config.h"

namespace revolve::station {

int RunReconstructCommand(const ReconstructCommandOptions& options, std::stop_token stop,
                          std::ostream& out, std::ostream& err) {
  const std::filesystem::path& dir = options.scan_dir;
  auto manifest = ReadManifest(dir);
  if (!manifest) {
    fmt::print(err, "revolve reconstruct: {}\n", manifest.error().message);
    return kExitFailed;
  }
  auto config = LoadStationConfig(dir / "scan.toml");
  if (!config) {
    fmt::print(err, "revolve reconstruct: {}\n", config.error().message);
    return kExitConfig;
  }
  reconstruct::ReconstructOptions recon = config->reconstruct;
  if (options.method) recon.method = *options.method;
  if (options.resolution) recon.resolution = *options.resolution;
  if (options.formats) recon.formats = *options.formats;
  auto camera = capture::Create(config->camera, std::make_shared<SimulatedPlate>());
  if (!camera) {
    fmt::print(err, "revolve reconstruct: {}: {}\n", (dir / "scan.toml").string(),
               camera.error().message);
    return kExitConfig;
  }
  // The scan's own camera model: its copy of the calibration, the camera's geometry, or the
  // thesis's (station/scan_geometry.h). Its frames and masks are already undistorted.
  std::error_code ec;
  const std::filesystem::path calibration_file =
      std::filesystem::exists(dir / "calibration.toml", ec) ? dir / "calibration.toml" : "";
  auto geometry = ScanGeometry::Create(recon, **camera, calibration_file);
  if (!geometry) {
    fmt::print(err, "revolve reconstruct: {}\n", geometry.error().message);
    return kExitConfig;
  }
  std::vector<std::string> skipped;
  auto stops = ReadSavedStops(dir, *manifest, false, &skipped);
  if (!stops) {
    fmt::print(err, "revolve reconstruct: {}\n", stops.error().message);
    return kExitFailed;
  }
  for (const std::string& s : skipped) fmt::print(err, "revolve reconstruct: skipped {}\n", s);
  if (stops->empty()) {
    fmt::print(err, "revolve reconstruct: {}: no stop with a readable mask\n", dir.string());
    return kExitFailed;
  }
  const int planned = manifest->value("stops_planned", 0);
  fmt::print(out,
             "revolve reconstruct: {} ({}), {} of {} stops, {} at resolution {}, {} geometry\n",
             dir.string(), manifest->value("state", std::string("unknown")), stops->size(), planned,
             recon.method, recon.resolution, ToString(geometry->source()));
  for (SavedStop& s : *stops) {
    if (stop.stop_requested()) {
      fmt::print(err, "revolve reconstruct: aborted\n");
      return kExitAborted;
    }
    cv::Mat frame = cv::imread((dir / s.frame_file).string(), cv::IMREAD_COLOR);
    if (frame.size() != s.mask.size()) frame.release();
    if (cv::countNonZero(s.mask) == 0) {
      fmt::print(err, "revolve reconstruct: stop {}: the silhouette is empty; not used\n", s.index);
      continue;
    }
    if (auto integrated = geometry->Integrate(s.mask, frame, s.readback_deg); !integrated) {
      fmt::print(err, "revolve reconstruct: stop {}: {}\n", s.index, integrated.error().message);
      return kExitFailed;
    }
  }
  auto mesh = geometry->Finish();
  if (!mesh) {
    fmt::print(err, "revolve reconstruct: meshing: {}\n", mesh.error().message);
    return kExitFailed;
  }
  const std::filesystem::path out_dir = options.out ? *options.out : dir / "model";
  std::filesystem::create_directories(out_dir, ec);
  auto files = reconstruct::WriteModel(*mesh, out_dir, "model", recon.formats);
  if (!files) {
    fmt::print(err, "revolve reconstruct: {}\n", files.error().message);
    return kExitFailed;
  }
  const reconstruct::MeshStats stats = reconstruct::ComputeStats(*mesh);
  std::string names;
  for (const auto& f : *files) names += (names.empty() ? "" : ", ") + f.string();
  const std::string unit = geometry->metric() ? "mm" : "px";
  fmt::print(out, "  model  {} ({} triangles, {}), volume {:.0f} {}^3{}\n", names,
             stats.triangle_count, stats.closed ? "watertight" : "NOT watertight", stats.volume_mm3,
             unit, geometry->metric() ? "" : " (thesis mode: scale unknown)");
  if (static_cast<int>(stops->size()) < planned) {
    fmt::print(out,
               "  note   built from {} of {} stops: `revolve start --resume {}` captures the "
               "rest\n",
               stops->size(), planned, dir.filename().string());
  }
  return kExitOk;
}

}  // namespace revolve::station
