// VisualHull::ExtractSurface: marching cubes over the carved voxels, each vertex placed where its
// edge leaves the silhouettes (FirstExit, WalkCells).
#include "reconstruct/hull/visual_hull.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <numeric>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "reconstruct/hull/hull_internal.h"
#include "reconstruct/hull/marching_cubes.h"
#include "reconstruct/parallel.h"

namespace revolve::reconstruct {

using namespace hull_internal;  // NOLINT(google-build-using-namespace): this library's own parts

Mesh VisualHull::ExtractSurface(const HullSurfaceOptions& options) const {
  BitVolume field(grid_.dims);
  // With a clip plane, the first layer of samples kept (centres at or above the plane).
  int k_min = 0;
  if (options.clip_below_z_mm) {
    const double k =
        std::ceil((*options.clip_below_z_mm - grid_.origin_mm.z()) / grid_.voxel_mm - 0.5);
    k_min = static_cast<int>(std::clamp(k, 0.0, static_cast<double>(grid_.dims.z())));
  }
  // Each layer of bricks writes its own rows of the field: on all cores.
  ParallelFor(0, static_cast<std::size_t>(brick_dims_.z()), [&](std::size_t layer) {
    const int z = static_cast<int>(layer);
    for (int y = 0; y < brick_dims_.y(); ++y) {
      for (int x = 0; x < brick_dims_.x(); ++x) {
        const std::uint64_t word = bricks_[BrickIndex(Eigen::Vector3i(x, y, z))];
        if (word == 0) {
          continue;
        }
        for (int dz = 0; dz < kBrick; ++dz) {
          if (z * kBrick + dz < k_min) {
            continue;
          }
          for (int dy = 0; dy < kBrick; ++dy) {
            const std::uint64_t nibble = (word >> ((dy << 2) | (dz << 4))) & 0xF;
            if (nibble == 0) {
              continue;
            }
            // In-grid by construction: bits past the dims are never set.
            const int i = x * kBrick;
            field.Row(y * kBrick + dy, z * kBrick + dz)[i >> 6] |= nibble << (i & 63);
          }
        }
      }
    }
  });
  EdgeCrossings crossings;
  if (options.sub_voxel) {
    crossings = [this, &options](const std::vector<GridEdge>& edges) {
      return PlaceOnEdges(edges, options.clip_below_z_mm, options.cull_views);
    };
  }
  MarchingCubesOptions mc;
  mc.keep_largest_component = options.keep_largest_component;
  return MarchingCubes(field, grid_.Centre(0, 0, 0), grid_.voxel_mm, crossings, mc);
}

double VisualHull::FirstExit(const ViewData& view, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& d, double t_max) {
  const Matrix34d& p = view.pixel_from_object;
  const Homogeneous ha = Project(p, a);
  const Eigen::Vector3d hd(p(0, 0) * d.x() + p(0, 1) * d.y() + p(0, 2) * d.z(),
                           p(1, 0) * d.x() + p(1, 1) * d.y() + p(1, 2) * d.z(),
                           p(2, 0) * d.x() + p(2, 1) * d.y() + p(2, 2) * d.z());
  const double wb = ha.w + t_max * hd.z();
  if (!(ha.w > 0.0) || !(wb > 0.0)) {
    // The segment reaches behind the camera (a camera inside the volume): fine sampling, then
    // bisection between the last point that survives and the first that does not.
    constexpr int kSamples = 256;
    double last_good = 0.0;
    for (int s = 1; s <= kSamples; ++s) {
      const double t = t_max * s / kSamples;
      const Eigen::Vector3d q = a + t * d;
      const Homogeneous h = Project(p, q);
      if (SurvivesProjected(view, h.x, h.y, h.w)) {
        last_good = t;
        continue;
      }
      double lo = last_good;
      double hi = t;
      for (int step = 0; step < 40; ++step) {
        const double mid = 0.5 * (lo + hi);
        const Homogeneous hm = Project(p, a + mid * d);
        (SurvivesProjected(view, hm.x, hm.y, hm.w) ? lo : hi) = mid;
      }
      return hi;
    }
    return t_max + 1.0;
  }
  // In front all along: u(t) and v(t) are monotonic. Walk the nearest-pixel cells the
  // projection crosses, in order; the borders are the half-integer lines.
  const double ua = ha.x / ha.w;
  const double va = ha.y / ha.w;
  const double ub = (ha.x + t_max * hd.x()) / wb;
  const double vb = (ha.y + t_max * hd.y()) / wb;
  int iu = static_cast<int>(std::floor(ua + 0.5));
  int iv = static_cast<int>(std::floor(va + 0.5));
  const int end_u = static_cast<int>(std::floor(ub + 0.5));
  const int end_v = static_cast<int>(std::floor(vb + 0.5));
  // The walk stays in the rectangle of the end cells: when all of it is on the silhouette (or
  // off the image), nothing on the segment is carved (the common case).
  {
    const int u0 = std::max(std::min(iu, end_u), 0);
    const int u1 = std::min(std::max(iu, end_u), view.width - 1);
    const int v0 = std::max(std::min(iv, end_v), 0);
    const int v1 = std::min(std::max(iv, end_v), view.height - 1);
    // A pixel of the image outside the held window is off the silhouette.
    const cv::Rect& held = view.window;
    bool all_on =
        u0 > u1 || v0 > v1 ||
        (u0 >= held.x && v0 >= held.y && u1 < held.x + held.width && v1 < held.y + held.height);
    for (int y = v0; y <= v1 && all_on; ++y) {
      const std::uint8_t* row = view.mask01.ptr<std::uint8_t>(y - held.y);
      for (int x = u0; x <= u1; ++x) {
        all_on = all_on && row[x - held.x] != 0;
      }
    }
    if (all_on) {
      return t_max + 1.0;
    }
  }
  return WalkCells(view, ha.x, ha.y, ha.w, hd.data(), t_max, iu, iv, end_u, end_v);
}

double VisualHull::WalkCells(const ViewData& view, double hx, double hy, double hw,
                             const double* hd, double t_max, int iu, int iv, int end_u, int end_v) {
  const int cols = view.width;
  const int rows = view.height;
  const cv::Rect& roi = view.roi;
  // Whether in-image pixel (u, v) is off the silhouette, from the packed bits (which the
  // callers' tests have just read, so they are in cache): pixels outside roi are off.
  auto off = [&](int u, int v) {
    const auto x = static_cast<unsigned>(u - roi.x);
    const auto y = static_cast<unsigned>(v - roi.y);
    if (x >= static_cast<unsigned>(roi.width) || y >= static_cast<unsigned>(roi.height)) {
      return true;
    }
    return ((view.packed[static_cast<std::size_t>(y) * view.packed_words + (x >> 6)] >> (x & 63)) &
            1) == 0;
  };
  const int su = end_u > iu ? 1 : (end_u < iu ? -1 : 0);
  const int sv = end_v > iv ? 1 : (end_v < iv ? -1 : 0);
  // Parameter where the projection reaches the line u = c (or v = c): x(t) - c w(t) = 0.
  auto cross = [&](double c, double x0, double dx) {
    const double denominator = dx - c * hd[2];
    return denominator != 0.0 ? (c * hw - x0) / denominator : t_max + 1.0;
  };
  double t = 0.0;
  const int steps = std::abs(end_u - iu) + std::abs(end_v - iv);
  for (int step = 0; step <= steps; ++step) {
    if (iu >= 0 && iv >= 0 && iu < cols && iv < rows && off(iu, iv)) {
      return std::clamp(t, 0.0, t_max);
    }
    if (step == steps) {
      break;
    }
    const double tu = su != 0 && iu != end_u ? cross(iu + 0.5 * su, hx, hd[0]) : t_max + 1.0;
    const double tv = sv != 0 && iv != end_v ? cross(iv + 0.5 * sv, hy, hd[1]) : t_max + 1.0;
    if (tu <= tv) {
      iu += su;
      t = std::max(t, tu);
    } else {
      iv += sv;
      t = std::max(t, tv);
    }
  }
  return t_max + 1.0;
}

}  // namespace revolve::reconstruct
