#include "capture/synthetic/scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include "capture/synthetic/mesh.h"

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
  if (name == "cone") return Shape::kCone;
  if (name == "box") return Shape::kBox;
  if (name == "torus") return Shape::kTorus;
  if (name == "mesh") return Shape::kMesh;
  return MakeError(ErrorCode::kBadInput,
                   fmt::format("unknown object \"{}\" (sphere, cylinder, vase, cone, box, torus "
                               "or mesh)",
                               name));
}

std::string_view ToString(Shape shape) {
  switch (shape) {
    case Shape::kSphere:
      return "sphere";
    case Shape::kCylinder:
      return "cylinder";
    case Shape::kVase:
      return "vase";
    case Shape::kCone:
      return "cone";
    case Shape::kBox:
      return "box";
    case Shape::kTorus:
      return "torus";
    case Shape::kMesh:
      return "mesh";
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
  if (shape == Shape::kMesh) {
    return MakeError(ErrorCode::kBadInput, "a mesh scene needs a mesh (Scene::CreateMesh)");
  }
  if (shape == Shape::kTorus && !(radius_mm > 0.5 * height_mm)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("a torus needs radius_mm ({}) > height_mm / 2 ({}): its tube is "
                                 "height_mm thick",
                                 radius_mm, 0.5 * height_mm));
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
    case Shape::kCone:
      return radius_mm_ * (1.0 - z_mm / height_mm_);
    case Shape::kBox:
    case Shape::kMesh:
      return radius_mm_;
    case Shape::kTorus: {
      const double a = 0.5 * height_mm_;
      const double dz = z_mm - a;
      return radius_mm_ - a + std::sqrt(std::max(0.0, a * a - dz * dz));
    }
  }
  return 0.0;
}

double Scene::bounding_radius_mm() const {
  return shape_ == Shape::kBox ? radius_mm_ * std::numbers::sqrt2 : radius_mm_;
}

double Scene::TorusSdf(const Eigen::Vector3d& point) const {
  const double a = 0.5 * height_mm_;
  const double major = radius_mm_ - a;
  return std::hypot(point.head<2>().norm() - major, point.z() - a) - a;
}

bool Scene::Contains(const Eigen::Vector3d& point) const {
  switch (shape_) {
    case Shape::kSphere:
      return (point - Eigen::Vector3d(0.0, 0.0, radius_mm_)).norm() <= radius_mm_;
    case Shape::kBox:
      return std::abs(point.x()) <= radius_mm_ && std::abs(point.y()) <= radius_mm_ &&
             point.z() >= 0.0 && point.z() <= height_mm_;
    case Shape::kTorus:
      return TorusSdf(point) <= 0.0;
    case Shape::kMesh: {
      // Parity of crossings along a fixed, slightly skewed ray.
      const Eigen::Vector3d d = Eigen::Vector3d(0.5773, 0.5774, 0.5775).normalized();
      int crossings = 0;
      for (const auto& t : mesh_->triangles) {
        if (RayTriangle(point, d, mesh_->vertices[t[0]], mesh_->vertices[t[1]],
                        mesh_->vertices[t[2]])) {
          ++crossings;
        }
      }
      return crossings % 2 == 1;
    }
    default:
      break;
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
  const double bounding = bounding_radius_mm();
  const double c = origin.head<2>().squaredNorm() - bounding * bounding;
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
    default:
      return Intersect(origin, direction.normalized()).has_value();
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
    default:
      return IntersectConvexOrMarched(origin, direction);
  }
  return std::nullopt;
}

