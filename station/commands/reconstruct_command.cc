#include "station/commands/reconstruct_command.h"

#include <ostream>

#include <fmt/format.h>
#include <fmt/ostream.h>

#include "base/atomic_file.h"
#include "base/image_read.h"
#include "reconstruct/io/model_writer.h"
#include "reconstruct/metrics/metrics.h"
#include "station/commands/scan_command.h"
#include "station/report_json.h"
#include "station/saved_stops.h"
#include "station/scan_folder.h"
#include "station/scan_geometry.h"
#include "station/station_config.h"

namespace revolve::station {
namespace {

Expected<void> WriteReport(const std::filesystem::path& file, const std::filesystem::path& dir,
                           const nlohmann::json& manifest,
                           const reconstruct::ReconstructOptions& recon,
                           const ScanGeometry& geometry, const reconstruct::MeshStats& stats,
                           const std::vector<std::filesystem::path>& files,
                           std::size_t stops_used) {
  nlohmann::json report = {{"source", "revolve reconstruct"},
                           {"scan_dir", dir.string()},
                           {"scan_id", manifest.value("scan_id", std::string())},
                           {"recipe", manifest.value("recipe", std::string("default"))},
                           {"method", recon.method},
                           {"resolution", recon.resolution},
                           {"stops_used", stops_used},
                           {"stops_planned", manifest.value("stops_planned", 0)}};
  report.update(geometry.ReportJson());
  const std::string unit = geometry.metric() ? "mm" : "px";
  std::vector<std::string> names;
  names.reserve(files.size());
  for (const auto& f : files) names.push_back(f.filename().string());
  report["model"] = ModelReportJson(names, stats, unit);
  const std::string text = report.dump(2) + "\n";
  return WriteFileAtomically(file, std::string_view(text));
}

}  // namespace

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
  // The output folder first: a read-only or unwritable one is said before any work.
  const std::filesystem::path out_dir = options.out ? *options.out : dir / "model";
  if (auto made = CreateOutputFolder(out_dir); !made) {
    fmt::print(err, "revolve reconstruct: {}\n", made.error().message);
    return kExitFailed;
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
  // A camera whose own geometry carves must be the one the scan was made with: a scan.toml
  // changed or cut short (still valid TOML, so other defaults) would carve with other views.
  if (geometry->source() == GeometrySource::kCamera) {
    const std::string recorded = manifest->value("camera", std::string());
    if (!recorded.empty() && recorded != (*camera)->Describe()) {
      fmt::print(err,
                 "revolve reconstruct: {}: the camera it describes ({}) is not the one "
                 "{} records for this scan ({}): scan.toml was changed or cut short; restore it\n",
                 (dir / "scan.toml").string(), (*camera)->Describe(),
                 (dir / "manifest.json").string(), recorded);
      return kExitConfig;
    }
  }
  std::vector<std::string> skipped;
  auto stops = ReadSavedStops(dir, *manifest, false, &skipped);
  if (!stops) {
    fmt::print(err, "revolve reconstruct: {}\n", stops.error().message);
    return kExitFailed;
  }
  for (const std::string& s : skipped) fmt::print(err, "revolve reconstruct: skipped {}\n", s);
  if (stops->empty()) {
    if (skipped.empty()) {
      fmt::print(err,
                 "revolve reconstruct: {}: stops: lists no stop (nothing was captured): nothing "
                 "to reconstruct\n",
                 (dir / "manifest.json").string());
    } else {
      fmt::print(err, "revolve reconstruct: {}: no stop with a readable mask (see above)\n",
                 dir.string());
    }
    return kExitFailed;
  }
  // The masks against the camera of scan.toml (or the calibration): another size would carve
  // with the wrong view.
  if (auto size = geometry->CheckFrameSize(stops->front().mask.cols, stops->front().mask.rows);
      !size) {
    fmt::print(err, "revolve reconstruct: {}: {}\n", (dir / stops->front().mask_file).string(),
               size.error().message);
    return kExitConfig;
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
    cv::Mat frame;
    if (!s.frame_file.empty()) {
      ImageReadOptions read;
      read.imread_flags = cv::IMREAD_COLOR;
      read.expected_size = s.mask.size();
      if (Expected<cv::Mat> loaded = ReadImageFile(dir / s.frame_file, read); loaded) {
        frame = std::move(*loaded);
      } else {
        fmt::print(err,
                   "revolve reconstruct: warning: stop {} ({} stops[{}].frame): {}; the stop is "
                   "carved but gives no colour\n",
                   s.index, (dir / "manifest.json").string(), s.manifest_position,
                   loaded.error().message);
      }
    }
    if (cv::countNonZero(s.mask) == 0) {
      fmt::print(err, "revolve reconstruct: stop {}: the silhouette is empty; not used\n", s.index);
      continue;
    }
    if (auto integrated = geometry->Integrate(s.mask, frame, s.readback_deg); !integrated) {
      fmt::print(err, "revolve reconstruct: stop {}: {}\n", s.index, integrated.error().message);
      return kExitFailed;
    }
  }
  // The files are written while the mesh is made (reconstruct/io/model_writer.h).
  reconstruct::Mesh mesh;  // before the writer, which borrows it
  auto writer = reconstruct::ModelWriter::Start(mesh, out_dir, "model", recon.formats);
  if (!writer) {
    fmt::print(err, "revolve reconstruct: {}\n", writer.error().message);
    return kExitFailed;
  }
  if (auto made = geometry->Finish(&mesh, (*writer)->Hook()); !made) {
    fmt::print(err, "revolve reconstruct: meshing: {}\n", made.error().message);
    return kExitFailed;
  }
  auto files = (*writer)->Finish();
  if (!files) {
    fmt::print(err, "revolve reconstruct: {}\n", files.error().message);
    return kExitFailed;
  }
  const reconstruct::MeshStats stats = reconstruct::ComputeStats(mesh);
  // The report of this model, next to it: the scan's own report.json when the model replaces
  // the scan's, else in --out. A report of an earlier model is never left beside a new one.
  const std::filesystem::path report_file =
      options.out ? *options.out / "report.json" : dir / "report.json";
  if (auto w =
          WriteReport(report_file, dir, *manifest, recon, *geometry, stats, *files, stops->size());
      !w) {
    fmt::print(err, "revolve reconstruct: {}\n", w.error().message);
    return kExitFailed;
  }
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
