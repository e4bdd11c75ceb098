#include "capture/synthetic/scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

namespace revolve::capture {
namespace {

constexpr double kPi = std::numbers::pi;
// The vase's distance function searches a polyline of this many segments (chord error below
// 1e-5 mm for any sensible size), then the exact profile near the best segment.
constexpr int kProfileSamples = 4096;

// Distance from q to the segment [a, b] in the meridian half-plane.
double SegmentDistance(const Eigen::Vector2d& q, const Eigen::Vector2d& a,
                       const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double length2 = ab.squaredNorm();
  const double s = length2 > 0.0 ? std::clamp((q - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
  return (q - (a + s * ab)).norm();
}

}  // namespace

Expected<Shape> ParseShape(std::string_view name) {
  if (name == "sphere") return Shape::kSphere;
  if (name == "cylinder") return Shape::kCylinder;
  if (name == "vase") return Shape::kVase;
  return MakeError(ErrorCode::kBadInput,
                   fmt::format("unknown object \"{}\" (sphere, cylinder or vase)", name));
}

std::string_view ToString(Shape shape) {
  switch (shape) {
    case Shape::kSphere:
      return "sphere";
    case Shape::kCylinder:
      return "cylinder";
    case Shape::kVase:
      return "vase";
  }
  return "?";
}

double VaseRadiusMm(double z_mm, double radius_mm, double height_mm) {
  const double t = z_mm / height_mm;
  return radius_mm * (kVaseMean + kVaseSwing * std::cos(2.0 * kPi * (t - kVaseBellyAt)));
}

double VaseRadiusSlope(double z_mm, double radius_mm, double height_mm) {
  const double t = z_mm / height_mm;
  return -radius_mm * kVaseSwing * 2.0 * kPi / height_mm * std::sin(2.0 * kPi * (t - kVaseBellyAt));
}

Expected<Scene> Scene::Create(Shape shape, double radius_mm, double height_mm) {
  if (!(radius_mm > 0.0) || !std::isfinite(radius_mm)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("object radius must be positive, got {} mm", radius_mm));
  }
  if (shape != Shape::kSphere && (!(height_mm > 0.0) || !std::isfinite(height_mm))) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("object height must be positive, got {} mm", height_mm));
  }
  Scene scene;
  scene.shape_ = shape;
  scene.radius_mm_ = radius_mm;
  scene.height_mm_ = shape == Shape::kSphere ? 2.0 * radius_mm : height_mm;
  if (shape == Shape::kVase) {
    auto profile = std::make_shared<std::vector<Eigen::Vector2d>>();
    profile->reserve(kProfileSamples + 1);
    for (int i = 0; i <= kProfileSamples; ++i) {
      const double z = height_mm * i / kProfileSamples;
      profile->emplace_back(VaseRadiusMm(z, radius_mm, height_mm), z);
    }
    scene.profile_ = std::move(profile);
  }
  return scene;
}

double Scene::ProfileRadiusMm(double z_mm) const {
  if (z_mm < 0.0 || z_mm > height_mm_) return 0.0;
  switch (shape_) {
    case Shape::kSphere: {
      const double dz = z_mm - radius_mm_;
      return std::sqrt(std::max(0.0, radius_mm_ * radius_mm_ - dz * dz));
    }
    case Shape::kCylinder:
      return radius_mm_;
    case Shape::kVase:
      return VaseRadiusMm(z_mm, radius_mm_, height_mm_);
  }
  return 0.0;
}

bool Scene::Contains(const Eigen::Vector3d& point) const {
  if (shape_ == Shape::kSphere) {
    return (point - Eigen::Vector3d(0.0, 0.0, radius_mm_)).norm() <= radius_mm_;
  }
  if (point.z() < 0.0 || point.z() > height_mm_) return false;
  return point.head<2>().norm() <= ProfileRadiusMm(point.z());
}

bool Scene::BoundingInterval(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                             double* t_in, double* t_out, bool* entered_by_cap) const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double lo = -kInf;
  double hi = kInf;
  const double a = direction.head<2>().squaredNorm();
  const double half_b = origin.head<2>().dot(direction.head<2>());
  const double c = origin.head<2>().squaredNorm() - radius_mm_ * radius_mm_;
  if (a > 0.0) {
    const double discriminant = half_b * half_b - a * c;
    if (discriminant < 0.0) return false;
    const double root = std::sqrt(discriminant);
    lo = (-half_b - root) / a;
    hi = (-half_b + root) / a;
  } else if (c > 0.0) {
    return false;
  }
  bool by_cap = false;
  if (direction.z() != 0.0) {
    double z_lo = -origin.z() / direction.z();
    double z_hi = (height_mm_ - origin.z()) / direction.z();
    if (z_lo > z_hi) std::swap(z_lo, z_hi);
    if (z_lo > lo) {
      lo = z_lo;
      by_cap = true;
    }
    hi = std::min(hi, z_hi);
  } else if (origin.z() < 0.0 || origin.z() > height_mm_) {
    return false;
  }
  if (!(lo < hi) || hi <= 0.0) return false;
  *t_in = std::max(lo, 0.0);
  *t_out = hi;
  *entered_by_cap = by_cap;
  return true;
}

