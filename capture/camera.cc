#include "capture/camera.h"

#include <filesystem>
#include <limits>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "capture/replay/replay_camera.h"
#include "capture/synthetic/mesh.h"
#include "capture/synthetic/synthetic_camera.h"
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

// Reads typed keys of one section into fields, stopping at the first error.
class Reader {
 public:
  explicit Reader(const config::Section& section) : section_(section) {}

  void Int(std::string_view key, int* field, double min, double max) {
    if (error_) return;
    auto value = section_.Integer(key, *field, static_cast<std::int64_t>(min),
                                  static_cast<std::int64_t>(max));
    if (!value) {
      error_ = value.error();
      return;
    }
    *field = static_cast<int>(*value);
  }
  void Number(std::string_view key, double* field, double min, double max) {
    if (error_) return;
    auto value = section_.Number(key, *field, min, max);
    if (!value) {
      error_ = value.error();
      return;
    }
    *field = *value;
  }
  void Number(std::string_view key, double* field, OptionRange range) {
    Number(key, field, range.min, range.max);
  }
  void Bool(std::string_view key, bool* field) {
    if (error_) return;
    auto value = section_.Boolean(key, *field);
    if (!value) {
      error_ = value.error();
      return;
    }
    *field = *value;
  }
  void String(std::string_view key, std::string* field,
              std::initializer_list<std::string_view> allowed = {}) {
    if (error_) return;
    auto value = section_.String(key, *field, allowed);
    if (!value) {
      error_ = value.error();
      return;
    }
    *field = *value;
  }
  void Strings(std::string_view key, std::vector<std::string>* field) {
    if (error_) return;
    auto value = section_.Strings(key, *field);
    if (!value) {
      error_ = value.error();
      return;
    }
    *field = *value;
  }
  // An array of numbers in [min, max] whose length is a multiple of `group` (0: any length;
  // `exact` > 0: exactly that many, or none).
  void Numbers(std::string_view key, std::vector<double>* field, double min, double max,
               std::size_t group, std::size_t exact = 0) {
    if (error_) return;
    auto value = section_.Numbers(key, *field);
    if (!value) {
      error_ = value.error();
      return;
    }
    if (exact > 0 && !value->empty() && value->size() != exact) {
      error_ =
          section_.BadValue(key, fmt::format("needs {} numbers, got {}", exact, value->size()));
      return;
    }
    if (group > 0 && value->size() % group != 0) {
      error_ = section_.BadValue(
          key, fmt::format("needs groups of {} numbers, got {}", group, value->size()));
      return;
    }
    for (double v : *value) {
      if (!(v >= min && v <= max)) {
        error_ = section_.BadValue(key, fmt::format("{} is out of range [{}, {}]", v, min, max));
        return;
      }
    }
    *field = *value;
  }
  // A relative path is taken relative to the config file's folder (when there is a file).
  void Path(std::string_view key, std::string* field) {
    if (error_) return;
    auto value = section_.Path(key, *field);
    if (!value) {
      error_ = value.error();
      return;
    }
    *field = value->string();
  }

  Expected<void> Finish() {
    if (error_) return std::unexpected(*error_);
    if (auto ok = section_.CheckNoUnknownKeys(); !ok) return ok;
    return {};
  }
  const config::Section& section() const { return section_; }

 private:
  const config::Section& section_;
  std::optional<Error> error_;
};

