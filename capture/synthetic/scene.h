// The synthetic camera's scene, as pure geometry: one solid standing on the plate, its ray
// intersection, its exact silhouette, volume and distance function.
//
// Every shape stands on the plate (z = 0) centred on the object frame's z axis (base/rig.h).
// Lengths are millimetres, points are in the object frame.
//  - sphere:   radius r, centre (0, 0, r); height 2 r.
//  - cylinder: radius r, height h, capped top and bottom.
//  - vase:     height h, profile radius VaseRadiusMm(z) (below), capped top and bottom.
//  - cone:     base radius r on the plate, apex at height h on the axis.
//  - box:      |x| <= r, |y| <= r, 0 <= z <= h (a square box; its corners turn with the plate).
//  - torus:    lying flat: tube radius a = h / 2, centre circle of radius r - a at height a, so
//              its outer radius is r and its height h. Needs r > h / 2 (an open hole: r > h).
//  - mesh:     a triangle mesh (capture/synthetic/mesh.h) scaled to height h, centred on the
//              axis and resting on the plate; see Scene::CreateMesh.
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

enum class Shape { kSphere, kCylinder, kVase, kCone, kBox, kTorus, kMesh };

// "sphere" | "cylinder" | "vase" | "cone" | "box" | "torus" | "mesh"; bad_input otherwise.
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

struct TriangleMesh;
class MeshGrid;

class Scene {
 public:
  // Errors: bad_input when a size is not positive and finite, or (torus) radius_mm <= height_mm
  // / 2. `height_mm` is ignored for the sphere (its height is 2 * radius_mm). Not for kMesh.
  static Expected<Scene> Create(Shape shape, double radius_mm, double height_mm);

  // A mesh scaled uniformly so that its height is `height_mm`, moved so that its bounding box
  // is centred on the axis and its lowest point rests on the plate. Errors: bad_input for an
  // empty or flat mesh.
  static Expected<Scene> CreateMesh(const TriangleMesh& mesh, double height_mm, std::string name);

  Shape shape() const { return shape_; }
  // Sphere, cylinder and cone radius; the vase's largest radius; the box's half side; the
  // torus's outer radius; the mesh's largest distance from the axis.
  double radius_mm() const { return radius_mm_; }
  // Height of the solid (2 r for the sphere).
  double height_mm() const { return height_mm_; }
  // Radius of the enclosing cylinder about the axis (r sqrt 2 for the box).
  double bounding_radius_mm() const;
  // The mesh of a kMesh scene, in the object frame (null otherwise).
  const std::shared_ptr<const TriangleMesh>& mesh() const { return mesh_; }

  // Radius of the horizontal cross-section at height z along +x (the box's half side, the
  // torus's outer edge); 0 outside [0, height]. For a mesh: radius_mm() inside [0, height].
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

  // Volume in mm^3: closed forms; for a mesh, the divergence theorem (exact for a closed mesh).
  double VolumeMm3() const;

  // Unsigned distance from a point to the surface (lateral surface and caps). Exact for the
  // sphere, cylinder, cone, box, torus and mesh; within ~1e-4 mm for the vase.
  double DistanceMm(const Eigen::Vector3d& point) const;

  // "sphere r=40 mm", "cylinder r=40 mm h=100 mm", "vase r=40 mm h=100 mm", "mesh spot.obj
  // h=100 mm".
  std::string Describe() const;

  // Ground truth for accuracy checks (the distance function holds a copy of the scene), with
  // the true surface as a triangle mesh (analytic shapes tessellated finely).
  SceneTruth Truth() const;

  // The true surface as triangles in the object frame: the mesh itself, or the analytic shape
  // tessellated with `segments` steps around the axis (and matching steps along profiles).
  TriangleMesh Tessellate(int segments = 96) const;

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
  std::optional<RayHit> IntersectConvexOrMarched(const Eigen::Vector3d& origin,
                                                 const Eigen::Vector3d& direction) const;
  double TorusSdf(const Eigen::Vector3d& point) const;

  Shape shape_ = Shape::kSphere;
  double radius_mm_ = 0.0;
  double height_mm_ = 0.0;
  std::string name_;  // the mesh's file name
  std::shared_ptr<const TriangleMesh> mesh_;
  std::shared_ptr<const MeshGrid> mesh_index_;  // for DistanceMm
  // Vase: the profile sampled at kProfileSamples + 1 heights, (r, z) pairs.
  std::shared_ptr<const std::vector<Eigen::Vector2d>> profile_;
};

// How the simulated camera projects. Pinhole: the rig. Orthographic (the thesis's assumption):
// the rig's pose and principal point, parallel rays along the optical axis, `px_per_mm` pixels
// per millimetre everywhere (the pinhole's magnification at the axis, fx / distance).
struct SimProjection {
  SimProjection() = default;
  SimProjection(const Rig& r) : rig(r) {}  // NOLINT: a pinhole rig is a projection
  Rig rig;
  bool orthographic = false;
  double px_per_mm = 1.0;

  // K [R | t] for a pinhole; for orthographic [m R_xy | m t_xy + c; 0 0 0 1] (affine).
  Matrix34d PixelFromObject(double plate_angle_deg) const;
  View ViewAt(double plate_angle_deg) const;
  int width_px() const { return rig.intrinsics.width_px; }
  int height_px() const { return rig.intrinsics.height_px; }
};

// Rays through pixels at one plate angle, in the object frame. Orthographic rays start on a
// plane behind the camera's, far enough back to lie outside any sensible scene.
class PixelRays {
 public:
  PixelRays(const SimProjection& projection, double plate_angle_deg);
  // The ray's origin for pixel (u, v): the camera centre for a pinhole.
  Eigen::Vector3d Origin(double u_px, double v_px) const {
    if (!orthographic_) return origin_;
    return origin_ + object_from_pixel_ * Eigen::Vector3d(u_px, v_px, 1.0);
  }
  // Unit direction of the ray through pixel (u, v) (pixel centres are integers).
  Eigen::Vector3d Direction(double u_px, double v_px) const {
    if (orthographic_) return forward_;
    return (object_from_pixel_ * Eigen::Vector3d(u_px, v_px, 1.0)).normalized();
  }
  // The pinhole's centre; for orthographic the origin of pixel (0, 0) minus its offset.
  const Eigen::Vector3d& origin() const { return origin_; }
  bool orthographic() const { return orthographic_; }

 private:
  bool orthographic_ = false;
  Eigen::Vector3d origin_;
  Eigen::Vector3d forward_;
  Eigen::Matrix3d object_from_pixel_;
};

// The pixel rectangle (clipped to the image) where `box` (object frame) can appear, with a
// margin of `margin_px`; the whole image when the box reaches behind a pinhole camera. Empty
// when nothing can be seen.
cv::Rect ProjectedBoxBounds(const Eigen::Vector3d& box_min, const Eigen::Vector3d& box_max,
                            const SimProjection& projection, double plate_angle_deg, int margin_px);

// ProjectedBoxBounds of the solid's enclosing cylinder's bounding box.
cv::Rect ProjectedBounds(const Scene& scene, const SimProjection& projection,
                         double plate_angle_deg, int margin_px);

// The TRUE silhouette at a plate angle: CV_8UC1 of the image size, 255 where the ray through
// the pixel centre meets the solid, 0 elsewhere. No noise, no anti-aliasing, no occluders.
cv::Mat RenderTrueMask(const Scene& scene, const SimProjection& projection, double plate_angle_deg);

}  // namespace revolve::capture
