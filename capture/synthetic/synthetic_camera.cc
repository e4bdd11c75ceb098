#include "capture/synthetic/synthetic_camera.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <utility>

#include <fmt/format.h>

#include "base/log.h"
#include "capture/synthetic/mesh.h"

namespace revolve::capture {
namespace {

// Nominal exposure reported with every frame (the renderer has no motion blur).
constexpr double kExposureUs = 10000.0;

double Milliseconds(Clock::duration d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

Expected<void> CheckRange(std::string_view key, double value, OptionRange range) {
  if (std::isfinite(value) && value >= range.min && value <= range.max) return {};
  return MakeError(ErrorCode::kBadInput,
                   fmt::format("[camera.synthetic] {} = {} is out of range [{}, {}]", key, value,
                               range.min, range.max));
}

}  // namespace

Expected<Scene> SceneFromOptions(const SyntheticOptions& options) {
  auto shape = ParseShape(options.object);
  if (!shape) return std::unexpected(shape.error());
  if (*shape != Shape::kMesh) return Scene::Create(*shape, options.radius_mm, options.height_mm);
  if (options.mesh_path.empty()) {
    return MakeError(ErrorCode::kBadInput,
                     "object = \"mesh\" needs mesh_path (an OBJ or PLY file)");
  }
  auto mesh = ReadMesh(options.mesh_path);
  if (!mesh) return std::unexpected(mesh.error());
  // Turn the file's up axis into +z (right-handed rotations).
  for (auto& v : mesh->vertices) {
    if (options.mesh_up == "y") {
      v = Eigen::Vector3d(v.x(), -v.z(), v.y());
    } else if (options.mesh_up == "x") {
      v = Eigen::Vector3d(v.y(), v.z(), v.x());
    } else if (options.mesh_up != "z") {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("mesh_up = \"{}\" is not one of x, y, z", options.mesh_up));
    }
  }
  return Scene::CreateMesh(*mesh, options.height_mm,
                           std::filesystem::path(options.mesh_path).filename().string());
}

Rig RigFromOptions(const SyntheticOptions& options) {
  Rig rig;
  rig.intrinsics =
      Intrinsics::FromFieldOfView(options.width_px, options.height_px, options.hfov_deg);
  rig.intrinsics.cx_px += options.axis_offset_px;
  rig.cam_from_table = CamFromTableLookingAtAxis(options.distance_mm, options.elevation_deg,
                                                 options.target_height_mm);
  if (options.roll_deg != 0.0) {
    rig.cam_from_table.prerotate(
        Eigen::AngleAxisd(options.roll_deg * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()));
  }
  return rig;
}

SimProjection ProjectionFromOptions(const SyntheticOptions& options) {
  SimProjection projection(RigFromOptions(options));
  projection.orthographic = options.projection == "orthographic";
  projection.px_per_mm = projection.rig.intrinsics.fx_px / options.distance_mm;
  return projection;
}

namespace {

Eigen::Vector3f Colour(const std::vector<double>& bgr, const Eigen::Vector3f& fallback) {
  if (bgr.size() != 3) return fallback;
  return Eigen::Vector3f(static_cast<float>(bgr[0]), static_cast<float>(bgr[1]),
                         static_cast<float>(bgr[2]));
}

}  // namespace

RenderSettings RenderSettingsFromOptions(const SyntheticOptions& options) {
  RenderSettings settings;
  const float grey = static_cast<float>(options.backdrop_grey);
  settings.backdrop_bgr = Colour(options.backdrop_bgr, Eigen::Vector3f(grey, grey, grey));
  settings.object_albedo = static_cast<float>(options.object_albedo);
  settings.speckle = options.texture == "speckle";
  settings.noise_sigma = options.noise_sigma;
  settings.blur_sigma_px = options.blur_sigma_px;
  settings.seed = options.seed;
  settings.stage.plate_radius_mm = options.plate_radius_mm;
  settings.stage.plate_thickness_mm = options.plate_thickness_mm;
  settings.stage.plate_top_bgr = Colour(options.plate_top_bgr, settings.backdrop_bgr);
  settings.stage.plate_rim_bgr = Colour(options.plate_rim_bgr, settings.stage.plate_rim_bgr);
  const Eigen::Vector3f fixture_bgr = Colour(options.fixture_bgr, Fixture{}.bgr);
  for (std::size_t i = 0; i + 5 < options.fixture_mm.size(); i += 6) {
    Fixture f;
    const auto& b = options.fixture_mm;
    f.min_mm = Eigen::Vector3d(std::min(b[i], b[i + 3]), std::min(b[i + 1], b[i + 4]),
                               std::min(b[i + 2], b[i + 5]));
    f.max_mm = Eigen::Vector3d(std::max(b[i], b[i + 3]), std::max(b[i + 1], b[i + 4]),
                               std::max(b[i + 2], b[i + 5]));
    f.bgr = fixture_bgr;
    settings.stage.fixtures.push_back(f);
  }
  return settings;
}

Expected<void> CheckCameraOutsideObject(const SyntheticOptions& options, const Scene& scene) {
  const Eigen::Vector3d camera_table =
      RigFromOptions(options).cam_from_table.inverse().translation();
  const bool outside = camera_table.head<2>().norm() > scene.bounding_radius_mm() ||
                       camera_table.z() < 0.0 || camera_table.z() > scene.height_mm();
  if (outside) return {};
  return MakeError(ErrorCode::kBadInput,
                   fmt::format("distance_mm = {} puts the camera inside the {}'s enclosing "
                               "cylinder; move it farther away",
                               options.distance_mm, scene.Describe()));
}

Expected<void> CheckCameraOutsideObject(const SyntheticOptions& options) {
  auto scene = SceneFromOptions(options);
  if (!scene) return std::unexpected(scene.error());
  return CheckCameraOutsideObject(options, *scene);
}

namespace {

// Range checks of every field (not the scene).
Expected<void> CheckRanges(const SyntheticOptions& options) {
  const std::pair<std::string_view, std::pair<double, OptionRange>> checks[] = {
      {"width_px", {options.width_px, kImageSidePxRange}},
      {"height_px", {options.height_px, kImageSidePxRange}},
      {"hfov_deg", {options.hfov_deg, kHfovDegRange}},
      {"distance_mm", {options.distance_mm, kDistanceMmRange}},
      {"elevation_deg", {options.elevation_deg, kElevationDegRange}},
      {"target_height_mm", {options.target_height_mm, kTargetHeightMmRange}},
      {"axis_offset_px", {options.axis_offset_px, kAxisOffsetPxRange}},
      {"roll_deg", {options.roll_deg, kRollDegRange}},
      {"radius_mm", {options.radius_mm, kObjectSizeMmRange}},
      {"height_mm", {options.height_mm, kObjectSizeMmRange}},
      {"backdrop_grey", {options.backdrop_grey, kBackdropGreyRange}},
      {"object_albedo", {options.object_albedo, kAlbedoRange}},
      {"plate_radius_mm", {options.plate_radius_mm, kPlateMmRange}},
      {"plate_thickness_mm", {options.plate_thickness_mm, kPlateMmRange}},
      {"blur_sigma_px", {options.blur_sigma_px, kBlurSigmaPxRange}},
      {"noise_sigma", {options.noise_sigma, kNoiseSigmaRange}},
  };
  for (const auto& [key, check] : checks) {
    if (auto ok = CheckRange(key, check.first, check.second); !ok) return ok;
  }
  if (options.projection != "pinhole" && options.projection != "orthographic") {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("[camera.synthetic] projection = \"{}\" is not one of "
                                 "\"pinhole\", \"orthographic\"",
                                 options.projection));
  }
  for (const auto& [key, colour] : {std::pair<std::string_view, const std::vector<double>*>{
                                        "backdrop_bgr", &options.backdrop_bgr},
                                    {"plate_top_bgr", &options.plate_top_bgr},
                                    {"plate_rim_bgr", &options.plate_rim_bgr},
                                    {"fixture_bgr", &options.fixture_bgr}}) {
    if (colour->empty()) continue;
    bool ok = colour->size() == 3;
    for (double c : *colour) ok = ok && c >= 0.0 && c <= 255.0;
    if (!ok) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("[camera.synthetic] {} needs three numbers B G R in [0, 255]", key));
    }
  }
  if (options.fixture_mm.size() % 6 != 0) {
    return MakeError(ErrorCode::kBadInput,
                     "[camera.synthetic] fixture_mm needs groups of six numbers: x0 y0 z0 x1 y1 "
                     "z1 (mm, table frame)");
  }
  return {};
}

}  // namespace

