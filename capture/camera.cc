#include "capture/camera.h"

#include <fmt/format.h>

#include "capture/synthetic/synthetic_camera.h"

namespace revolve::capture {
namespace {

// The camera backends this build has.
constexpr std::string_view kBuiltBackends = "synthetic";

Expected<SyntheticOptions> ParseSynthetic(const config::Section& section) {
  SyntheticOptions o;
  const SyntheticOptions defaults;
  auto integer = [&](std::string_view key, int fallback, OptionRange range) -> Expected<int> {
    auto value = section.Integer(key, fallback, static_cast<std::int64_t>(range.min),
                                 static_cast<std::int64_t>(range.max));
    if (!value) return std::unexpected(value.error());
    return static_cast<int>(*value);
  };
  auto number = [&](std::string_view key, double fallback, OptionRange range) {
    return section.Number(key, fallback, range.min, range.max);
  };
  auto width = integer("width_px", defaults.width_px, kImageSidePxRange);
  if (!width) return std::unexpected(width.error());
  auto height = integer("height_px", defaults.height_px, kImageSidePxRange);
  if (!height) return std::unexpected(height.error());
  auto hfov = number("hfov_deg", defaults.hfov_deg, kHfovDegRange);
  if (!hfov) return std::unexpected(hfov.error());
  auto distance = number("distance_mm", defaults.distance_mm, kDistanceMmRange);
  if (!distance) return std::unexpected(distance.error());
  auto elevation = number("elevation_deg", defaults.elevation_deg, kElevationDegRange);
  if (!elevation) return std::unexpected(elevation.error());
  auto target = number("target_height_mm", defaults.target_height_mm, kTargetHeightMmRange);
  if (!target) return std::unexpected(target.error());
  auto object = section.String("object", defaults.object, {"sphere", "cylinder", "vase"});
  if (!object) return std::unexpected(object.error());
  auto radius = number("radius_mm", defaults.radius_mm, kObjectSizeMmRange);
  if (!radius) return std::unexpected(radius.error());
  auto object_height = number("height_mm", defaults.height_mm, kObjectSizeMmRange);
  if (!object_height) return std::unexpected(object_height.error());
  auto backdrop = integer("backdrop_grey", defaults.backdrop_grey, kBackdropGreyRange);
  if (!backdrop) return std::unexpected(backdrop.error());
  auto noise = number("noise_sigma", defaults.noise_sigma, kNoiseSigmaRange);
  if (!noise) return std::unexpected(noise.error());
  auto seed = section.Integer("seed", static_cast<std::int64_t>(defaults.seed), 0,
                              std::numeric_limits<std::int64_t>::max());
  if (!seed) return std::unexpected(seed.error());
  if (auto ok = section.CheckNoUnknownKeys(); !ok) return std::unexpected(ok.error());

  o.width_px = *width;
  o.height_px = *height;
  o.hfov_deg = *hfov;
  o.distance_mm = *distance;
  o.elevation_deg = *elevation;
  o.target_height_mm = *target;
  o.object = *object;
  o.radius_mm = *radius;
  o.height_mm = *object_height;
  o.backdrop_grey = *backdrop;
  o.noise_sigma = *noise;
  o.seed = static_cast<std::uint64_t>(*seed);
  // Cross-field check: the camera must stand outside the object.
  if (auto ok = CheckCameraOutsideObject(o); !ok) {
    return std::unexpected(section.BadValue("distance_mm", ok.error().message));
  }
  return o;
}

}  // namespace

Expected<CameraOptions> ParseOptions(const config::Section& section) {
  CameraOptions options;
  auto backend = section.String("backend", options.backend);
  if (!backend) return std::unexpected(backend.error());
  if (*backend != "synthetic") {
    return std::unexpected(section.BadValue(
        "backend", fmt::format("\"{}\" is not a camera backend of this build (it has: {})",
                               *backend, kBuiltBackends)));
  }
  options.backend = *backend;
  auto child = section.Child("synthetic");
  if (!child) return std::unexpected(child.error());
  auto synthetic = ParseSynthetic(*child);
  if (!synthetic) return std::unexpected(synthetic.error());
  options.synthetic = *synthetic;
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
  return MakeError(ErrorCode::kUnsupported,
                   fmt::format("[camera].backend = \"{}\" is not available in this build (it "
                               "has: {})",
                               options.backend, kBuiltBackends));
}

}  // namespace revolve::capture
