#include "capture/synthetic/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "capture/synthetic/mesh.h"

namespace revolve::capture {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kSubsamples = 4;  // per axis, for edge pixels

// B, G, R albedos; [band parity][checker parity].
constexpr float kPalette[2][2][3] = {
    {{0.24f, 0.59f, 0.94f}, {0.70f, 0.88f, 0.94f}},  // orange, cream
    {{0.90f, 0.75f, 0.47f}, {0.86f, 0.62f, 0.88f}},  // light blue, lilac
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
  float albedo_scale;
  bool speckle;

  Eigen::Vector3f Shade(const RayHit& hit) const {
    const Eigen::Vector3d to_light = (light - hit.point).normalized();
    const double lambert = std::max(0.0, hit.normal.dot(to_light));
    const float gain = static_cast<float>(255.0 * (kAmbient + kDiffuse * lambert)) * albedo_scale *
                       (speckle ? SpeckleShade(hit.point) : 1.0f);
    return (SurfaceAlbedo(scene, hit.point) * gain).cwiseMin(255.0f);
  }
};

// A z-buffer rasterization of a mesh over `bounds` (pixels) at `scale` x `scale` samples per
// pixel: sample (gx, gy) sits at pixel (bounds.x + (gx + 0.5) / scale - 0.5, ...), so scale 1
// samples pixel centres and scale 4 the renderer's 4 x 4 subsamples.
class MeshRaster {
 public:
  MeshRaster(const TriangleMesh& mesh, const SimProjection& projection, double plate_angle_deg,
             cv::Rect bounds, int scale)
      : bounds_(bounds),
        scale_(scale),
        width_(bounds.width * scale),
        height_(bounds.height * scale) {
    triangle_.assign(static_cast<std::size_t>(width_) * height_, -1);
    std::vector<float> nearness(triangle_.size(), -std::numeric_limits<float>::infinity());
    const Eigen::Isometry3d cam_from_object = projection.rig.CamFromObject(plate_angle_deg);
    const Intrinsics& k = projection.rig.intrinsics;
    // Per vertex: grid position and a depth key that interpolates linearly on screen and grows
    // toward the camera (1 / z for a pinhole, -z for orthographic).
    std::vector<Eigen::Vector3d> screen(mesh.vertices.size());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
      const Eigen::Vector3d c = cam_from_object * mesh.vertices[i];
      double u, v, key;
      if (projection.orthographic) {
        u = projection.px_per_mm * c.x() + k.cx_px;
        v = projection.px_per_mm * c.y() + k.cy_px;
        key = -c.z();
      } else {
        const double z = std::max(c.z(), 1e-9);
        u = k.fx_px * c.x() / z + k.cx_px;
        v = k.fy_px * c.y() / z + k.cy_px;
        key = 1.0 / z;
      }
      screen[i] = Eigen::Vector3d((u - bounds.x + 0.5) * scale - 0.5,
                                  (v - bounds.y + 0.5) * scale - 0.5, key);
    }
    for (int t = 0; t < static_cast<int>(mesh.triangles.size()); ++t) {
      const auto& tri = mesh.triangles[t];
      const Eigen::Vector3d& a = screen[tri[0]];
      const Eigen::Vector3d& b = screen[tri[1]];
      const Eigen::Vector3d& c = screen[tri[2]];
      const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
      if (std::abs(area) < 1e-12) continue;
      const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}))));
      const int x1 =
          std::min(width_ - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}))));
      const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}))));
      const int y1 =
          std::min(height_ - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}))));
      const double inv_area = 1.0 / area;
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          // Barycentric weights; both windings (a mesh with holes shows its back faces).
          const double w0 = ((b.x() - x) * (c.y() - y) - (b.y() - y) * (c.x() - x)) * inv_area;
          const double w1 = ((c.x() - x) * (a.y() - y) - (c.y() - y) * (a.x() - x)) * inv_area;
          const double w2 = 1.0 - w0 - w1;
          if (w0 < 0.0 || w1 < 0.0 || w2 < 0.0) continue;
          const float key = static_cast<float>(w0 * a.z() + w1 * b.z() + w2 * c.z());
          const std::size_t i = static_cast<std::size_t>(y) * width_ + x;
          if (key > nearness[i]) {
            nearness[i] = key;
            triangle_[i] = t;
          }
        }
      }
    }
  }

  // The triangle seen by sample (gx, gy) of pixel-space sample grid, or -1.
  int TriangleAt(int gx, int gy) const {
    if (gx < 0 || gy < 0 || gx >= width_ || gy >= height_) return -1;
    return triangle_[static_cast<std::size_t>(gy) * width_ + gx];
  }
  const cv::Rect& bounds() const { return bounds_; }
  int scale() const { return scale_; }

 private:
  cv::Rect bounds_;
  int scale_;
  int width_, height_;
  std::vector<int> triangle_;
};

