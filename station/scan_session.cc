#include "station/scan_session.h"

#include <chrono>
#include <ctime>
#include <thread>

#include <fmt/format.h>

#include "base/log.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/metrics/metrics.h"
#include "station/contact_sheet.h"

namespace revolve::station {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

Clock::time_point DeadlineIn(double seconds) {
  return Clock::now() +
         std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

// UTC, ISO 8601 with milliseconds: "2026-11-21T23:01:05.123Z".
std::string IsoTimeNow() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t seconds = std::chrono::system_clock::to_time_t(now);
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()) % 1000;
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%S", &utc);
  return fmt::format("{}.{:03d}Z", buf, static_cast<int>(ms.count()));
}

nlohmann::json Vec3Json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// Points sampled on the model's surface for the distance to the truth.
constexpr int kSurfaceSamples = 20000;

// The accuracy of `mesh` against a simulated scene's true geometry.
nlohmann::json AccuracyJson(const reconstruct::Mesh& mesh, const reconstruct::MeshStats& stats,
                            const capture::SceneTruth& truth) {
  nlohmann::json j;
  j["truth"] = truth.description;
  j["true_volume_mm3"] = truth.volume_mm3;
  j["volume_error_percent"] = 100.0 * (stats.volume_mm3 - truth.volume_mm3) / truth.volume_mm3;
  if (truth.distance_mm) {
    const reconstruct::DistanceStats d =
        reconstruct::SurfaceDistance(mesh, truth.distance_mm, kSurfaceSamples);
    j["mean_surface_distance_mm"] = d.mean_mm;
    j["rms_surface_distance_mm"] = d.rms_mm;
    j["p90_surface_distance_mm"] = d.p90_mm;
    j["max_surface_distance_mm"] = d.max_mm;
  }
  if (truth.sphere_radius_mm && truth.sphere_center_mm) {
    const reconstruct::SphereFit fit = reconstruct::FitSphere(mesh);
    j["sphere_true_radius_mm"] = *truth.sphere_radius_mm;
    j["sphere_fitted_radius_mm"] = fit.radius_mm;
    j["sphere_radius_error_percent"] =
        100.0 * (fit.radius_mm - *truth.sphere_radius_mm) / *truth.sphere_radius_mm;
    j["sphere_center_error_mm"] = (fit.centre_mm - *truth.sphere_center_mm).norm();
  }
  return j;
}

}  // namespace

Expected<Devices> OpenDevices(const StationConfig& config) {
  Devices devices;
  devices.plate = std::make_shared<SimulatedPlate>();
  auto turntable = turntable::Create(config.turntable, devices.plate);
  if (!turntable) return std::unexpected(turntable.error());
  devices.turntable = std::move(*turntable);
  auto camera = capture::Create(config.camera, devices.plate);
  if (!camera) return std::unexpected(camera.error());
  devices.camera = std::move(*camera);
  auto segmenter = capture::CreateSegmenter(config.segment);
  if (!segmenter) return std::unexpected(segmenter.error());
  devices.segmenter = std::move(*segmenter);
  return devices;
}

nlohmann::json StageTimes::ToJson() const {
  return {{"home_ms", home_ms},       {"move_ms", move_ms},       {"settle_ms", settle_ms},
          {"capture_ms", capture_ms}, {"segment_ms", segment_ms}, {"integrate_ms", integrate_ms},
          {"save_ms", save_ms},       {"mesh_ms", mesh_ms},       {"write_ms", write_ms},
          {"total_ms", total_ms}};
}

ScanSession::ScanSession(const StationConfig& config, Devices& devices, const ScanFolder& folder)
    : config_(config), devices_(devices), folder_(folder) {}

Expected<void> ScanSession::SaveManifest() { return folder_.WriteJson("manifest.json", manifest_); }