std::optional<double> Scene::VaseEntry(const Eigen::Vector3d& origin,
                                       const Eigen::Vector3d& direction, bool* by_cap) const {
  double t0 = 0.0;
  double t1 = 0.0;
  if (!BoundingInterval(origin, direction, &t0, &t1, by_cap)) return std::nullopt;
  // Inside the enclosing cylinder the ray is in the solid where
  //   f(t) = rho(t)^2 - r(z(t))^2 <= 0.
  // rho^2 is quadratic in t, so f'' >= m := 2 |d_xy|^2 - d_z^2 max (r^2)'' everywhere, and
  //   f(t + s) >= f(t) + f'(t) s + m s^2 / 2.
  // Stepping to the first root of that bound never steps over a crossing; it converges like
  // Newton's method toward a root from outside, and ends at once when the bound has no root
  // left before t1 (a miss).
  const double w = 2.0 * kPi / height_mm_;
  const double phase = -2.0 * kPi * kVaseBellyAt;
  const double mean = radius_mm_ * kVaseMean;
  const double swing = radius_mm_ * kVaseSwing;
  // max over theta of (r^2)'' = 2 swing w^2 (swing sin^2 - (mean + swing cos) cos), at
  // cos = -mean / (4 swing) when that lies in [-1, 1].
  const double c_star = std::clamp(-mean / (4.0 * swing), -1.0, 1.0);
  const double max_r2_curvature =
      2.0 * swing * w * w * (swing * (1.0 - c_star * c_star) - (mean + swing * c_star) * c_star);
  const double m = 2.0 * direction.head<2>().squaredNorm() -
                   direction.z() * direction.z() * std::max(0.0, max_r2_curvature);
  const double tolerance = 1e-7 * (radius_mm_ + height_mm_) / direction.norm();
  double t = t0;
  for (int iteration = 0; iteration < 200; ++iteration) {
    const Eigen::Vector3d p = origin + t * direction;
    const double theta = w * p.z() + phase;
    const double r = mean + swing * std::cos(theta);
    const double dr_dz = -swing * w * std::sin(theta);
    const double f = p.head<2>().squaredNorm() - r * r;
    if (f <= 0.0) {
      if (t > t0) *by_cap = false;
      return t;
    }
    const double df = 2.0 * p.head<2>().dot(direction.head<2>()) - 2.0 * r * dr_dz * direction.z();
    // Smallest positive root of f + df s + m s^2 / 2.
    double step;
    if (std::abs(m) < 1e-12) {
      if (df >= 0.0) return std::nullopt;
      step = -f / df;
    } else {
      const double discriminant = df * df - 2.0 * m * f;
      if (discriminant < 0.0) return std::nullopt;  // m > 0 and the bound stays positive
      const double root = std::sqrt(discriminant);
      // m > 0: the smaller root, valid only when df < 0; m < 0: the one positive root.
      if (m > 0.0 && df >= 0.0) return std::nullopt;
      // Written to avoid cancellation: 2 f / (-df + root) for m > 0, same formula for m < 0.
      step = 2.0 * f / (root - df);
    }
    if (t + step > t1) return std::nullopt;
    if (step < tolerance) {
      *by_cap = false;
      return t + step;
    }
    t += step;
  }
  return std::nullopt;
}

