#include "reconstruct/hull/visual_hull.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "reconstruct/hull/marching_cubes.h"

namespace revolve::reconstruct {
namespace {

constexpr int kBrickShift = 2;  // bricks of 4 voxels per side
constexpr int kBrick = 1 << kBrickShift;
// Widening of a block's projected rectangle (px): far above the floating-point error of a
// projection (~1e-12 px), far below anything that changes a decision more than conservatively.
constexpr double kRectMarginPx = 1e-6;
// Rectangles up to this many pixels are counted on the mask rather than the summed-area table.
constexpr std::int64_t kDirectCountMaxArea = 16;

// Homogeneous projection; every test of the carver goes through this one expression.
struct Homogeneous {
  double x, y, w;
};
inline Homogeneous Project(const Matrix34d& p, const Eigen::Vector3d& point) {
  return {p(0, 0) * point.x() + p(0, 1) * point.y() + p(0, 2) * point.z() + p(0, 3),
          p(1, 0) * point.x() + p(1, 1) * point.y() + p(1, 2) * point.z() + p(1, 3),
          p(2, 0) * point.x() + p(2, 1) * point.y() + p(2, 2) * point.z() + p(2, 3)};
}

// Bits of a brick that belong to voxels inside the grid, for the brick at `brick`.
std::uint64_t BrickValidBits(const Eigen::Vector3i& brick, const Eigen::Vector3i& dims) {
  std::uint64_t bits = 0;
  for (int z = 0; z < kBrick; ++z) {
    for (int y = 0; y < kBrick; ++y) {
      for (int x = 0; x < kBrick; ++x) {
        const Eigen::Vector3i v = brick * kBrick + Eigen::Vector3i(x, y, z);
        if ((v.array() < dims.array()).all()) {
          bits |= std::uint64_t{1} << (x | (y << 2) | (z << 4));
        }
      }
    }
  }
  return bits;
}

}  // namespace

struct VisualHull::Sat {
  cv::Mat sum;  // CV_32S, (height + 1) x (width + 1)
  int width = 0;
  int height = 0;
  // Mask pixels in the inclusive rectangle [u0, u1] x [v0, v1] (inside the image).
  std::int64_t Count(int u0, int v0, int u1, int v1) const {
    const int* top = sum.ptr<int>(v0);
    const int* bottom = sum.ptr<int>(v1 + 1);
    return std::int64_t{bottom[u1 + 1]} - top[u1 + 1] - bottom[u0] + top[u0];
  }
};

Expected<VoxelGrid> VoxelGrid::FromBox(const Eigen::Vector3d& bbox_min_mm,
                                       const Eigen::Vector3d& bbox_max_mm, int resolution) {
  const Eigen::Vector3d extent = bbox_max_mm - bbox_min_mm;
  if (!(extent.array() > 0.0).all() || !extent.allFinite()) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("carving volume is empty: min ({}, {}, {}) max ({}, {}, {}) mm",
                                 bbox_min_mm.x(), bbox_min_mm.y(), bbox_min_mm.z(), bbox_max_mm.x(),
                                 bbox_max_mm.y(), bbox_max_mm.z()));
  }
  if (resolution < 1 || resolution > 4096) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("resolution {} is out of range [1, 4096]", resolution));
  }
  VoxelGrid grid;
  grid.origin_mm = bbox_min_mm;
  grid.voxel_mm = extent.maxCoeff() / resolution;
  for (int a = 0; a < 3; ++a) {
    grid.dims[a] = std::max(1, static_cast<int>(std::ceil(extent[a] / grid.voxel_mm - 1e-9)));
  }
  return grid;
}