// Where a sample's ray meets the object: analytic shapes by ray casting, meshes through their
// rasterizations (scale 1 for pixel centres, 4 for subsamples).
class ObjectSampler {
 public:
  ObjectSampler(const Scene& scene, const SimProjection& projection, double plate_angle_deg,
                cv::Rect bounds)
      : scene_(scene) {
    if (scene.shape() == Shape::kMesh && bounds.area() > 0) {
      centres_ =
          std::make_unique<MeshRaster>(*scene.mesh(), projection, plate_angle_deg, bounds, 1);
      subsamples_ = std::make_unique<MeshRaster>(*scene.mesh(), projection, plate_angle_deg, bounds,
                                                 kSubsamples);
    }
  }

  // Sample (sx, sy) of pixel (u, v); sx < 0 means the pixel centre.
  std::optional<RayHit> Hit(int u, int v, int sx, int sy, const Eigen::Vector3d& origin,
                            const Eigen::Vector3d& direction) const {
    if (scene_.shape() != Shape::kMesh) return scene_.Intersect(origin, direction);
    if (!centres_) return std::nullopt;
    const cv::Rect& b = centres_->bounds();
    const int t = sx < 0 ? centres_->TriangleAt(u - b.x, v - b.y)
                         : subsamples_->TriangleAt((u - b.x) * kSubsamples + sx,
                                                   (v - b.y) * kSubsamples + sy);
    if (t < 0) return std::nullopt;
    const TriangleMesh& mesh = *scene_.mesh();
    const auto& tri = mesh.triangles[t];
    const Eigen::Vector3d& a = mesh.vertices[tri[0]];
    const Eigen::Vector3d& b1 = mesh.vertices[tri[1]];
    const Eigen::Vector3d& c = mesh.vertices[tri[2]];
    RayHit hit;
    // The ray passes through the triangle up to rounding; intersect its plane.
    Eigen::Vector3d normal = (b1 - a).cross(c - a).normalized();
    const double denominator = normal.dot(direction);
    if (std::abs(denominator) < 1e-12) return std::nullopt;
    hit.t = normal.dot(a - origin) / denominator;
    hit.point = origin + hit.t * direction;
    if (normal.dot(direction) > 0.0) normal = -normal;
    hit.normal = normal;
    return hit;
  }

 private:
  const Scene& scene_;
  std::unique_ptr<MeshRaster> centres_, subsamples_;
};

// The plate (a disc under z = 0) and the fixtures, as flat-coloured surfaces.
struct StageHit {
  double t = std::numeric_limits<double>::infinity();
  std::uint8_t id = kBackdropSurface;
};

StageHit HitStage(const Stage& stage, const Eigen::Matrix3d& table_from_object,
                  const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) {
  StageHit best;
  if (stage.plate_radius_mm > 0.0) {
    // Cylinder |xy| <= R, -thickness <= z <= 0, in the object frame (it is symmetric).
    constexpr double kInf = std::numeric_limits<double>::infinity();
    double lo = -kInf, hi = kInf;
    bool top = false;
    const double a = direction.head<2>().squaredNorm();
    const double half_b = origin.head<2>().dot(direction.head<2>());
    const double c = origin.head<2>().squaredNorm() - stage.plate_radius_mm * stage.plate_radius_mm;
    bool miss = false;
    if (a > 0.0) {
      const double disc = half_b * half_b - a * c;
      if (disc < 0.0) {
        miss = true;
      } else {
        const double root = std::sqrt(disc);
        lo = (-half_b - root) / a;
        hi = (-half_b + root) / a;
      }
    } else if (c > 0.0) {
      miss = true;
    }
    if (!miss && direction.z() != 0.0) {
      double z_lo = (-stage.plate_thickness_mm - origin.z()) / direction.z();
      double z_hi = -origin.z() / direction.z();
      const bool enters_top = direction.z() < 0.0;
      if (z_lo > z_hi) std::swap(z_lo, z_hi);
      if (z_lo > lo) {
        lo = z_lo;
        top = enters_top;
      }
      hi = std::min(hi, z_hi);
    } else if (!miss && (origin.z() < -stage.plate_thickness_mm || origin.z() > 0.0)) {
      miss = true;
    }
    if (!miss && lo < hi && lo > 0.0) {
      best.t = lo;
      best.id = top ? kPlateTopSurface : kPlateRimSurface;
    }
  }
  if (!stage.fixtures.empty()) {
    const Eigen::Vector3d o = table_from_object * origin;
    const Eigen::Vector3d d = table_from_object * direction;
    for (std::size_t i = 0; i < stage.fixtures.size(); ++i) {
      const Fixture& f = stage.fixtures[i];
      double t0 = -std::numeric_limits<double>::infinity(), t1 = -t0;
      bool miss = false;
      for (int axis = 0; axis < 3 && !miss; ++axis) {
        if (d[axis] == 0.0) {
          miss = o[axis] < f.min_mm[axis] || o[axis] > f.max_mm[axis];
          continue;
        }
        double near = (f.min_mm[axis] - o[axis]) / d[axis];
        double far = (f.max_mm[axis] - o[axis]) / d[axis];
        if (near > far) std::swap(near, far);
        t0 = std::max(t0, near);
        t1 = std::min(t1, far);
      }
      if (!miss && t0 <= t1 && t0 > 0.0 && t0 < best.t) {
        best.t = t0;
        best.id = static_cast<std::uint8_t>(kFixtureSurface + i);
      }
    }
  }
  return best;
}

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