std::optional<RayHit> Scene::IntersectConvexOrMarched(const Eigen::Vector3d& origin,
                                                      const Eigen::Vector3d& direction) const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  RayHit hit;
  switch (shape_) {
    case Shape::kBox: {
      // Slabs.
      const Eigen::Vector3d lo(-radius_mm_, -radius_mm_, 0.0),
          hi(radius_mm_, radius_mm_, height_mm_);
      double t0 = -kInf, t1 = kInf;
      int axis = -1;
      for (int a = 0; a < 3; ++a) {
        if (direction[a] == 0.0) {
          if (origin[a] < lo[a] || origin[a] > hi[a]) return std::nullopt;
          continue;
        }
        double near = (lo[a] - origin[a]) / direction[a];
        double far = (hi[a] - origin[a]) / direction[a];
        if (near > far) std::swap(near, far);
        if (near > t0) {
          t0 = near;
          axis = a;
        }
        t1 = std::min(t1, far);
      }
      if (!(t0 <= t1) || t0 <= 0.0 || axis < 0) return std::nullopt;
      hit.t = t0;
      hit.point = origin + t0 * direction;
      hit.normal = Eigen::Vector3d::Zero();
      hit.normal[axis] = direction[axis] > 0.0 ? -1.0 : 1.0;
      return hit;
    }
    case Shape::kCone: {
      // Inside: rho^2 <= (R (1 - z / h))^2 with 0 <= z <= h (the slab drops the upper nappe).
      const double k = radius_mm_ / height_mm_;
      const Eigen::Vector3d& o = origin;
      const Eigen::Vector3d& d = direction;
      const double w0 = radius_mm_ - k * o.z();  // R (1 - z/h) at t = 0
      const double qa = d.head<2>().squaredNorm() - k * k * d.z() * d.z();
      const double qb = 2.0 * (o.head<2>().dot(d.head<2>()) + k * d.z() * w0);
      const double qc = o.head<2>().squaredNorm() - w0 * w0;
      // Intervals where the quadratic is <= 0.
      std::vector<std::pair<double, double>> inside;
      if (std::abs(qa) < 1e-12) {
        if (std::abs(qb) < 1e-300) {
          if (qc <= 0.0) inside.emplace_back(-kInf, kInf);
        } else if (qb > 0.0) {
          inside.emplace_back(-kInf, -qc / qb);
        } else {
          inside.emplace_back(-qc / qb, kInf);
        }
      } else {
        const double disc = qb * qb - 4.0 * qa * qc;
        if (disc >= 0.0) {
          const double root = std::sqrt(disc);
          double r0 = (-qb - root) / (2.0 * qa), r1 = (-qb + root) / (2.0 * qa);
          if (r0 > r1) std::swap(r0, r1);
          if (qa > 0.0) {
            inside.emplace_back(r0, r1);
          } else {
            inside.emplace_back(-kInf, r0);
            inside.emplace_back(r1, kInf);
          }
        } else if (qa < 0.0) {
          inside.emplace_back(-kInf, kInf);
        }
      }
      double s0 = -kInf, s1 = kInf;
      if (d.z() != 0.0) {
        s0 = -o.z() / d.z();
        s1 = (height_mm_ - o.z()) / d.z();
        if (s0 > s1) std::swap(s0, s1);
      } else if (o.z() < 0.0 || o.z() > height_mm_) {
        return std::nullopt;
      }
      double best = kInf;
      bool by_cap = false;
      for (const auto& [lo, hi] : inside) {
        const double t_lo = std::max(lo, s0), t_hi = std::min(hi, s1);
        if (t_lo <= t_hi && t_lo > 0.0 && t_lo < best) {
          best = t_lo;
          by_cap = s0 >= lo;
        }
      }
      if (best == kInf) return std::nullopt;
      hit.t = best;
      hit.point = o + best * d;
      if (by_cap) {
        hit.normal = Eigen::Vector3d(0.0, 0.0, d.z() > 0.0 ? -1.0 : 1.0);
      } else {
        const double rho = std::max(hit.point.head<2>().norm(), 1e-12);
        hit.normal = Eigen::Vector3d(hit.point.x() / rho, hit.point.y() / rho, k).normalized();
      }
      return hit;
    }
    case Shape::kTorus: {
      // Sphere tracing inside the enclosing cylinder: the signed distance never oversteps.
      double t0, t1;
      bool by_cap;
      if (!BoundingInterval(origin, direction, &t0, &t1, &by_cap)) return std::nullopt;
      const double tolerance = 1e-7 * (radius_mm_ + height_mm_);
      double t = t0;
      for (int iteration = 0; iteration < 2000 && t <= t1; ++iteration) {
        const double d = TorusSdf(origin + t * direction);
        if (d < tolerance) {
          hit.t = t;
          hit.point = origin + t * direction;
          const double a = 0.5 * height_mm_;
          const double rho = std::max(hit.point.head<2>().norm(), 1e-12);
          const Eigen::Vector3d centre((radius_mm_ - a) * hit.point.x() / rho,
                                       (radius_mm_ - a) * hit.point.y() / rho, a);
          hit.normal = (hit.point - centre).normalized();
          return hit;
        }
        t += d;
      }
      return std::nullopt;
    }
    case Shape::kMesh: {
      double t0, t1;
      bool by_cap;
      if (!BoundingInterval(origin, direction, &t0, &t1, &by_cap)) return std::nullopt;
      double best = kInf;
      int best_triangle = -1;
      for (int i = 0; i < static_cast<int>(mesh_->triangles.size()); ++i) {
        const auto& tri = mesh_->triangles[i];
        const auto t = RayTriangle(origin, direction, mesh_->vertices[tri[0]],
                                   mesh_->vertices[tri[1]], mesh_->vertices[tri[2]]);
        if (t && *t < best) {
          best = *t;
          best_triangle = i;
        }
      }
      if (best_triangle < 0) return std::nullopt;
      const auto& tri = mesh_->triangles[best_triangle];
      hit.t = best;
      hit.point = origin + best * direction;
      hit.normal = (mesh_->vertices[tri[1]] - mesh_->vertices[tri[0]])
                       .cross(mesh_->vertices[tri[2]] - mesh_->vertices[tri[0]])
                       .normalized();
      if (hit.normal.dot(direction) > 0.0) hit.normal = -hit.normal;
      return hit;
    }
    default:
      return std::nullopt;
  }
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
    case Shape::kCone:
      return kPi * radius_mm_ * radius_mm_ * height_mm_ / 3.0;
    case Shape::kBox:
      return 4.0 * radius_mm_ * radius_mm_ * height_mm_;
    case Shape::kTorus: {
      const double a = 0.5 * height_mm_;
      return 2.0 * kPi * kPi * (radius_mm_ - a) * a * a;
    }
    case Shape::kMesh:
      return std::abs(MeshVolume(*mesh_));
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
  switch (shape_) {
    case Shape::kCone: {
      const Eigen::Vector2d q(point.head<2>().norm(), point.z());
      return std::min(
          SegmentDistance(q, Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(radius_mm_, 0.0)),
          SegmentDistance(q, Eigen::Vector2d(radius_mm_, 0.0), Eigen::Vector2d(0.0, height_mm_)));
    }
    case Shape::kBox: {
      const Eigen::Vector3d centre(0.0, 0.0, 0.5 * height_mm_);
      const Eigen::Vector3d half(radius_mm_, radius_mm_, 0.5 * height_mm_);
      const Eigen::Vector3d q = (point - centre).cwiseAbs() - half;
      const double outside = q.cwiseMax(0.0).norm();
      return outside > 0.0 ? outside : -q.maxCoeff();
    }
    case Shape::kTorus:
      return std::abs(TorusSdf(point));
    case Shape::kMesh:
      return mesh_index_->Distance(point);
    default:
      break;
  }
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
  if (shape_ == Shape::kMesh) return fmt::format("mesh {} h={:g} mm", name_, height_mm_);
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
  TriangleMesh surface = Tessellate();
  truth.mesh_vertices_mm = std::move(surface.vertices);
  truth.mesh_triangles = std::move(surface.triangles);
  return truth;
}

