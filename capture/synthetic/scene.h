// The synthetic camera's scene, as pure geometry: one analytic solid standing on the plate, its
// ray intersection, its exact silhouette, volume and distance function.
//
// Every shape is a solid of revolution about the object frame's z axis (base/rig.h) with its
// bottom on the plate (z = 0). Lengths are millimetres, points are in the object frame.
//  - sphere:   radius r, centre (0, 0, r); height 2 r.
//  - cylinder: radius r, height h, capped top and bottom.
//  - vase:     height h, profile radius VaseRadiusMm(z) (below), capped top and bottom.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "capture/camera.h"

namespace revolve::capture {

enum class Shape { kSphere, kCylinder, kVase };

// "sphere" | "cylinder" | "vase"; bad_input otherwise.
Expected<Shape> ParseShape(std::string_view name);
std::string_view ToString(Shape shape);

// The vase profile, with t = z / h:
//   r(z) = R * (kVaseMean + kVaseSwing * cos(2 pi (t - kVaseBellyAt)))   for 0 <= z <= h
// i.e. R (0.66 + 0.34 cos(2 pi (z/h - 0.35))): a foot of 0.46 R at z = 0, the belly (largest
// radius, exactly R) at z = 0.35 h, the neck (smallest radius, 0.32 R) at z = 0.85 h and a lip
// flaring back out to 0.46 R at the top. Volume: pi R^2 h (kVaseMean^2 + kVaseSwing^2 / 2).
inline constexpr double kVaseMean = 0.66;
inline constexpr double kVaseSwing = 0.34;
inline constexpr double kVaseBellyAt = 0.35;
double VaseRadiusMm(double z_mm, double radius_mm, double height_mm);
// dr/dz of the vase profile.
double VaseRadiusSlope(double z_mm, double radius_mm, double height_mm);

// A ray's first entry into the solid.
struct RayHit {
  double t = 0.0;                                     // o + t d, t > 0
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    // object frame
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit, outward
};

class Scene {
 public:
  // Errors: bad_input when a size is not positive and finite. `height_mm` is ignored for the
  // sphere (its height is 2 * radius_mm).
  static Expected<Scene> Create(Shape shape, double radius_mm, double height_mm);

  Shape shape() const { return shape_; }
  // Sphere and cylinder radius; the vase's largest radius.
  double radius_mm() const { return radius_mm_; }
  // Height of the solid (2 r for the sphere).
  double height_mm() const { return height_mm_; }
  // Radius of the enclosing cylinder (radius_mm() for every shape).
  double bounding_radius_mm() const { return radius_mm_; }

  // Radius of the horizontal cross-section at height z; 0 outside [0, height].
  double ProfileRadiusMm(double z_mm) const;

  // True when the point lies inside the solid or on its surface.
  bool Contains(const Eigen::Vector3d& point) const;

  // Whether the ray o + t d (t > 0, d need not be unit) meets the solid. Cheaper than Intersect.
  // Contract: the origin lies outside the solid's enclosing cylinder (a camera outside).
  bool Hits(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const;

  // The first point where the ray o + t d (t > 0, d unit) enters the solid, with its normal.
  // Same contract as Hits. Analytic for the sphere and the cylinder; for the vase, a march
  // inside the enclosing cylinder whose steps follow a rigorous second-order lower bound of
  // rho^2 - r(z)^2 along the ray: it never steps over a crossing, however grazing, and
  // converges to the entry point within ~1e-7 (r + h).
  std::optional<RayHit> Intersect(const Eigen::Vector3d& origin,
                                  const Eigen::Vector3d& direction) const;

  // Exact volume in mm^3 (closed forms).
  double VolumeMm3() const;

  // Unsigned distance from a point to the surface (lateral surface and caps). Exact for the
  // sphere and the cylinder; within ~1e-4 mm for the vase.
  double DistanceMm(const Eigen::Vector3d& point) const;

  // "sphere r=40 mm", "cylinder r=40 mm h=100 mm", "vase r=40 mm h=100 mm".
  std::string Describe() const;

  // Ground truth for accuracy checks (the distance function holds a copy of the scene).
  SceneTruth Truth() const;

 private:
  Scene() = default;
  // The ray's parameter interval inside the enclosing capped cylinder; false when it misses.
  // `entered_by_cap` tells whether the entry is through a cap (else the lateral surface).
  bool BoundingInterval(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                        double* t_in, double* t_out, bool* entered_by_cap) const;
  // For the vase: the ray parameter where it enters the solid, or nullopt.
  std::optional<double> VaseEntry(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                  bool* by_cap) const;
  double MeridianDistanceMm(double rho_mm, double z_mm) const;

  Shape shape_ = Shape::kSphere;
  double radius_mm_ = 0.0;
  double height_mm_ = 0.0;
  // Vase: the profile sampled at kProfileSamples + 1 heights, (r, z) pairs.
  std::shared_ptr<const std::vector<Eigen::Vector2d>> profile_;
};

// Rays through pixels of a rig at one plate angle, in the object frame.
class PixelRays {
 public:
  PixelRays(const Rig& rig, double plate_angle_deg);
  // The camera centre in the object frame.
  const Eigen::Vector3d& origin() const { return origin_; }
  // Unit direction of the ray through pixel (u, v) (pixel centres are integers).
  Eigen::Vector3d Direction(double u_px, double v_px) const {
    return (object_from_pixel_ * Eigen::Vector3d(u_px, v_px, 1.0)).normalized();
  }

 private:
  Eigen::Vector3d origin_;
  Eigen::Matrix3d object_from_pixel_;
};

// The pixel rectangle (clipped to the image) that can see the solid at this plate angle, with a
// margin of `margin_px`; the whole image when the enclosing cylinder is not entirely in front of
// the camera. Empty when nothing can be seen.
cv::Rect ProjectedBounds(const Scene& scene, const Rig& rig, double plate_angle_deg, int margin_px);

// The TRUE silhouette at a plate angle: CV_8UC1 of the rig's image size, 255 where the ray
// through the pixel centre meets the solid, 0 elsewhere. No noise, no anti-aliasing.
cv::Mat RenderTrueMask(const Scene& scene, const Rig& rig, double plate_angle_deg);

}  // namespace revolve::capture