VisualHull::VisualHull(const VoxelGrid& grid) : grid_(grid) {
  brick_dims_ = (grid_.dims + Eigen::Vector3i::Constant(kBrick - 1)) / kBrick;
  bricks_.assign(static_cast<std::size_t>(brick_dims_.prod()), ~std::uint64_t{0});
  // Clear the bits past the grid in the last brick of each axis.
  for (int z = 0; z < brick_dims_.z(); ++z) {
    for (int y = 0; y < brick_dims_.y(); ++y) {
      for (int x = 0; x < brick_dims_.x(); ++x) {
        const Eigen::Vector3i b(x, y, z);
        if (((b.array() + 1) * kBrick > grid_.dims.array()).any()) {
          bricks_[BrickIndex(b)] = BrickValidBits(b, grid_.dims);
        }
      }
    }
  }
  level_dims_.push_back(brick_dims_);
  alive_.emplace_back();  // level 0 uses the brick words themselves
  while ((level_dims_.back().array() > 1).any()) {
    const Eigen::Vector3i d = (level_dims_.back() + Eigen::Vector3i::Ones()) / 2;
    level_dims_.push_back(d);
    alive_.emplace_back(static_cast<std::size_t>(d.prod()), std::uint8_t{1});
  }
}

Expected<VisualHull::ViewData> VisualHull::Prepare(const cv::Mat& mask, const View& view) const {
  if (view.width_px <= 0 || view.height_px <= 0) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("view has no image size ({}x{})", view.width_px, view.height_px));
  }
  if (mask.type() != CV_8UC1 || mask.cols != view.width_px || mask.rows != view.height_px) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("silhouette mask must be CV_8UC1 {}x{} (the view's size), got "
                                 "type {} {}x{}",
                                 view.width_px, view.height_px, mask.type(), mask.cols, mask.rows));
  }
  if (!view.pixel_from_object.allFinite()) {
    return MakeError(ErrorCode::kBadInput, "view projection matrix is not finite");
  }
  ViewData data;
  data.pixel_from_object = view.pixel_from_object;
  cv::min(mask, 1, data.mask01);
  return data;
}

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
  if (!(fu >= 0.0 && fv >= 0.0 && fu < view.mask01.cols && fv < view.mask01.rows)) {
    return true;  // outside the image: not seen
  }
  return view.mask01.data[static_cast<std::size_t>(view.mask01.step[0]) * static_cast<int>(fv) +
                          static_cast<int>(fu)] != 0;
}

[[gnu::always_inline]] inline bool VisualHull::PointSurvives(
    const ViewData& view, const Eigen::Vector3d& point_mm) const {
  const Homogeneous h = Project(view.pixel_from_object, point_mm);
  return SurvivesProjected(view, h.x, h.y, h.w);
}

[[gnu::always_inline]] inline bool VisualHull::VoxelSurvives(const ViewData& view, int i, int j,
                                                             int k) const {
  return PointSurvives(view, grid_.Centre(i, j, k));
}

VisualHull::Sat VisualHull::MakeSat(const ViewData& view) {
  Sat sat;
  sat.width = view.mask01.cols;
  sat.height = view.mask01.rows;
  cv::integral(view.mask01, sat.sum, CV_32S);
  return sat;
}

VisualHull::BlockClass VisualHull::Classify(const ViewData& view, const Sat& sat,
                                            const Eigen::Vector3i& lo,
                                            const Eigen::Vector3i& hi) const {
  Eigen::Vector3d corners[8];
  for (int c = 0; c < 8; ++c) {
    corners[c] =
        grid_.Centre(c & 1 ? hi.x() : lo.x(), c & 2 ? hi.y() : lo.y(), c & 4 ? hi.z() : lo.z());
  }
  return ClassifyHull(view, sat, corners, 8);
}