Expected<ScanResult> ScanSession::Run(std::stop_token stop) {
  manifest_ = {{"version", 1},
               {"state", "running"},
               {"started", IsoTimeNow()},
               {"config", config_.origin},
               {"stops_planned", config_.scan.stops},
               {"step_deg", config_.scan.step_deg},
               {"turntable", devices_.turntable->Describe()},
               {"camera", devices_.camera->Describe()},
               {"stops", nlohmann::json::array()}};
  if (auto w = folder_.WriteText("scan.toml", config_.text); !w) return std::unexpected(w.error());
  if (auto w = SaveManifest(); !w) return std::unexpected(w.error());

  std::stop_callback stop_motor(stop, [this] { devices_.turntable->Stop(); });
  auto result = RunStops(stop);
  devices_.turntable->Stop();
  devices_.camera->Stop();
  (void)devices_.turntable->Disable();

  manifest_["finished"] = IsoTimeNow();
  if (result) {
    manifest_["state"] = "complete";
  } else {
    manifest_["state"] = result.error().code == ErrorCode::kAborted ? "aborted" : "failed";
    manifest_["error"] = {{"code", ToString(result.error().code)},
                          {"message", result.error().message}};
  }
  if (auto w = SaveManifest(); !w && result) return std::unexpected(w.error());
  return result;
}