Expected<Scene> Scene::CreateMesh(const TriangleMesh& mesh, double height_mm, std::string name) {
  if (mesh.triangles.empty() || mesh.vertices.empty()) {
    return MakeError(ErrorCode::kBadInput, fmt::format("mesh {} is empty", name));
  }
  if (!(height_mm > 0.0) || !std::isfinite(height_mm)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("object height must be positive, got {} mm", height_mm));
  }
  Eigen::Vector3d lo = mesh.vertices.front(), hi = lo;
  for (const auto& v : mesh.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  if (!(hi.z() - lo.z() > 0.0)) {
    return MakeError(ErrorCode::kBadInput, fmt::format("mesh {} is flat (no height)", name));
  }
  const double scale = height_mm / (hi.z() - lo.z());
  const Eigen::Vector3d shift(-0.5 * (lo.x() + hi.x()), -0.5 * (lo.y() + hi.y()), -lo.z());
  auto placed = std::make_shared<TriangleMesh>(mesh);
  double radius = 0.0;
  for (auto& v : placed->vertices) {
    v = (v + shift) * scale;
    radius = std::max(radius, v.head<2>().norm());
  }
  Scene scene;
  scene.shape_ = Shape::kMesh;
  scene.radius_mm_ = radius;
  scene.height_mm_ = height_mm;
  scene.name_ = std::move(name);
  scene.mesh_ = placed;
  scene.mesh_index_ = std::make_shared<MeshGrid>(placed);
  return scene;
}