namespace {

// Value noise: a hashed value in [0, 1] at each lattice point, trilinear in between.
double ValueNoise(const Eigen::Vector3d& point, double cell_mm, std::uint64_t salt) {
  const Eigen::Vector3d q = point / cell_mm;
  const Eigen::Vector3d base = q.array().floor();
  const Eigen::Vector3d f = q - base;
  double sum = 0.0;
  for (int corner = 0; corner < 8; ++corner) {
    const int dx = corner & 1, dy = (corner >> 1) & 1, dz = (corner >> 2) & 1;
    std::uint64_t h = salt;
    h = SplitMix64(h ^ static_cast<std::uint64_t>(static_cast<std::int64_t>(base.x()) + dx));
    h = SplitMix64(h ^ static_cast<std::uint64_t>(static_cast<std::int64_t>(base.y()) + dy));
    h = SplitMix64(h ^ static_cast<std::uint64_t>(static_cast<std::int64_t>(base.z()) + dz));
    const double value = static_cast<double>(h >> 11) * 0x1.0p-53;
    const double w =
        (dx ? f.x() : 1.0 - f.x()) * (dy ? f.y() : 1.0 - f.y()) * (dz ? f.z() : 1.0 - f.z());
    sum += w * value;
  }
  return sum;
}

}  // namespace

float SpeckleShade(const Eigen::Vector3d& point) {
  const double noise = 0.6 * ValueNoise(point, 1.5, 0x5EC1) + 0.4 * ValueNoise(point, 4.0, 0xB10B);
  return static_cast<float>(0.6 + 0.4 * noise);
}

std::uint64_t NoiseSeed(std::uint64_t seed, std::uint64_t sequence) {
  return SplitMix64(SplitMix64(seed) ^ sequence);
}

