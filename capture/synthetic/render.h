// Photo-like rendering of a Scene through a Rig: Lambert shading under one point light near the
// camera plus ambient light, a procedural texture fixed to the object (it turns with the plate),
// a uniform dark backdrop, an anti-aliased silhouette and seeded Gaussian sensor noise.
// Pure: the same inputs give the same image, bit for bit.
#pragma once

#include <cstdint>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/rig.h"
#include "capture/synthetic/scene.h"

namespace revolve::capture {

struct RenderSettings {
  int backdrop_grey = 20;    // 0..255, the backdrop's level in every channel
  double noise_sigma = 3.0;  // standard deviation of the noise added to every channel
  std::uint64_t seed = 1;    // with the frame's sequence number, seeds the noise
};

// Shading: colour = 255 * albedo * (kAmbient + kDiffuse * max(0, n . l)), l toward a point
// light at (kLightRight, kLightDown, 0) * D in the camera frame, D being the camera's distance
// to the object's mid-height point on the axis (so: up and to the left of the lens). The strong
// ambient term stands for a soft-box: the limb, where Lambert falls to zero, keeps ~3/4 of the
// object's mean level, so Otsu's threshold cuts edge pixels near half coverage.
inline constexpr double kAmbient = 0.7;
inline constexpr double kDiffuse = 0.35;
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

// True on the marker patch.
bool InMarker(const Scene& scene, const Eigen::Vector3d& point);

// The centre of the marker on the surface: (r(h/2), 0, h/2) in the object frame.
Eigen::Vector3d MarkerCenter(const Scene& scene);

// The seed of frame `sequence`'s noise (a mix of both, so neighbouring frames are unrelated).
std::uint64_t NoiseSeed(std::uint64_t seed, std::uint64_t sequence);

// Renders the BGR frame (CV_8UC3, the rig's image size) at a plate angle. Pixels whose centre
// ray result differs from a neighbour's are supersampled 4 x 4, so the silhouette's edge is
// sub-pixel faithful (an edge pixel's level is the covered fraction's blend of object and
// backdrop). Noise from cv::RNG seeded with NoiseSeed(settings.seed, sequence); none when
// noise_sigma is 0.
cv::Mat RenderFrame(const Scene& scene, const Rig& rig, double plate_angle_deg,
                    const RenderSettings& settings, std::uint64_t sequence);

}  // namespace revolve::capture
