#include "capture/camera.h"

#include <filesystem>
#include <limits>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "capture/replay/replay_camera.h"
#include "capture/synthetic/mesh.h"
#include "capture/synthetic/synthetic_camera.h"
#include "config/reader.h"
#if REVOLVE_HAVE_V4L2
#include "capture/v4l2/pixel_convert.h"
#include "capture/v4l2/v4l2_camera.h"
#include "capture/v4l2/v4l2_device.h"
#endif
#if REVOLVE_HAVE_LIBCAMERA
#include "capture/libcamera/libcamera_camera.h"
#endif

namespace revolve::capture {
namespace {

Expected<SyntheticOptions> ParseSynthetic(const config::Section& section) {
  SyntheticOptions o;
  config::Reader r(section);
  r.Integer("width_px", o.width_px, kImageSidePxRange.min, kImageSidePxRange.max);
  r.Integer("height_px", o.height_px, kImageSidePxRange.min, kImageSidePxRange.max);
  r.Number("hfov_deg", o.hfov_deg, kHfovDegRange.min, kHfovDegRange.max);
  r.Number("distance_mm", o.distance_mm, kDistanceMmRange.min, kDistanceMmRange.max);
  r.Number("elevation_deg", o.elevation_deg, kElevationDegRange.min, kElevationDegRange.max);
  r.Number("target_height_mm", o.target_height_mm, kTargetHeightMmRange.min,
           kTargetHeightMmRange.max);
  r.String("projection", o.projection, {"pinhole", "orthographic"});
  r.Number("axis_offset_px", o.axis_offset_px, kAxisOffsetPxRange.min, kAxisOffsetPxRange.max);
  r.Number("roll_deg", o.roll_deg, kRollDegRange.min, kRollDegRange.max);
  r.Boolean("known_geometry", o.known_geometry);
  r.String("object", o.object, {"sphere", "cylinder", "vase", "cone", "box", "torus", "mesh"});
  r.Number("radius_mm", o.radius_mm, kObjectSizeMmRange.min, kObjectSizeMmRange.max);
  r.Number("height_mm", o.height_mm, kObjectSizeMmRange.min, kObjectSizeMmRange.max);
  r.Path("mesh_path", o.mesh_path);
  r.String("mesh_up", o.mesh_up, {"x", "y", "z"});
  r.Integer("backdrop_grey", o.backdrop_grey, kBackdropGreyRange.min, kBackdropGreyRange.max);
  r.Numbers("backdrop_bgr", o.backdrop_bgr, 0.0, 255.0, 0, 3);
  r.Number("object_albedo", o.object_albedo, kAlbedoRange.min, kAlbedoRange.max);
  r.String("texture", o.texture, {"checker", "speckle"});
  r.Number("plate_radius_mm", o.plate_radius_mm, kPlateMmRange.min, kPlateMmRange.max);
  r.Number("plate_thickness_mm", o.plate_thickness_mm, kPlateMmRange.min, kPlateMmRange.max);
  r.Numbers("plate_top_bgr", o.plate_top_bgr, 0.0, 255.0, 0, 3);
  r.Numbers("plate_rim_bgr", o.plate_rim_bgr, 0.0, 255.0, 0, 3);
  r.Numbers("fixture_mm", o.fixture_mm, -1e5, 1e5, 6);
  r.Numbers("fixture_bgr", o.fixture_bgr, 0.0, 255.0, 0, 3);
  r.Number("blur_sigma_px", o.blur_sigma_px, kBlurSigmaPxRange.min, kBlurSigmaPxRange.max);
  r.Number("noise_sigma", o.noise_sigma, kNoiseSigmaRange.min, kNoiseSigmaRange.max);
  auto seed = section.Integer("seed", static_cast<std::int64_t>(o.seed), 0,
                              std::numeric_limits<std::int64_t>::max());
  if (!seed) return std::unexpected(seed.error());
  o.seed = static_cast<std::uint64_t>(*seed);
  if (auto ok = r.Finish(); !ok) return std::unexpected(ok.error());
  // Cross-field checks: the object (a mesh must load) and the camera outside it.
  auto scene = SceneFromOptions(o);
  if (!scene) {
    return std::unexpected(
        section.BadValue(o.object == "mesh" ? "mesh_path" : "object", scene.error().message));
  }
  if (auto ok = CheckCameraOutsideObject(o, *scene); !ok) {
    return std::unexpected(section.BadValue("distance_mm", ok.error().message));
  }
  return o;
}

Expected<ReplayOptions> ParseReplay(const config::Section& section) {
  ReplayOptions o;
  config::Reader r(section);
  r.Path("dir", o.dir);
  r.String("pattern", o.pattern);
  r.Number("step_deg", o.step_deg, 0.001, 360.0);
  r.String("order", o.order, {"angle", "sequence"});
  r.Path("background", o.background);
  r.Number("hfov_deg", o.hfov_deg, 0.0, kHfovDegRange.max);
  r.Number("distance_mm", o.distance_mm, kDistanceMmRange.min, kDistanceMmRange.max);
  r.Number("elevation_deg", o.elevation_deg, kElevationDegRange.min, kElevationDegRange.max);
  r.Number("target_height_mm", o.target_height_mm, kTargetHeightMmRange.min,
           kTargetHeightMmRange.max);
  if (auto ok = r.Finish(); !ok) return std::unexpected(ok.error());
  if (auto ok = CheckReplayPattern(o.pattern); !ok) {
    return std::unexpected(section.BadValue("pattern", ok.error().message));
  }
  return o;
}

Expected<V4l2Options> ParseV4l2(const config::Section& section) {
  V4l2Options o;
  config::Reader r(section);
  r.String("device", o.device);
  r.Integer("width_px", o.width_px, 0, 16384);
  r.Integer("height_px", o.height_px, 0, 16384);
  r.Strings("pixel_formats", o.pixel_formats);
  r.Boolean("exact_size", o.exact_size);
  r.Number("fps", o.fps, 0.0, 1000.0);
  r.Integer("buffers", o.buffers, 2, 32);
  r.Boolean("use_libv4l2", o.use_libv4l2);
  r.Number("exposure_us", o.exposure_us, -1.0, 1e8);
  r.Number("gain", o.gain, -1.0, 1e6);
  r.Number("white_balance_k", o.white_balance_k, -1.0, 20000.0);
  r.Number("focus", o.focus, -1.0, 1e6);
  r.Integer("power_line_hz", o.power_line_hz, -1, 60);
  r.Number("lock_after_s", o.lock_after_s, 0.0, 60.0);
  r.Number("settle_margin_ms", o.settle_margin_ms, 0.0, 10000.0);
  r.Integer("timeouts_before_reopen", o.timeouts_before_reopen, 1, 1000);
  if (auto ok = r.Finish(); !ok) return std::unexpected(ok.error());
  if (o.power_line_hz != -1 && o.power_line_hz != 0 && o.power_line_hz != 50 &&
      o.power_line_hz != 60) {
    return std::unexpected(section.BadValue("power_line_hz", "must be 0, 50 or 60 (or -1)"));
  }
  if (o.pixel_formats.empty()) {
    return std::unexpected(section.BadValue("pixel_formats", "needs at least one format"));
  }
  for (const std::string& f : o.pixel_formats) {
    if (f.size() != 4) {
      return std::unexpected(section.BadValue(
          "pixel_formats", fmt::format("\"{}\" is not a four-character code like \"YUYV\"", f)));
    }
  }
  return o;
}

Expected<LibcameraOptions> ParseLibcamera(const config::Section& section) {
  LibcameraOptions o;
  config::Reader r(section);
  r.String("camera", o.camera);
  r.Integer("width_px", o.width_px, 16, 16384);
  r.Integer("height_px", o.height_px, 16, 16384);
  r.Number("exposure_us", o.exposure_us, -1.0, 1e8);
  r.Number("analogue_gain", o.analogue_gain, -1.0, 1000.0);
  r.Numbers("colour_gains", o.colour_gains, 0.0, 32.0, 0, 2);
  if (auto ok = r.Finish(); !ok) return std::unexpected(ok.error());
  return o;
}

template <class Options, class Parse>
Expected<void> ParseChild(const config::Section& section, std::string_view key, Parse parse,
                          Options* out) {
  auto child = section.Child(key);
  if (!child) return std::unexpected(child.error());
  auto parsed = parse(*child);
  if (!parsed) return std::unexpected(parsed.error());
  *out = std::move(*parsed);
  return {};
}

}  // namespace

std::vector<std::string> BuiltBackends() {
  std::vector<std::string> backends = {"synthetic", "replay"};
#if REVOLVE_HAVE_V4L2
  backends.push_back("v4l2");
#endif
#if REVOLVE_HAVE_LIBCAMERA
  backends.push_back("libcamera");
#endif
  return backends;
}

Expected<void> WriteTruthMeshPly(const SceneTruth& truth, const std::filesystem::path& path) {
  if (truth.mesh_triangles.empty()) {
    return MakeError(ErrorCode::kBadInput, "the scene's truth has no surface mesh");
  }
  TriangleMesh mesh;
  mesh.vertices = truth.mesh_vertices_mm;
  mesh.triangles = truth.mesh_triangles;
  return WritePlyAscii(mesh, path);
}

std::string ListCameraDevices() {
  std::string out;
#if REVOLVE_HAVE_V4L2
  auto sys = MakeKernelV4l2Sys();
  const std::vector<DeviceListing> devices = ListV4l2Devices(*sys);
  if (devices.empty()) out += "V4L2: no /dev/video* devices\n";
  for (const DeviceListing& d : devices) {
    out += d.path;
    if (!d.resolves_to.empty()) out += " -> " + d.resolves_to;
    out += "\n";
    if (!d.error.empty()) {
      out += "    cannot query: " + d.error + "\n";
      continue;
    }
    if (!d.caps) continue;
    out += fmt::format("    {} ({}, {})\n", d.caps->card, d.caps->driver, d.caps->bus_info);
    if (!d.caps->video_capture) {
      out += "    not a capture node (metadata or output): do not use\n";
      continue;
    }
    for (const PixelFormatInfo& f : d.formats) {
      std::vector<std::string> sizes;
      sizes.reserve(f.sizes.size());
      for (const auto& [w, h] : f.sizes) sizes.push_back(fmt::format("{}x{}", w, h));
      out += fmt::format("    {} {}{}: {}\n", FourCcToString(f.fourcc), f.description,
                         CanConvert(f.fourcc) ? "" : " (not supported by revolve)",
                         sizes.empty() ? "any size" : fmt::format("{}", fmt::join(sizes, " ")));
    }
  }
#else
  out += "V4L2: not in this build\n";
#endif
#if REVOLVE_HAVE_LIBCAMERA
  out += ListLibcameraCameras();
#endif
  return out;
}

Expected<CameraOptions> ParseOptions(const config::Section& section) {
  CameraOptions options;
  auto backend = section.String("backend", options.backend);
  if (!backend) return std::unexpected(backend.error());
  const std::vector<std::string> built = BuiltBackends();
  if (std::find(built.begin(), built.end(), *backend) == built.end()) {
    return std::unexpected(section.BadValue(
        "backend", fmt::format("\"{}\" is not a camera backend of this build (it has: {})",
                               *backend, fmt::join(built, ", "))));
  }
  options.backend = *backend;
  // Every backend's table is checked, so a typo is found before the rig is switched to it.
  if (auto ok = ParseChild(section, "synthetic", ParseSynthetic, &options.synthetic); !ok) {
    return std::unexpected(ok.error());
  }
  if (auto ok = ParseChild(section, "replay", ParseReplay, &options.replay); !ok) {
    return std::unexpected(ok.error());
  }
  if (auto ok = ParseChild(section, "v4l2", ParseV4l2, &options.v4l2); !ok) {
    return std::unexpected(ok.error());
  }
  if (auto ok = ParseChild(section, "libcamera", ParseLibcamera, &options.libcamera); !ok) {
    return std::unexpected(ok.error());
  }
  if (auto ok = section.CheckNoUnknownKeys(); !ok) return std::unexpected(ok.error());
  return options;
}

Expected<std::unique_ptr<Camera>> Create(const CameraOptions& options,
                                         std::shared_ptr<const SimulatedPlate> plate) {
  if (options.backend == "synthetic") {
    auto camera = SyntheticCamera::Create(options.synthetic, std::move(plate));
    if (!camera) return std::unexpected(camera.error());
    return std::unique_ptr<Camera>(std::move(*camera));
  }
  if (options.backend == "replay") {
    auto camera = ReplayCamera::Create(options.replay, std::move(plate));
    if (!camera) return std::unexpected(camera.error());
    return std::unique_ptr<Camera>(std::move(*camera));
  }
#if REVOLVE_HAVE_V4L2
  if (options.backend == "v4l2") {
    auto camera = V4l2Camera::Create(options.v4l2);
    if (!camera) return std::unexpected(camera.error());
    return std::unique_ptr<Camera>(std::move(*camera));
  }
#endif
#if REVOLVE_HAVE_LIBCAMERA
  if (options.backend == "libcamera") {
    auto camera = CreateLibcameraCamera(options.libcamera);
    if (!camera) return std::unexpected(camera.error());
    return std::move(*camera);
  }
#endif
  return MakeError(ErrorCode::kUnsupported,
                   fmt::format("[camera].backend = \"{}\" is not available in this build (it "
                               "has: {})",
                               options.backend, fmt::join(BuiltBackends(), ", ")));
}

}  // namespace revolve::capture