VisualHull::BlockClass VisualHull::ClassifyHull(const ViewData& view, const Sat& sat,
                                                const Eigen::Vector3d* points, int count) {
  double u_min = std::numeric_limits<double>::infinity();
  double v_min = u_min;
  double u_max = -u_min;
  double v_max = -u_min;
  int in_front = 0;
  for (int c = 0; c < count; ++c) {
    const Homogeneous h = Project(view.pixel_from_object, points[c]);
    if (!(h.w > 0.0)) {
      continue;
    }
    ++in_front;
    const double u = h.x / h.w;
    const double v = h.y / h.w;
    u_min = std::min(u_min, u);
    u_max = std::max(u_max, u);
    v_min = std::min(v_min, v);
    v_max = std::max(v_max, v);
  }
  if (in_front == 0) {
    return BlockClass::kUnaffected;  // all behind the camera: not seen
  }
  if (in_front < count) {
    return BlockClass::kMixed;
  }
  // Nearest pixels, clamped to [-1, size] (enough to tell inside from outside).
  auto pixel = [](double x, int size) {
    return static_cast<int>(std::floor(std::clamp(x + 0.5, -1.0, size + 1.0)));
  };
  const int u0 = pixel(u_min - kRectMarginPx, sat.width);
  const int u1 = pixel(u_max + kRectMarginPx, sat.width);
  const int v0 = pixel(v_min - kRectMarginPx, sat.height);
  const int v1 = pixel(v_max + kRectMarginPx, sat.height);
  const int cu0 = std::max(u0, 0);
  const int cv0 = std::max(v0, 0);
  const int cu1 = std::min(u1, sat.width - 1);
  const int cv1 = std::min(v1, sat.height - 1);
  if (cu0 > cu1 || cv0 > cv1) {
    return BlockClass::kUnaffected;  // projects outside the image
  }
  const std::int64_t area = std::int64_t{cu1 - cu0 + 1} * (cv1 - cv0 + 1);
  std::int64_t mask_count = 0;
  if (area <= kDirectCountMaxArea) {
    // Small rectangles (surface edges): the 0/1 mask itself is closer in cache than the table.
    for (int v = cv0; v <= cv1; ++v) {
      const std::uint8_t* row = view.mask01.ptr<std::uint8_t>(v);
      for (int u = cu0; u <= cu1; ++u) {
        mask_count += row[u];
      }
    }
  } else {
    mask_count = sat.Count(cu0, cv0, cu1, cv1);
  }
  // Every point that is seen lands on the silhouette; the others are not seen.
  if (mask_count == area) {
    return BlockClass::kUnaffected;
  }
  const bool rect_inside = u0 >= 0 && v0 >= 0 && u1 < sat.width && v1 < sat.height;
  if (mask_count == 0 && rect_inside) {
    return BlockClass::kCarve;
  }
  return BlockClass::kMixed;
}

bool VisualHull::CarveBrick(const ViewData& view, const Eigen::Vector3i& brick) {
  std::uint64_t& word = bricks_[BrickIndex(brick)];
  const Matrix34d& p = view.pixel_from_object;
  // Project's products for the brick's 4 centre coordinates along each axis, summed below in
  // Project's order: bit-identical to VoxelSurvives (this file is built with
  // -ffp-contract=off, so no fused multiply-add changes the rounding of either path).
  double px[kBrick][3];
  double py[kBrick][3];
  double pz[kBrick][3];
  const Eigen::Vector3i base = brick * kBrick;
  for (int d = 0; d < kBrick; ++d) {
    const Eigen::Vector3d c = grid_.Centre(base.x() + d, base.y() + d, base.z() + d);
    for (int r = 0; r < 3; ++r) {
      px[d][r] = p(r, 0) * c.x();
      py[d][r] = p(r, 1) * c.y();
      pz[d][r] = p(r, 2) * c.z();
    }
  }
  std::uint64_t carved = 0;
  for (std::uint64_t remaining = word; remaining != 0; remaining &= remaining - 1) {
    const int bit = std::countr_zero(remaining);
    const int x = bit & 3;
    const int y = (bit >> 2) & 3;
    const int z = bit >> 4;
    const double hx = px[x][0] + py[y][0] + pz[z][0] + p(0, 3);
    const double hy = px[x][1] + py[y][1] + pz[z][1] + p(1, 3);
    const double hw = px[x][2] + py[y][2] + pz[z][2] + p(2, 3);
    carved |= std::uint64_t{!SurvivesProjected(view, hx, hy, hw)} << bit;
  }
  word &= ~carved;
  return word != 0;
}