TriangleMesh Scene::Tessellate(int segments) const {
  if (shape_ == Shape::kMesh) return *mesh_;
  TriangleMesh out;
  segments = std::max(segments, 8);
  auto add_grid = [&](auto point_at, int rows, int columns, bool wrap_columns) {
    // A (rows + 1) x (columns + 1 or columns) grid of points, two triangles per cell.
    const int base = static_cast<int>(out.vertices.size());
    const int stored_columns = wrap_columns ? columns : columns + 1;
    for (int i = 0; i <= rows; ++i) {
      for (int j = 0; j < stored_columns; ++j) out.vertices.push_back(point_at(i, j));
    }
    for (int i = 0; i < rows; ++i) {
      for (int j = 0; j < columns; ++j) {
        const int j1 = wrap_columns ? (j + 1) % columns : j + 1;
        const int a = base + i * stored_columns + j, b = base + i * stored_columns + j1;
        const int c = base + (i + 1) * stored_columns + j, d = base + (i + 1) * stored_columns + j1;
        out.triangles.emplace_back(a, b, d);
        out.triangles.emplace_back(a, d, c);
      }
    }
  };
  auto ring = [&](double rho, double z, int j) {
    const double phi = 2.0 * kPi * j / segments;
    return Eigen::Vector3d(rho * std::cos(phi), rho * std::sin(phi), z);
  };
  switch (shape_) {
    case Shape::kBox: {
      const double r = radius_mm_, h = height_mm_;
      const Eigen::Vector3d c[8] = {{-r, -r, 0}, {r, -r, 0}, {r, r, 0}, {-r, r, 0},
                                    {-r, -r, h}, {r, -r, h}, {r, r, h}, {-r, r, h}};
      for (const auto& v : c) out.vertices.push_back(v);
      const int faces[12][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                {1, 2, 6}, {1, 6, 5}, {2, 3, 7}, {2, 7, 6}, {3, 0, 4}, {3, 4, 7}};
      for (const auto& f : faces) out.triangles.emplace_back(f[0], f[1], f[2]);
      return out;
    }
    case Shape::kTorus: {
      const double a = 0.5 * height_mm_, major = radius_mm_ - a;
      add_grid(
          [&](int i, int j) {
            const double theta = 2.0 * kPi * i / segments;
            return ring(major + a * std::cos(theta), a + a * std::sin(theta), j);
          },
          segments, segments, true);
      return out;
    }
    default: {
      // Solids of revolution: the profile from the bottom centre to the top centre.
      const int rows = segments;
      std::vector<Eigen::Vector2d> profile;  // (rho, z)
      if (shape_ == Shape::kSphere) {
        for (int i = 0; i <= rows; ++i) {
          const double polar = kPi * i / rows;  // from the bottom pole
          profile.emplace_back(radius_mm_ * std::sin(polar), radius_mm_ * (1.0 - std::cos(polar)));
        }
      } else {
        for (int i = 0; i <= rows; ++i) {
          const double z = height_mm_ * i / rows;
          profile.emplace_back(ProfileRadiusMm(z), z);
        }
        profile.insert(profile.begin(), Eigen::Vector2d(0.0, 0.0));
        profile.emplace_back(0.0, height_mm_);
      }
      add_grid([&](int i, int j) { return ring(profile[i].x(), profile[i].y(), j); },
               static_cast<int>(profile.size()) - 1, segments, true);
      return out;
    }
  }
}