Expected<void> ValidateSyntheticOptions(const SyntheticOptions& options) {
  if (auto ok = CheckRanges(options); !ok) return ok;
  auto scene = SceneFromOptions(options);
  if (!scene) return std::unexpected(WithContext(scene.error(), "[camera.synthetic]"));
  if (auto ok = CheckCameraOutsideObject(options, *scene); !ok) {
    return std::unexpected(WithContext(ok.error(), "[camera.synthetic]"));
  }
  return {};
}

Expected<std::unique_ptr<SyntheticCamera>> SyntheticCamera::Create(
    const SyntheticOptions& options, std::shared_ptr<const SimulatedPlate> plate) {
  if (plate == nullptr) {
    return MakeError(ErrorCode::kBadInput,
                     "the synthetic camera needs the simulated plate (the mock turntable's angle)");
  }
  if (auto ok = CheckRanges(options); !ok) return std::unexpected(ok.error());
  auto scene = SceneFromOptions(options);
  if (!scene) return std::unexpected(WithContext(scene.error(), "[camera.synthetic]"));
  if (auto ok = CheckCameraOutsideObject(options, *scene); !ok) {
    return std::unexpected(WithContext(ok.error(), "[camera.synthetic]"));
  }
  return std::unique_ptr<SyntheticCamera>(
      new SyntheticCamera(options, std::move(*scene), std::move(plate)));
}