Expected<ScanResult> ScanSession::RunStops(std::stop_token stop) {
  auto log = Logger("station");
  const ScanOptions& scan = config_.scan;
  const auto scan_start = Clock::now();

  const std::optional<revolve::Rig> geometry = devices_.camera->KnownRig();
  if (!geometry) {
    return MakeError(ErrorCode::kUnsupported,
                     fmt::format("{}: the camera \"{}\" has no known geometry and this build has "
                                 "no calibration yet; use the synthetic camera",
                                 config_.origin, devices_.camera->Describe()));
  }
  auto reconstructor = reconstruct::Create(config_.reconstruct);
  if (!reconstructor) return std::unexpected(reconstructor.error());

  auto t = Clock::now();
  if (auto homed = devices_.turntable->Home(DeadlineIn(scan.move_timeout_s)); !homed) {
    return std::unexpected(WithContext(homed.error(), "homing the turntable"));
  }
  times_.home_ms = MsSince(t);
  auto format = devices_.camera->Start();
  if (!format) return std::unexpected(WithContext(format.error(), "starting the camera"));

  std::vector<cv::Mat> thumbnails;
  ScanResult result;
  for (int k = 0; k < scan.stops; ++k) {
    if (stop.stop_requested()) {
      return MakeError(ErrorCode::kAborted,
                       fmt::format("aborted after {} of {} stops", k, scan.stops));
    }
    const auto stop_start = Clock::now();
    const double commanded_deg = k * scan.step_deg;

    t = Clock::now();
    if (auto moved = devices_.turntable->MoveTo(commanded_deg, DeadlineIn(scan.move_timeout_s));
        !moved) {
      return std::unexpected(
          WithContext(moved.error(), fmt::format("moving to stop {} ({} deg)", k, commanded_deg)));
    }
    auto state = devices_.turntable->State();
    if (!state) return std::unexpected(WithContext(state.error(), "reading the turntable"));
    times_.move_ms += MsSince(t);

    t = Clock::now();
    std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(scan.settle_ms));
    const auto settled = Clock::now();
    times_.settle_ms += MsSince(t);

    t = Clock::now();
    auto frame = devices_.camera->Capture(
        settled, std::chrono::duration_cast<Clock::duration>(
                     std::chrono::duration<double>(scan.capture_timeout_s)));
    if (!frame) {
      return std::unexpected(WithContext(frame.error(), fmt::format("capturing stop {}", k)));
    }
    times_.capture_ms += MsSince(t);

    t = Clock::now();
    auto mask = devices_.segmenter->Segment(frame->image, cv::Mat());
    if (!mask) {
      return std::unexpected(WithContext(mask.error(), fmt::format("segmenting stop {}", k)));
    }
    times_.segment_ms += MsSince(t);
    const int mask_area_px = cv::countNonZero(*mask);
    if (mask_area_px == 0) log->warn("stop {}: the silhouette is empty", k);

    t = Clock::now();
    View view;
    view.pixel_from_object = geometry->PixelFromObject(state->angle_deg);
    view.width_px = frame->image.cols;
    view.height_px = frame->image.rows;
    if (auto integrated = (*reconstructor)->Integrate(*mask, frame->image, view); !integrated) {
      return std::unexpected(
          WithContext(integrated.error(), fmt::format("integrating stop {}", k)));
    }
    times_.integrate_ms += MsSince(t);

    t = Clock::now();
    const std::string name = StopFileName(k);
    if (auto w = folder_.WriteImage("frames/" + name, frame->image); !w) {
      return std::unexpected(w.error());
    }
    if (auto w = folder_.WriteImage("masks/" + name, *mask); !w) return std::unexpected(w.error());
    thumbnails.push_back(ContactSheetTile(frame->image, *mask));
    manifest_["stops"].push_back({{"index", k},
                                  {"commanded_deg", commanded_deg},
                                  {"readback_deg", state->angle_deg},
                                  {"captured", IsoTimeNow()},
                                  {"frame", "frames/" + name},
                                  {"mask", "masks/" + name},
                                  {"mask_area_px", mask_area_px}});
    manifest_["stops_done"] = k + 1;
    if (auto w = SaveManifest(); !w) return std::unexpected(w.error());
    times_.save_ms += MsSince(t);

    result.stops_done = k + 1;
    if (on_stop_) {
      StopProgress p;
      p.index = k;
      p.stops = scan.stops;
      p.commanded_deg = commanded_deg;
      p.readback_deg = state->angle_deg;
      p.mask_area_px = mask_area_px;
      p.stop_ms = MsSince(stop_start);
      const double per_stop_ms = MsSince(scan_start) / (k + 1);
      p.eta_s = per_stop_ms * (scan.stops - k - 1) / 1000.0;
      on_stop_(p);
    }
  }

  t = Clock::now();
  auto mesh = (*reconstructor)->Finish();
  if (!mesh) return std::unexpected(WithContext(mesh.error(), "meshing"));
  times_.mesh_ms = MsSince(t);

  t = Clock::now();
  auto files =
      reconstruct::WriteModel(*mesh, folder_.model_dir(), "model", config_.reconstruct.formats);
  if (!files) return std::unexpected(files.error());
  for (const auto& f : *files) {
    result.model_files.push_back(std::filesystem::relative(f, folder_.dir()).string());
  }
  if (auto w = folder_.WriteImage("contact_sheet.png", AssembleContactSheet(thumbnails)); !w) {
    return std::unexpected(w.error());
  }
  times_.write_ms = MsSince(t);
  times_.total_ms = MsSince(scan_start);

  const reconstruct::MeshStats stats = reconstruct::ComputeStats(*mesh);
  result.vertices = static_cast<std::size_t>(stats.vertex_count);
  result.triangles = static_cast<std::size_t>(stats.triangle_count);
  result.times = times_;
  nlohmann::json& report = result.report;
  report["stops_done"] = result.stops_done;
  report["units"] = "mm";
  report["scale"] = "metric (simulated rig geometry)";
  report["model"] = {{"files", result.model_files},
                     {"vertices", stats.vertex_count},
                     {"triangles", stats.triangle_count},
                     {"volume_mm3", stats.volume_mm3},
                     {"surface_area_mm2", stats.area_mm2},
                     {"bbox_min_mm", Vec3Json(stats.bbox_min_mm)},
                     {"bbox_max_mm", Vec3Json(stats.bbox_max_mm)},
                     {"dimensions_mm", Vec3Json(stats.bbox_max_mm - stats.bbox_min_mm)},
                     {"watertight", stats.closed},
                     {"consistently_oriented", stats.oriented}};
  report["times_ms"] = times_.ToJson();
  if (auto truth = devices_.camera->KnownScene()) {
    report["accuracy"] = AccuracyJson(*mesh, stats, *truth);
  }
  if (auto w = folder_.WriteJson("report.json", report); !w) return std::unexpected(w.error());
  manifest_["model"] = result.model_files;
  return result;
}

}  // namespace revolve::station