bool Scene::Hits(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const {
  switch (shape_) {
    case Shape::kSphere: {
      const Eigen::Vector3d m = origin - Eigen::Vector3d(0.0, 0.0, radius_mm_);
      const double a = direction.squaredNorm();
      const double half_b = m.dot(direction);
      const double c = m.squaredNorm() - radius_mm_ * radius_mm_;
      const double discriminant = half_b * half_b - a * c;
      return discriminant >= 0.0 && -half_b + std::sqrt(discriminant) > 0.0;
    }
    case Shape::kCylinder: {
      double t0, t1;
      bool by_cap;
      return BoundingInterval(origin, direction, &t0, &t1, &by_cap);
    }
    case Shape::kVase: {
      bool by_cap;
      return VaseEntry(origin, direction, &by_cap).has_value();
    }
  }
  return false;
}

std::optional<RayHit> Scene::Intersect(const Eigen::Vector3d& origin,
                                       const Eigen::Vector3d& direction) const {
  RayHit hit;
  switch (shape_) {
    case Shape::kSphere: {
      const Eigen::Vector3d center(0.0, 0.0, radius_mm_);
      const Eigen::Vector3d m = origin - center;
      const double half_b = m.dot(direction);
      const double c = m.squaredNorm() - radius_mm_ * radius_mm_;
      const double discriminant = half_b * half_b - c;
      if (discriminant < 0.0) return std::nullopt;
      const double root = std::sqrt(discriminant);
      hit.t = -half_b - root;
      if (hit.t <= 0.0) hit.t = -half_b + root;
      if (hit.t <= 0.0) return std::nullopt;
      hit.point = origin + hit.t * direction;
      hit.normal = (hit.point - center) / radius_mm_;
      return hit;
    }
    case Shape::kCylinder: {
      double t1;
      bool by_cap;
      if (!BoundingInterval(origin, direction, &hit.t, &t1, &by_cap)) return std::nullopt;
      hit.point = origin + hit.t * direction;
      if (by_cap) {
        hit.normal = Eigen::Vector3d(0.0, 0.0, direction.z() > 0.0 ? -1.0 : 1.0);
      } else {
        hit.normal = Eigen::Vector3d(hit.point.x(), hit.point.y(), 0.0).normalized();
      }
      return hit;
    }
    case Shape::kVase: {
      bool by_cap = false;
      const std::optional<double> t = VaseEntry(origin, direction, &by_cap);
      if (!t) return std::nullopt;
      hit.t = *t;
      hit.point = origin + hit.t * direction;
      if (by_cap) {
        hit.normal = Eigen::Vector3d(0.0, 0.0, direction.z() > 0.0 ? -1.0 : 1.0);
      } else {
        const double rho = hit.point.head<2>().norm();
        const double slope = VaseRadiusSlope(hit.point.z(), radius_mm_, height_mm_);
        hit.normal = Eigen::Vector3d(hit.point.x() / rho, hit.point.y() / rho, -slope).normalized();
      }
      return hit;
    }
  }
  return std::nullopt;
}

double Scene::VolumeMm3() const {
  switch (shape_) {
    case Shape::kSphere:
      return 4.0 / 3.0 * kPi * radius_mm_ * radius_mm_ * radius_mm_;
    case Shape::kCylinder:
      return kPi * radius_mm_ * radius_mm_ * height_mm_;
    case Shape::kVase:
      return kPi * radius_mm_ * radius_mm_ * height_mm_ *
             (kVaseMean * kVaseMean + 0.5 * kVaseSwing * kVaseSwing);
  }
  return 0.0;
}

double Scene::MeridianDistanceMm(double rho_mm, double z_mm) const {
  const Eigen::Vector2d q(rho_mm, z_mm);
  const std::vector<Eigen::Vector2d>& profile = *profile_;
  // The caps, then the profile polyline around z, widening while a segment can still be closer.
  double best = std::min(SegmentDistance(q, Eigen::Vector2d(0.0, 0.0), profile.front()),
                         SegmentDistance(q, Eigen::Vector2d(0.0, height_mm_), profile.back()));
  const int n = kProfileSamples;
  const int k = std::clamp(static_cast<int>(std::lround(z_mm / height_mm_ * n)), 0, n);
  int best_segment = -1;
  auto consider = [&](int i) {  // segment [i, i + 1]
    const double d = SegmentDistance(q, profile[i], profile[i + 1]);
    if (d < best) {
      best = d;
      best_segment = i;
    }
  };
  for (int i = k; i < n && profile[i].y() - z_mm < best; ++i) consider(i);
  for (int i = k - 1; i >= 0 && z_mm - profile[i + 1].y() < best; --i) consider(i);
  if (best_segment < 0) return best;
  // Refine on the exact profile: Newton on the squared distance's derivative, kept within the
  // neighbouring segments; the polyline value stands when the refinement does not improve it.
  const double lo = profile[std::max(best_segment - 1, 0)].y();
  const double hi = profile[std::min(best_segment + 2, n)].y();
  double z = std::clamp(z_mm, lo, hi);
  const double w = 2.0 * kPi / height_mm_;
  for (int iteration = 0; iteration < 8; ++iteration) {
    const double r = VaseRadiusMm(z, radius_mm_, height_mm_);
    const double r1 = VaseRadiusSlope(z, radius_mm_, height_mm_);
    const double r2 = -radius_mm_ * kVaseSwing * w * w * std::cos(w * z - 2.0 * kPi * kVaseBellyAt);
    const double f = -(rho_mm - r) * r1 - (z_mm - z);
    const double df = r1 * r1 - (rho_mm - r) * r2 + 1.0;
    if (df <= 0.0) break;
    z = std::clamp(z - f / df, lo, hi);
  }
  const double refined = std::hypot(rho_mm - VaseRadiusMm(z, radius_mm_, height_mm_), z_mm - z);
  return std::min(best, refined);
}

double Scene::DistanceMm(const Eigen::Vector3d& point) const {
  if (shape_ == Shape::kSphere) {
    return std::abs((point - Eigen::Vector3d(0.0, 0.0, radius_mm_)).norm() - radius_mm_);
  }
  const double rho = point.head<2>().norm();
  if (shape_ == Shape::kCylinder) {
    const Eigen::Vector2d q(rho, point.z());
    const Eigen::Vector2d bottom_rim(radius_mm_, 0.0), top_rim(radius_mm_, height_mm_);
    return std::min({SegmentDistance(q, Eigen::Vector2d(0.0, 0.0), bottom_rim),
                     SegmentDistance(q, bottom_rim, top_rim),
                     SegmentDistance(q, Eigen::Vector2d(0.0, height_mm_), top_rim)});
  }
  return MeridianDistanceMm(rho, point.z());
}

std::string Scene::Describe() const {
  if (shape_ == Shape::kSphere) return fmt::format("sphere r={:g} mm", radius_mm_);
  return fmt::format("{} r={:g} mm h={:g} mm", ToString(shape_), radius_mm_, height_mm_);
}

SceneTruth Scene::Truth() const {
  SceneTruth truth;
  truth.description = Describe();
  truth.volume_mm3 = VolumeMm3();
  truth.distance_mm = [scene = *this](const Eigen::Vector3d& p) { return scene.DistanceMm(p); };
  if (shape_ == Shape::kSphere) {
    truth.sphere_center_mm = Eigen::Vector3d(0.0, 0.0, radius_mm_);
    truth.sphere_radius_mm = radius_mm_;
  }
  return truth;
}

PixelRays::PixelRays(const Rig& rig, double plate_angle_deg) {
  const Eigen::Isometry3d object_from_cam = rig.CamFromObject(plate_angle_deg).inverse();
  origin_ = object_from_cam.translation();
  object_from_pixel_ = object_from_cam.linear() * rig.intrinsics.K().inverse();
}

cv::Rect ProjectedBounds(const Scene& scene, const Rig& rig, double plate_angle_deg,
                         int margin_px) {
  const int width = rig.intrinsics.width_px;
  const int height = rig.intrinsics.height_px;
  const cv::Rect image(0, 0, width, height);
  const Matrix34d pixel_from_object = rig.PixelFromObject(plate_angle_deg);
  const double r = scene.bounding_radius_mm();
  double u_min = std::numeric_limits<double>::infinity(), v_min = u_min;
  double u_max = -u_min, v_max = -u_min;
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d p((corner & 1) ? r : -r, (corner & 2) ? r : -r,
                            (corner & 4) ? scene.height_mm() : 0.0);
    const Eigen::Vector3d h = pixel_from_object.leftCols<3>() * p + pixel_from_object.col(3);
    if (h.z() <= 1e-9) return image;  // the box reaches behind the camera: look everywhere
    u_min = std::min(u_min, h.x() / h.z());
    u_max = std::max(u_max, h.x() / h.z());
    v_min = std::min(v_min, h.y() / h.z());
    v_max = std::max(v_max, h.y() / h.z());
  }
  // Clamp in double before converting, so far-off boxes cannot overflow an int.
  auto clamp = [](double x, int limit) { return std::clamp(x, -1.0, limit + 1.0); };
  const int x0 = static_cast<int>(std::floor(clamp(u_min, width))) - margin_px;
  const int x1 = static_cast<int>(std::ceil(clamp(u_max, width))) + margin_px;
  const int y0 = static_cast<int>(std::floor(clamp(v_min, height))) - margin_px;
  const int y1 = static_cast<int>(std::ceil(clamp(v_max, height))) + margin_px;
  return cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1) & image;
}

cv::Mat RenderTrueMask(const Scene& scene, const Rig& rig, double plate_angle_deg) {
  cv::Mat mask(rig.intrinsics.height_px, rig.intrinsics.width_px, CV_8UC1, cv::Scalar(0));
  const cv::Rect bounds = ProjectedBounds(scene, rig, plate_angle_deg, 1);
  const PixelRays rays(rig, plate_angle_deg);
  for (int v = bounds.y; v < bounds.y + bounds.height; ++v) {
    auto* row = mask.ptr<std::uint8_t>(v);
    for (int u = bounds.x; u < bounds.x + bounds.width; ++u) {
      if (scene.Hits(rays.origin(), rays.Direction(u, v))) row[u] = 255;
    }
  }
  return mask;
}

}  // namespace revolve::capture