SyntheticCamera::SyntheticCamera(const SyntheticOptions& options, Scene scene,
                                 std::shared_ptr<const SimulatedPlate> plate)
    : options_(options),
      scene_(std::move(scene)),
      projection_(ProjectionFromOptions(options)),
      render_settings_(RenderSettingsFromOptions(options)),
      plate_(std::move(plate)) {}

std::optional<Rig> SyntheticCamera::KnownRig() const {
  if (projection_.orthographic || !options_.known_geometry) return std::nullopt;
  return projection_.rig;
}

Expected<FrameFormat> SyntheticCamera::Start() {
  {
    std::lock_guard lock(mutex_);
    started_ = true;
  }
  Logger("capture")->info("{} started", Describe());
  return FrameFormat{options_.width_px, options_.height_px, "BGR3"};
}

void SyntheticCamera::Stop() noexcept {
  {
    std::lock_guard lock(mutex_);
    started_ = false;
  }
  wake_.notify_all();
}

Expected<Frame> SyntheticCamera::Capture(Clock::time_point not_before, Clock::duration timeout) {
  return Expose(not_before, timeout, true);
}

Expected<Frame> SyntheticCamera::CaptureBackground(Clock::time_point not_before,
                                                   Clock::duration timeout) {
  return Expose(not_before, timeout, false);
}

Expected<Frame> SyntheticCamera::Expose(Clock::time_point not_before, Clock::duration timeout,
                                        bool draw_object) {
  std::unique_lock lock(mutex_);
  if (!started_) {
    return MakeError(ErrorCode::kInternal, "synthetic camera: Capture() called while not started");
  }
  const Clock::time_point now = Clock::now();
  if (not_before > now && not_before - now > timeout) {
    return MakeError(ErrorCode::kTimeout,
                     fmt::format("synthetic camera: the exposure may not start for {:.1f} ms, "
                                 "beyond the capture timeout of {:.1f} ms",
                                 Milliseconds(not_before - now), Milliseconds(timeout)));
  }
  while (started_ && Clock::now() < not_before) wake_.wait_until(lock, not_before);
  if (!started_) {
    return MakeError(ErrorCode::kAborted, "synthetic camera: stopped while waiting to expose");
  }
  Frame frame;
  frame.exposed = Clock::now();
  frame.sequence = next_sequence_++;
  frame.exposure_us = kExposureUs;
  const double angle_deg = plate_->angle_deg.load();
  if (plate_->moving.load() && !warned_moving_) {
    warned_moving_ = true;
    Logger("capture")->warn(
        "synthetic camera: frame {} exposed while the plate was moving (at {:.2f} deg)",
        frame.sequence, angle_deg);
  }
  lock.unlock();
  RenderOutput out = RenderWithTruth(angle_deg, frame.sequence, draw_object);
  frame.image = std::move(out.image);
  frame.true_mask = std::move(out.true_mask);
  frame.plate_angle_deg = angle_deg;
  return frame;
}

std::string SyntheticCamera::Describe() const {
  return fmt::format(
      "synthetic {}camera {}x{} hfov {:g} deg, {:g} mm from the axis at {:g} deg "
      "elevation, seeing a {}{}",
      projection_.orthographic ? "orthographic " : "", options_.width_px, options_.height_px,
      options_.hfov_deg, options_.distance_mm, options_.elevation_deg, scene_.Describe(),
      options_.known_geometry ? "" : " (geometry hidden)");
}

cv::Mat SyntheticCamera::Render(double plate_angle_deg, std::uint64_t sequence) const {
  return RenderFrame(scene_, projection_, plate_angle_deg, render_settings_, sequence);
}

RenderOutput SyntheticCamera::RenderWithTruth(double plate_angle_deg, std::uint64_t sequence,
                                              bool draw_object) const {
  return RenderScene(scene_, projection_, plate_angle_deg, render_settings_, sequence, draw_object);
}

cv::Mat SyntheticCamera::TrueMask(double plate_angle_deg) const {
  RenderSettings quiet = render_settings_;
  quiet.noise_sigma = 0.0;
  quiet.blur_sigma_px = 0.0;
  return RenderScene(scene_, projection_, plate_angle_deg, quiet, 0).true_mask;
}

}  // namespace revolve::capture