Matrix34d SimProjection::PixelFromObject(double plate_angle_deg) const {
  if (!orthographic) return rig.PixelFromObject(plate_angle_deg);
  const Eigen::Matrix<double, 3, 4> cam = rig.CamFromObject(plate_angle_deg).matrix().topRows<3>();
  Matrix34d p = Matrix34d::Zero();
  p.row(0) = px_per_mm * cam.row(0);
  p.row(1) = px_per_mm * cam.row(1);
  p(0, 3) += rig.intrinsics.cx_px;
  p(1, 3) += rig.intrinsics.cy_px;
  p(2, 3) = 1.0;
  return p;
}

View SimProjection::ViewAt(double plate_angle_deg) const {
  View view;
  view.pixel_from_object = PixelFromObject(plate_angle_deg);
  view.width_px = rig.intrinsics.width_px;
  view.height_px = rig.intrinsics.height_px;
  return view;
}

PixelRays::PixelRays(const SimProjection& projection, double plate_angle_deg)
    : orthographic_(projection.orthographic) {
  const Eigen::Isometry3d object_from_cam = projection.rig.CamFromObject(plate_angle_deg).inverse();
  forward_ = object_from_cam.linear().col(2);
  if (!orthographic_) {
    origin_ = object_from_cam.translation();
    object_from_pixel_ = object_from_cam.linear() * projection.rig.intrinsics.K().inverse();
    return;
  }
  // Pixel (u, v) -> camera-frame offset ((u - cx) / m, (v - cy) / m, 0), started far behind the
  // camera's plane so that every ray begins outside the scene.
  const double m = projection.px_per_mm;
  const Eigen::Vector3d centre = object_from_cam.translation();
  const double back_mm = 10.0 * centre.norm() + 1000.0;
  Eigen::Matrix3d cam_from_pixel;
  cam_from_pixel << 1.0 / m, 0.0, -projection.rig.intrinsics.cx_px / m, 0.0, 1.0 / m,
      -projection.rig.intrinsics.cy_px / m, 0.0, 0.0, 0.0;
  object_from_pixel_ = object_from_cam.linear() * cam_from_pixel;
  origin_ = centre - back_mm * forward_;
}

cv::Rect ProjectedBoxBounds(const Eigen::Vector3d& box_min, const Eigen::Vector3d& box_max,
                            const SimProjection& projection, double plate_angle_deg,
                            int margin_px) {
  const int width = projection.width_px();
  const int height = projection.height_px();
  const cv::Rect image(0, 0, width, height);
  const Matrix34d pixel_from_object = projection.PixelFromObject(plate_angle_deg);
  double u_min = std::numeric_limits<double>::infinity(), v_min = u_min;
  double u_max = -u_min, v_max = -u_min;
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d p((corner & 1) ? box_max.x() : box_min.x(),
                            (corner & 2) ? box_max.y() : box_min.y(),
                            (corner & 4) ? box_max.z() : box_min.z());
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

cv::Rect ProjectedBounds(const Scene& scene, const SimProjection& projection,
                         double plate_angle_deg, int margin_px) {
  const double r = scene.bounding_radius_mm();
  return ProjectedBoxBounds(Eigen::Vector3d(-r, -r, 0.0), Eigen::Vector3d(r, r, scene.height_mm()),
                            projection, plate_angle_deg, margin_px);
}

cv::Mat RenderTrueMask(const Scene& scene, const SimProjection& projection,
                       double plate_angle_deg) {
  cv::Mat mask(projection.height_px(), projection.width_px(), CV_8UC1, cv::Scalar(0));
  const cv::Rect bounds = ProjectedBounds(scene, projection, plate_angle_deg, 1);
  const PixelRays rays(projection, plate_angle_deg);
  for (int v = bounds.y; v < bounds.y + bounds.height; ++v) {
    auto* row = mask.ptr<std::uint8_t>(v);
    for (int u = bounds.x; u < bounds.x + bounds.width; ++u) {
      if (scene.Hits(rays.Origin(u, v), rays.Direction(u, v))) row[u] = 255;
    }
  }
  return mask;
}

}  // namespace revolve::capture