RenderOutput RenderScene(const Scene& scene, const SimProjection& projection,
                         double plate_angle_deg, const RenderSettings& settings,
                         std::uint64_t sequence, bool draw_object) {
  const int width = projection.width_px();
  const int height = projection.height_px();
  const Eigen::Vector3f& backdrop = settings.backdrop_bgr;
  const Stage& stage = settings.stage;
  RenderOutput out;
  cv::Mat image(height, width, CV_32FC3, cv::Scalar(backdrop[0], backdrop[1], backdrop[2]));
  out.surface = cv::Mat(height, width, CV_8UC1, cv::Scalar(kBackdropSurface));

  const Eigen::Isometry3d object_from_cam = projection.rig.CamFromObject(plate_angle_deg).inverse();
  const Eigen::Vector3d mid_object(0.0, 0.0, 0.5 * scene.height_mm());
  const double light_distance = (object_from_cam.translation() - mid_object).norm();
  const Shader shader{scene,
                      object_from_cam * Eigen::Vector3d(kLightRight * light_distance,
                                                        kLightDown * light_distance, 0.0),
                      settings.object_albedo, settings.speckle};
  const PixelRays rays(projection, plate_angle_deg);
  const Eigen::Matrix3d table_from_object = TableFromObject(plate_angle_deg).linear();

  // Where anything but the backdrop can appear.
  const cv::Rect object_bounds =
      draw_object ? ProjectedBounds(scene, projection, plate_angle_deg, 2) : cv::Rect();
  cv::Rect bounds = object_bounds;
  if (stage.plate_radius_mm > 0.0) {
    const double r = stage.plate_radius_mm;
    bounds |= ProjectedBoxBounds(Eigen::Vector3d(-r, -r, -stage.plate_thickness_mm),
                                 Eigen::Vector3d(r, r, 0.0), projection, plate_angle_deg, 2);
  }
  for (const Fixture& f : stage.fixtures) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = -lo;
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3d p((corner & 1) ? f.max_mm.x() : f.min_mm.x(),
                              (corner & 2) ? f.max_mm.y() : f.min_mm.y(),
                              (corner & 4) ? f.max_mm.z() : f.min_mm.z());
      const Eigen::Vector3d q = table_from_object.transpose() * p;
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    bounds |= ProjectedBoxBounds(lo, hi, projection, plate_angle_deg, 2);
  }
  const ObjectSampler object(scene, projection, plate_angle_deg, object_bounds);

  // The colour and surface of one sample (sx < 0: the pixel centre).
  auto trace = [&](int u, int v, int sx, int sy, std::uint8_t* id) -> Eigen::Vector3f {
    const double du = sx < 0 ? 0.0 : (sx + 0.5) / kSubsamples - 0.5;
    const double dv = sy < 0 ? 0.0 : (sy + 0.5) / kSubsamples - 0.5;
    const Eigen::Vector3d origin = rays.Origin(u + du, v + dv);
    const Eigen::Vector3d direction = rays.Direction(u + du, v + dv);
    std::optional<RayHit> hit;
    if (draw_object && object_bounds.contains(cv::Point(u, v))) {
      hit = object.Hit(u, v, sx, sy, origin, direction);
    }
    const StageHit stage_hit = HitStage(stage, table_from_object, origin, direction);
    if (hit && hit->t <= stage_hit.t) {
      *id = kObjectSurface;
      return shader.Shade(*hit);
    }
    *id = stage_hit.id;
    switch (stage_hit.id) {
      case kBackdropSurface:
        return backdrop;
      case kPlateTopSurface:
        return stage.plate_top_bgr;
      case kPlateRimSurface:
        return stage.plate_rim_bgr;
      default:
        return stage.fixtures[stage_hit.id - kFixtureSurface].bgr;
    }
  };

  // Pass 1: one sample per pixel centre.
  for (int v = bounds.y; v < bounds.y + bounds.height; ++v) {
    auto* row = image.ptr<cv::Vec3f>(v);
    auto* ids = out.surface.ptr<std::uint8_t>(v);
    for (int u = bounds.x; u < bounds.x + bounds.width; ++u) {
      const Eigen::Vector3f c = trace(u, v, -1, -1, &ids[u]);
      row[u] = cv::Vec3f(c[0], c[1], c[2]);
    }
  }
  // Pass 2: supersample the pixels next to another surface.
  cv::Mat padded;
  cv::copyMakeBorder(out.surface, padded, 1, 1, 1, 1, cv::BORDER_REPLICATE);
  const cv::Rect edge_zone =
      (bounds + cv::Size(2, 2) - cv::Point(1, 1)) & cv::Rect(0, 0, width, height);
  for (int v = edge_zone.y; v < edge_zone.y + edge_zone.height; ++v) {
    auto* row = image.ptr<cv::Vec3f>(v);
    for (int u = edge_zone.x; u < edge_zone.x + edge_zone.width; ++u) {
      const std::uint8_t centre = padded.at<std::uint8_t>(v + 1, u + 1);
      bool edge = false;
      for (int dy = 0; dy <= 2 && !edge; ++dy) {
        const auto* p = padded.ptr<std::uint8_t>(v + dy);
        edge = p[u] != centre || p[u + 1] != centre || p[u + 2] != centre;
      }
      if (!edge) continue;
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      std::uint8_t id;
      for (int sy = 0; sy < kSubsamples; ++sy) {
        for (int sx = 0; sx < kSubsamples; ++sx) sum += trace(u, v, sx, sy, &id);
      }
      sum /= static_cast<float>(kSubsamples * kSubsamples);
      row[u] = cv::Vec3f(sum[0], sum[1], sum[2]);
    }
  }
  out.true_mask = out.surface == kObjectSurface;
  if (settings.blur_sigma_px > 0.0) {
    cv::GaussianBlur(image, image, cv::Size(), settings.blur_sigma_px, settings.blur_sigma_px,
                     cv::BORDER_REPLICATE);
  }
  if (settings.noise_sigma > 0.0) {
    cv::RNG rng(NoiseSeed(settings.seed, sequence));
    cv::Mat noise(height, width, CV_32FC3);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, settings.noise_sigma);
    image += noise;
  }
  image.convertTo(out.image, CV_8UC3);
  return out;
}

cv::Mat RenderFrame(const Scene& scene, const SimProjection& projection, double plate_angle_deg,
                    const RenderSettings& settings, std::uint64_t sequence) {
  return RenderScene(scene, projection, plate_angle_deg, settings, sequence).image;
}

}  // namespace revolve::capture