void VisualHull::ClearBlock(int level, const Eigen::Vector3i& node) {
  if (level == 0) {
    bricks_[BrickIndex(node)] = 0;
    return;
  }
  std::uint8_t& alive = alive_[level][NodeIndex(level, node)];
  if (!alive) {
    return;
  }
  alive = 0;
  const Eigen::Vector3i& child_dims = level_dims_[level - 1];
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3i child = 2 * node + Eigen::Vector3i(c & 1, (c >> 1) & 1, (c >> 2) & 1);
    if ((child.array() < child_dims.array()).all()) {
      ClearBlock(level - 1, child);
    }
  }
}

bool VisualHull::Visit(const ViewData& view, const Sat& sat, int level,
                       const Eigen::Vector3i& node) {
  if (level == 0) {
    if (bricks_[BrickIndex(node)] == 0) {
      return false;
    }
  } else if (!alive_[level][NodeIndex(level, node)]) {
    return false;
  }
  const int size = kBrick << level;
  const Eigen::Vector3i lo = node * size;
  const Eigen::Vector3i hi =
      (lo + Eigen::Vector3i::Constant(size - 1)).cwiseMin(grid_.dims - Eigen::Vector3i::Ones());
  switch (Classify(view, sat, lo, hi)) {
    case BlockClass::kUnaffected:
      return true;
    case BlockClass::kCarve:
      ClearBlock(level, node);
      return false;
    case BlockClass::kMixed:
      break;
  }
  if (level == 0) {
    return CarveBrick(view, node);
  }
  bool any = false;
  const Eigen::Vector3i& child_dims = level_dims_[level - 1];
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3i child = 2 * node + Eigen::Vector3i(c & 1, (c >> 1) & 1, (c >> 2) & 1);
    if ((child.array() < child_dims.array()).all()) {
      any |= Visit(view, sat, level - 1, child);
    }
  }
  alive_[level][NodeIndex(level, node)] = any ? 1 : 0;
  return any;
}

void VisualHull::RebuildFlags() {
  for (std::size_t level = 1; level < level_dims_.size(); ++level) {
    const Eigen::Vector3i& d = level_dims_[level];
    const Eigen::Vector3i& child_dims = level_dims_[level - 1];
    for (int z = 0; z < d.z(); ++z) {
      for (int y = 0; y < d.y(); ++y) {
        for (int x = 0; x < d.x(); ++x) {
          const Eigen::Vector3i node(x, y, z);
          bool any = false;
          for (int c = 0; c < 8 && !any; ++c) {
            const Eigen::Vector3i child =
                2 * node + Eigen::Vector3i(c & 1, (c >> 1) & 1, (c >> 2) & 1);
            if (!(child.array() < child_dims.array()).all()) {
              continue;
            }
            any = level == 1 ? bricks_[BrickIndex(child)] != 0
                             : alive_[level - 1][NodeIndex(level - 1, child)] != 0;
          }
          alive_[level][NodeIndex(level, node)] = any ? 1 : 0;
        }
      }
    }
  }
}

Expected<void> VisualHull::Integrate(const cv::Mat& mask, const View& view) {
  Expected<ViewData> data = Prepare(mask, view);
  if (!data) {
    return std::unexpected(data.error());
  }
  const Sat sat = MakeSat(*data);
  Visit(*data, sat, static_cast<int>(level_dims_.size()) - 1, Eigen::Vector3i::Zero());
  views_.push_back(std::move(*data));
  return {};
}

Expected<void> VisualHull::IntegrateNaive(const cv::Mat& mask, const View& view) {
  Expected<ViewData> data = Prepare(mask, view);
  if (!data) {
    return std::unexpected(data.error());
  }
  for (int k = 0; k < grid_.dims.z(); ++k) {
    for (int j = 0; j < grid_.dims.y(); ++j) {
      for (int i = 0; i < grid_.dims.x(); ++i) {
        if (!Occupied(i, j, k)) {
          continue;
        }
        if (!VoxelSurvives(*data, i, j, k)) {
          const Eigen::Vector3i v(i, j, k);
          const int bit = (i & 3) | ((j & 3) << 2) | ((k & 3) << 4);
          bricks_[BrickIndex(v / kBrick)] &= ~(std::uint64_t{1} << bit);
        }
      }
    }
  }
  RebuildFlags();
  views_.push_back(std::move(*data));
  return {};
}

