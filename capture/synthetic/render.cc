#include "capture/synthetic/render.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace revolve::capture {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kSubsamples = 4;  // per axis, for edge pixels

// B, G, R albedos; [band parity][checker parity].
constexpr float kPalette[2][2][3] = {
    {{0.24f, 0.59f, 0.94f}, {0.70f, 0.88f, 0.94f}},  // orange, cream
    {{0.90f, 0.75f, 0.47f}, {0.51f, 0.86f, 0.55f}},  // light blue, light green
};

std::uint64_t SplitMix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

struct Shader {
  const Scene& scene;
  Eigen::Vector3d light;  // object frame

  Eigen::Vector3f Shade(const RayHit& hit) const {
    const Eigen::Vector3d to_light = (light - hit.point).normalized();
    const double lambert = std::max(0.0, hit.normal.dot(to_light));
    const float gain = static_cast<float>(255.0 * (kAmbient + kDiffuse * lambert));
    return (SurfaceAlbedo(scene, hit.point) * gain).cwiseMin(255.0f);
  }
};

}  // namespace

bool InMarker(const Scene& scene, const Eigen::Vector3d& point) {
  const double h = scene.height_mm();
  if (std::abs(point.z() - 0.5 * h) > h * kMarkerHalfHeight) return false;
  const double phi_deg = std::atan2(point.y(), point.x()) * 180.0 / kPi;
  return std::abs(phi_deg) <= kMarkerHalfWidthDeg;
}

Eigen::Vector3d MarkerCenter(const Scene& scene) {
  const double z = 0.5 * scene.height_mm();
  return Eigen::Vector3d(scene.ProfileRadiusMm(z), 0.0, z);
}

Eigen::Vector3f SurfaceAlbedo(const Scene& scene, const Eigen::Vector3d& point) {
  if (InMarker(scene, point)) return Eigen::Vector3f(kMarkerBgr[0], kMarkerBgr[1], kMarkerBgr[2]);
  const double phi = std::atan2(point.y(), point.x());  // [-pi, pi]
  const int sector =
      std::clamp(static_cast<int>(std::floor((phi + kPi) / (2.0 * kPi) * kTextureSectors)), 0,
                 kTextureSectors - 1);
  const int band =
      std::clamp(static_cast<int>(std::floor(point.z() / scene.height_mm() * kTextureBands)), 0,
                 kTextureBands - 1);
  const float* c = kPalette[band % 2][(sector + band) % 2];
  return Eigen::Vector3f(c[0], c[1], c[2]);
}

std::uint64_t NoiseSeed(std::uint64_t seed, std::uint64_t sequence) {
  return SplitMix64(SplitMix64(seed) ^ sequence);
}

cv::Mat RenderFrame(const Scene& scene, const Rig& rig, double plate_angle_deg,
                    const RenderSettings& settings, std::uint64_t sequence) {
  const int width = rig.intrinsics.width_px;
  const int height = rig.intrinsics.height_px;
  const float backdrop = static_cast<float>(settings.backdrop_grey);
  cv::Mat image(height, width, CV_32FC3, cv::Scalar::all(backdrop));

  const Eigen::Isometry3d object_from_cam = rig.CamFromObject(plate_angle_deg).inverse();
  const Eigen::Vector3d mid_object(0.0, 0.0, 0.5 * scene.height_mm());
  const double light_distance = (object_from_cam.translation() - mid_object).norm();
  const Shader shader{scene, object_from_cam * Eigen::Vector3d(kLightRight * light_distance,
                                                               kLightDown * light_distance, 0.0)};
  const PixelRays rays(rig, plate_angle_deg);

  const cv::Rect bounds = ProjectedBounds(scene, rig, plate_angle_deg, 2);
  // Pass 1: one ray per pixel centre. `hit` has a one-pixel frame of misses around `bounds`.
  cv::Mat hit(bounds.height + 2, bounds.width + 2, CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < bounds.height; ++y) {
    const int v = bounds.y + y;
    auto* out = image.ptr<cv::Vec3f>(v);
    auto* hit_row = hit.ptr<std::uint8_t>(y + 1);
    for (int x = 0; x < bounds.width; ++x) {
      const int u = bounds.x + x;
      if (const auto h = scene.Intersect(rays.origin(), rays.Direction(u, v))) {
        const Eigen::Vector3f c = shader.Shade(*h);
        out[u] = cv::Vec3f(c[0], c[1], c[2]);
        hit_row[x + 1] = 1;
      }
    }
  }
  // Pass 2: supersample the pixels on either side of the silhouette's edge.
  for (int y = 0; y < bounds.height; ++y) {
    const int v = bounds.y + y;
    auto* out = image.ptr<cv::Vec3f>(v);
    for (int x = 0; x < bounds.width; ++x) {
      const std::uint8_t centre = hit.at<std::uint8_t>(y + 1, x + 1);
      bool edge = false;
      for (int dy = 0; dy <= 2 && !edge; ++dy) {
        const auto* row = hit.ptr<std::uint8_t>(y + dy);
        edge = row[x] != centre || row[x + 1] != centre || row[x + 2] != centre;
      }
      if (!edge) continue;
      const int u = bounds.x + x;
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      for (int sy = 0; sy < kSubsamples; ++sy) {
        for (int sx = 0; sx < kSubsamples; ++sx) {
          const double du = (sx + 0.5) / kSubsamples - 0.5;
          const double dv = (sy + 0.5) / kSubsamples - 0.5;
          if (const auto h = scene.Intersect(rays.origin(), rays.Direction(u + du, v + dv))) {
            sum += shader.Shade(*h);
          } else {
            sum += Eigen::Vector3f::Constant(backdrop);
          }
        }
      }
      sum /= static_cast<float>(kSubsamples * kSubsamples);
      out[u] = cv::Vec3f(sum[0], sum[1], sum[2]);
    }
  }
  if (settings.noise_sigma > 0.0) {
    cv::RNG rng(NoiseSeed(settings.seed, sequence));
    cv::Mat noise(height, width, CV_32FC3);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, settings.noise_sigma);
    image += noise;
  }
  cv::Mat frame;
  image.convertTo(frame, CV_8UC3);
  return frame;
}

}  // namespace revolve::capture
