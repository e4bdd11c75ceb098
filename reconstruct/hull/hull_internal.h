// Internal to reconstruct/hull: what the carving (visual_hull.cc), the surface (surface.cc) and
// its placement on the grid's edges (surface_placement.cc) share. All three are built with
// -ffp-contract=off: the carver and its per-voxel reference round each projection identically.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

// The x86 SIMD paths; REVOLVE_PORTABLE (the CMake option) leaves them out for the portable
// code, which gives the same values (./run test checks both).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
#include <immintrin.h>
#define REVOLVE_X86_AVX2 1
#endif

#include "reconstruct/hull/visual_hull.h"

namespace revolve::reconstruct::hull_internal {

constexpr int kBrickShift = 2;  // bricks of 4 voxels per side
constexpr int kBrick = 1 << kBrickShift;
// Widening of a block's projected rectangle (px): far above the floating-point error of a
// projection (~1e-12 px), far below anything that changes a decision more than conservatively.
constexpr double kRectMarginPx = 1e-6;
// How much wider than the silhouette's bounding rectangle a view's mask is held (px, each side):
// the rectangle of a brick on the silhouette's edge mostly lies within it, so the brick is
// tested on vectors (CarveBrick<true>) without reading past the held pixels.
constexpr int kWindowMarginPx = 16;

// Homogeneous projection; every test of the carver goes through this one expression.
struct Homogeneous {
  double x, y, w;
};
inline Homogeneous Project(const Matrix34d& p, const Eigen::Vector3d& point) {
  return {p(0, 0) * point.x() + p(0, 1) * point.y() + p(0, 2) * point.z() + p(0, 3),
          p(1, 0) * point.x() + p(1, 1) * point.y() + p(1, 2) * point.z() + p(1, 3),
          p(2, 0) * point.x() + p(2, 1) * point.y() + p(2, 2) * point.z() + p(2, 3)};
}

// mask01 over roi, one bit per pixel (bit x of a row's words is pixel roi.x + x), rows of
// *words words (one more than needed: a read of a row may take the next word).
void PackMask(const cv::Mat& mask01, const cv::Rect& roi, std::vector<std::uint64_t>* bits,
              int* words);

}  // namespace revolve::reconstruct::hull_internal

namespace revolve::reconstruct {

// The point test on a projected point h = P * [X; 1]; its callers compute h with Project's
// expression (in the same order), so every path gives the same answer for the same point.
[[gnu::always_inline]] inline bool VisualHull::SurvivesProjected(const ViewData& view, double x,
                                                                 double y, double w) {
  if (!(w > 0.0)) {
    return true;  // behind the camera (or NaN): not seen
  }
  const double inv_w = 1.0 / w;
  const double fu = x * inv_w + 0.5;
  const double fv = y * inv_w + 0.5;
  if (!(fu >= 0.0 && fv >= 0.0 && fu < view.width && fv < view.height)) {
    return true;  // outside the image: not seen
  }
  // In the image: off the silhouette outside the held window.
  const auto column = static_cast<unsigned>(static_cast<int>(fu) - view.window.x);
  const auto row = static_cast<unsigned>(static_cast<int>(fv) - view.window.y);
  if (column >= static_cast<unsigned>(view.window.width) ||
      row >= static_cast<unsigned>(view.window.height)) {
    return false;
  }
  return view.mask01.data[static_cast<std::size_t>(view.mask01.step[0]) * row + column] != 0;
}

}  // namespace revolve::reconstruct