bool VisualHull::Occupied(int i, int j, int k) const {
  if (i < 0 || j < 0 || k < 0 || i >= grid_.dims.x() || j >= grid_.dims.y() ||
      k >= grid_.dims.z()) {
    return false;
  }
  const int bit = (i & 3) | ((j & 3) << 2) | ((k & 3) << 4);
  return (bricks_[BrickIndex(Eigen::Vector3i(i >> 2, j >> 2, k >> 2))] >> bit) & 1u;
}

std::int64_t VisualHull::OccupiedCount() const {
  std::int64_t count = 0;
  for (std::uint64_t w : bricks_) {
    count += std::popcount(w);
  }
  return count;
}

bool VisualHull::SurvivesAllViews(const Eigen::Vector3d& point_mm) const {
  for (const ViewData& view : views_) {
    if (!PointSurvives(view, point_mm)) {
      return false;
    }
  }
  return true;
}

bool VisualHull::Contains(const Eigen::Vector3d& point_mm) const {
  if (!((point_mm.array() >= grid_.origin_mm.array()).all() &&
        (point_mm.array() <= grid_.MaxCorner().array()).all())) {
    return false;
  }
  return SurvivesAllViews(point_mm);
}

Mesh VisualHull::ExtractSurface(const HullSurfaceOptions& options) const {
  BitVolume field(grid_.dims);
  for (int z = 0; z < brick_dims_.z(); ++z) {
    for (int y = 0; y < brick_dims_.y(); ++y) {
      for (int x = 0; x < brick_dims_.x(); ++x) {
        const std::uint64_t word = bricks_[BrickIndex(Eigen::Vector3i(x, y, z))];
        if (word == 0) {
          continue;
        }
        for (int dz = 0; dz < kBrick; ++dz) {
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
  }
  EdgeCrossings crossings;
  if (options.bisection_steps > 0) {
    crossings = [this, &options](const std::vector<GridEdge>& edges) {
      return PlaceOnEdges(edges, options.bisection_steps);
    };
  }
  MarchingCubesOptions mc;
  mc.keep_largest_component = options.keep_largest_component;
  return MarchingCubes(field, grid_.Centre(0, 0, 0), grid_.voxel_mm, crossings, mc);
}

std::vector<double> VisualHull::PlaceOnEdges(const std::vector<GridEdge>& edges, int steps) const {
  const std::size_t n = edges.size();
  const int views = view_count();
  // The part of each edge that can hold the crossing: all of it, or up to the grid's face for
  // an edge leaving the grid.
  auto segment = [&](const GridEdge& e, Eigen::Vector3d* a, Eigen::Vector3d* d, double* t_max) {
    *a = grid_.Centre(e.inside.x(), e.inside.y(), e.inside.z());
    *d = grid_.Centre(e.outside.x(), e.outside.y(), e.outside.z()) - *a;
    const bool leaves =
        ((e.outside.array() < 0) || (e.outside.array() >= grid_.dims.array())).any();
    *t_max = leaves ? 0.5 : 1.0;
  };

  // relevant[e * words + v / 64] bit v: view v may reject some point of edge e's segment. The
  // others accept all of it, so testing only these equals testing every view. Found per view
  // in two steps: the bricks holding the edges' inside samples, grown by one voxel (they
  // contain the segments), then the segments of the bricks the view may act on.
  std::vector<std::int64_t> brick_of_edge(n);
  std::vector<std::int64_t> bricks;
  for (std::size_t e = 0; e < n; ++e) {
    brick_of_edge[e] = BrickIndex(edges[e].inside / kBrick);
  }
  bricks = brick_of_edge;
  std::sort(bricks.begin(), bricks.end());
  bricks.erase(std::unique(bricks.begin(), bricks.end()), bricks.end());
  for (std::int64_t& b : brick_of_edge) {
    b = std::lower_bound(bricks.begin(), bricks.end(), b) - bricks.begin();
  }
  std::vector<Eigen::Vector3d> brick_lo(bricks.size());
  std::vector<Eigen::Vector3d> brick_hi(bricks.size());
  for (std::size_t b = 0; b < bricks.size(); ++b) {
    const std::int64_t plane = std::int64_t{brick_dims_.x()} * brick_dims_.y();
    const Eigen::Vector3i brick(static_cast<int>(bricks[b] % brick_dims_.x()),
                                static_cast<int>((bricks[b] / brick_dims_.x()) % brick_dims_.y()),
                                static_cast<int>(bricks[b] / plane));
    const Eigen::Vector3i lo = brick * kBrick - Eigen::Vector3i::Ones();
    const Eigen::Vector3i hi = brick * kBrick + Eigen::Vector3i::Constant(kBrick);
    brick_lo[b] = grid_.Centre(lo.x(), lo.y(), lo.z());
    brick_hi[b] = grid_.Centre(hi.x(), hi.y(), hi.z());
  }
  const int words = (views + 63) / 64;
  std::vector<std::uint64_t> relevant(n * words, 0);
  std::vector<std::uint8_t> brick_relevant(bricks.size());
  for (int v = 0; v < views; ++v) {
    const ViewData& view = views_[v];
    const Sat sat = MakeSat(view);
    for (std::size_t b = 0; b < bricks.size(); ++b) {
      Eigen::Vector3d corners[8];
      for (int c = 0; c < 8; ++c) {
        corners[c] = Eigen::Vector3d(c & 1 ? brick_hi[b].x() : brick_lo[b].x(),
                                     c & 2 ? brick_hi[b].y() : brick_lo[b].y(),
                                     c & 4 ? brick_hi[b].z() : brick_lo[b].z());
      }
      brick_relevant[b] = ClassifyHull(view, sat, corners, 8) != BlockClass::kUnaffected;
    }
    for (std::size_t e = 0; e < n; ++e) {
      if (!brick_relevant[brick_of_edge[e]]) {
        continue;
      }
      Eigen::Vector3d ends[2];
      Eigen::Vector3d d;
      double t_max = 1.0;
      segment(edges[e], &ends[0], &d, &t_max);
      ends[1] = ends[0] + t_max * d;
      if (ClassifyHull(view, sat, ends, 2) != BlockClass::kUnaffected) {
        relevant[e * words + v / 64] |= std::uint64_t{1} << (v % 64);
      }
    }
  }

  std::vector<double> t(n, 0.5);
  std::vector<const ViewData*> tests;
  for (std::size_t e = 0; e < n; ++e) {
    tests.clear();
    for (int w = 0; w < words; ++w) {
      for (std::uint64_t bits = relevant[e * words + w]; bits != 0; bits &= bits - 1) {
        tests.push_back(&views_[w * 64 + std::countr_zero(bits)]);
      }
    }
    // Move-to-front: the view that rejected the last point usually rejects the next one.
    auto survives = [&](const Eigen::Vector3d& p) {
      for (std::size_t i = 0; i < tests.size(); ++i) {
        if (!PointSurvives(*tests[i], p)) {
          std::swap(tests[0], tests[i]);
          return false;
        }
      }
      return true;
    };
    Eigen::Vector3d a, d;
    double t_max = 1.0;
    segment(edges[e], &a, &d, &t_max);
    // An edge leaving the grid: the surface is the grid's face unless a silhouette cuts sooner.
    if (t_max < 1.0 && survives(a + t_max * d)) {
      t[e] = t_max;
      continue;
    }
    double lo = 0.0;
    double hi = t_max;
    for (int s = 0; s < steps; ++s) {
      const double mid = 0.5 * (lo + hi);
      if (survives(a + mid * d)) {
        lo = mid;
      } else {
        hi = mid;
      }
    }
    t[e] = 0.5 * (lo + hi);
  }
  return t;
}

}  // namespace revolve::reconstruct