Expected<SyntheticOptions> ParseSynthetic(const config::Section& section) {
  SyntheticOptions o;
  Reader r(section);
  r.Int("width_px", &o.width_px, kImageSidePxRange.min, kImageSidePxRange.max);
  r.Int("height_px", &o.height_px, kImageSidePxRange.min, kImageSidePxRange.max);
  r.Number("hfov_deg", &o.hfov_deg, kHfovDegRange);
  r.Number("distance_mm", &o.distance_mm, kDistanceMmRange);
  r.Number("elevation_deg", &o.elevation_deg, kElevationDegRange);
  r.Number("target_height_mm", &o.target_height_mm, kTargetHeightMmRange);
  r.String("projection", &o.projection, {"pinhole", "orthographic"});
  r.Number("axis_offset_px", &o.axis_offset_px, kAxisOffsetPxRange);
  r.Number("roll_deg", &o.roll_deg, kRollDegRange);
  r.Bool("known_geometry", &o.known_geometry);
  r.String("object", &o.object, {"sphere", "cylinder", "vase", "cone", "box", "torus", "mesh"});
  r.Number("radius_mm", &o.radius_mm, kObjectSizeMmRange);
  r.Number("height_mm", &o.height_mm, kObjectSizeMmRange);
  r.Path("mesh_path", &o.mesh_path);
  r.String("mesh_up", &o.mesh_up, {"x", "y", "z"});
  r.Int("backdrop_grey", &o.backdrop_grey, kBackdropGreyRange.min, kBackdropGreyRange.max);
  r.Numbers("backdrop_bgr", &o.backdrop_bgr, 0.0, 255.0, 0, 3);
  r.Number("object_albedo", &o.object_albedo, kAlbedoRange);
  r.Number("plate_radius_mm", &o.plate_radius_mm, kPlateMmRange);
  r.Number("plate_thickness_mm", &o.plate_thickness_mm, kPlateMmRange);
  r.Numbers("plate_top_bgr", &o.plate_top_bgr, 0.0, 255.0, 0, 3);
  r.Numbers("plate_rim_bgr", &o.plate_rim_bgr, 0.0, 255.0, 0, 3);
  r.Numbers("fixture_mm", &o.fixture_mm, -1e5, 1e5, 6);
  r.Numbers("fixture_bgr", &o.fixture_bgr, 0.0, 255.0, 0, 3);
  r.Number("blur_sigma_px", &o.blur_sigma_px, kBlurSigmaPxRange);
  r.Number("noise_sigma", &o.noise_sigma, kNoiseSigmaRange);
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
  Reader r(section);
  r.Path("dir", &o.dir);
  r.String("pattern", &o.pattern);
  r.Number("step_deg", &o.step_deg, 0.001, 360.0);
  r.String("order", &o.order, {"angle", "sequence"});
  r.Path("background", &o.background);
  r.Number("hfov_deg", &o.hfov_deg, 0.0, kHfovDegRange.max);
  r.Number("distance_mm", &o.distance_mm, kDistanceMmRange);
  r.Number("elevation_deg", &o.elevation_deg, kElevationDegRange);
  r.Number("target_height_mm", &o.target_height_mm, kTargetHeightMmRange);
  if (auto ok = r.Finish(); !ok) return std::unexpected(ok.error());
  if (auto ok = CheckReplayPattern(o.pattern); !ok) {
    return std::unexpected(section.BadValue("pattern", ok.error().message));
  }
  return o;
}

Expected<V4l2Options> ParseV4l2(const config::Section& section) {
  V4l2Options o;
  Reader r(section);
  r.String("device", &o.device);
  r.Int("width_px", &o.width_px, 0, 16384);
  r.Int("height_px", &o.height_px, 0, 16384);
  r.Strings("pixel_formats", &o.pixel_formats);
  r.Bool("exact_size", &o.exact_size);
  r.Number("fps", &o.fps, 0.0, 1000.0);
  r.Int("buffers", &o.buffers, 2, 32);
  r.Bool("use_libv4l2", &o.use_libv4l2);
  r.Number("exposure_us", &o.exposure_us, -1.0, 1e8);
  r.Number("gain", &o.gain, -1.0, 1e6);
  r.Number("white_balance_k", &o.white_balance_k, -1.0, 20000.0);
  r.Number("focus", &o.focus, -1.0, 1e6);
  r.Int("power_line_hz", &o.power_line_hz, -1, 60);
  r.Number("lock_after_s", &o.lock_after_s, 0.0, 60.0);
  r.Number("settle_margin_ms", &o.settle_margin_ms, 0.0, 10000.0);
  r.Int("timeouts_before_reopen", &o.timeouts_before_reopen, 1, 1000);
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
  Reader r(section);
  r.String("camera", &o.camera);
  r.Int("width_px", &o.width_px, 16, 16384);
  r.Int("height_px", &o.height_px, 16, 16384);
  r.Number("exposure_us", &o.exposure_us, -1.0, 1e8);
  r.Number("analogue_gain", &o.analogue_gain, -1.0, 1000.0);
  r.Numbers("colour_gains", &o.colour_gains, 0.0, 32.0, 0, 2);
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
