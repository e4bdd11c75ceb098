// Photo-like rendering of a Scene through a SimProjection: Lambert shading under one point light
// near the camera plus ambient light, a procedural texture fixed to the object (it turns with
// the plate), a uniform backdrop of any colour, the table's plate and fixed fixtures (flat
// colours), anti-aliased edges between all of them, optional Gaussian blur and seeded Gaussian
// sensor noise. Analytic objects are ray cast; meshes are rasterized with a z-buffer.
// Pure: the same inputs give the same image, bit for bit.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/rig.h"
#include "capture/synthetic/scene.h"

namespace revolve::capture {

// A box fixed to the table (a clamp, a post, the motor housing): it does not turn.
struct Fixture {
  Eigen::Vector3d min_mm = Eigen::Vector3d::Zero();  // table frame
  Eigen::Vector3d max_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3f bgr{200.0f, 200.0f, 200.0f};  // the level the camera sees, 0..255
};

// What stands around the object. Colours are the levels the camera sees (flat, unlit).
struct Stage {
  double plate_radius_mm = 0.0;  // 0: no plate
  double plate_thickness_mm = 8.0;
  Eigen::Vector3f plate_top_bgr{20.0f, 20.0f, 20.0f};
  Eigen::Vector3f plate_rim_bgr{150.0f, 150.0f, 150.0f};  // the plate's side and underside
  std::vector<Fixture> fixtures;
};

struct RenderSettings {
  Eigen::Vector3f backdrop_bgr{20.0f, 20.0f, 20.0f};  // 0..255
  float object_albedo = 1.0f;  // scales the texture's albedo (darker objects for a light backdrop)
  bool speckle = false;        // the texture's albedo times SpeckleShade
  double noise_sigma = 3.0;    // standard deviation of the noise added to every channel
  double blur_sigma_px = 0.0;  // Gaussian blur of the optics (before the noise); 0: none
  std::uint64_t seed = 1;      // with the frame's sequence number, seeds the noise
  Stage stage;
};

// What each pixel centre sees, in RenderOutput::surface.
enum SurfaceId : std::uint8_t {
  kBackdropSurface = 0,
  kObjectSurface = 1,
  kPlateTopSurface = 2,
  kPlateRimSurface = 3,
  kFixtureSurface = 4,  // fixture i is kFixtureSurface + i
};

struct RenderOutput {
  cv::Mat image;      // CV_8UC3 BGR
  cv::Mat true_mask;  // CV_8UC1: 255 where the pixel centre sees the object (occlusion included)
  cv::Mat surface;    // CV_8UC1 SurfaceId per pixel centre
};

// Shading: colour = 255 * albedo * (kAmbient + kDiffuse * max(0, n . l)) (at most 242 for a white
// texel, so a correctly exposed frame does not clip), l toward a point
// light at (kLightRight, kLightDown, 0) * D in the camera frame, D being the camera's distance
// to the object's mid-height point on the axis (so: up and to the left of the lens). The strong
// ambient term stands for a soft-box: the limb, where Lambert falls to zero, keeps ~3/4 of the
// object's mean level, so Otsu's threshold cuts edge pixels near half coverage.
inline constexpr double kAmbient = 0.65;
inline constexpr double kDiffuse = 0.3;
inline constexpr double kLightRight = -0.2;
inline constexpr double kLightDown = -0.3;

// The texture, in object coordinates. Azimuth phi = atan2(y, x) in [-pi, pi) splits into
// kTextureSectors sectors, height into kTextureBands bands of height_mm / kTextureBands; a
// cell's colour comes from its band's pair (even bands: orange/cream, odd: light blue/light
// green) by the parity of sector + band. A magenta marker patch (kMarkerBgr) covers
// |phi| <= kMarkerHalfWidthDeg and |z - height/2| <= height * kMarkerHalfHeight: the object's
// +x side at mid-height, so a test can see which way the object turned. Every colour is bright
// enough (grey >= 0.55) to stand well above a dark backdrop even where only ambient light hits.
inline constexpr int kTextureSectors = 12;
inline constexpr int kTextureBands = 8;
inline constexpr double kMarkerHalfWidthDeg = 12.0;
inline constexpr double kMarkerHalfHeight = 1.0 / 12.0;
inline constexpr float kMarkerBgr[3] = {1.0f, 0.25f, 1.0f};

// Albedo (B, G, R in [0, 1]) of the surface at an object-frame point on it.
Eigen::Vector3f SurfaceAlbedo(const Scene& scene, const Eigen::Vector3d& point);

// Fine blotches fixed to the object, for photogrammetry's feature detectors: a factor in
// [0.6, 1] from two octaves of value noise (trilinear between hashed values on lattices of 1.5
// and 4 mm) at an object-frame point.
float SpeckleShade(const Eigen::Vector3d& point);

// True on the marker patch.
bool InMarker(const Scene& scene, const Eigen::Vector3d& point);

// The centre of the marker on the surface: (r(h/2), 0, h/2) in the object frame.
Eigen::Vector3d MarkerCenter(const Scene& scene);

// The seed of frame `sequence`'s noise (a mix of both, so neighbouring frames are unrelated).
std::uint64_t NoiseSeed(std::uint64_t seed, std::uint64_t sequence);

// Renders the frame at a plate angle. Pixels whose centre sees another surface than a
// neighbour's are supersampled 4 x 4, so every edge is sub-pixel faithful (an edge pixel's level
// is the covered fractions' blend). Then blur (blur_sigma_px), then noise from cv::RNG seeded
// with NoiseSeed(settings.seed, sequence) (none when noise_sigma is 0). `draw_object` false
// renders the empty scene (the background frame).
RenderOutput RenderScene(const Scene& scene, const SimProjection& projection,
                         double plate_angle_deg, const RenderSettings& settings,
                         std::uint64_t sequence, bool draw_object = true);

// RenderScene(...).image.
cv::Mat RenderFrame(const Scene& scene, const SimProjection& projection, double plate_angle_deg,
                    const RenderSettings& settings, std::uint64_t sequence);

}  // namespace revolve::capture
