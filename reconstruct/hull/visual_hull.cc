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

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define REVOLVE_X86_AVX2 1
#endif

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
// Carved blocks up to this level (8 bricks a side) are cleared row by row.
constexpr int kClearByRowsLevel = 3;

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
  // CV_32S, (roi.height + 1) x (roi.width + 1): the table of the mask over `roi`, the bounding
  // rectangle of its non-zero pixels (a fraction of the image: cheaper to build).
  cv::Mat sum;
  cv::Rect roi;
  int width = 0;  // the image's
  int height = 0;
  // Mask pixels in the inclusive rectangle [u0, u1] x [v0, v1] (inside the image).
  std::int64_t Count(int u0, int v0, int u1, int v1) const {
    u0 = std::max(u0, roi.x) - roi.x;
    v0 = std::max(v0, roi.y) - roi.y;
    u1 = std::min(u1, roi.x + roi.width - 1) - roi.x;
    v1 = std::min(v1, roi.y + roi.height - 1) - roi.y;
    if (u0 > u1 || v0 > v1) {
      return 0;
    }
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

namespace {

// mask01 over roi, one bit per pixel (bit x of a row's words is pixel roi.x + x), rows of
// *words words (one more than needed: a read of a row may take the next word).
void PackMask(const cv::Mat& mask01, const cv::Rect& roi, std::vector<std::uint64_t>* bits,
              int* words) {
  *words = (roi.width + 63) / 64 + 1;
  bits->assign(static_cast<std::size_t>(*words) * std::max(roi.height, 0), 0);
  for (int y = 0; y < roi.height; ++y) {
    const std::uint8_t* row = mask01.ptr<std::uint8_t>(roi.y + y) + roi.x;
    std::uint64_t* out = &(*bits)[static_cast<std::size_t>(y) * *words];
    int x = 0;
    // 8 pixels (0/1 bytes) to 8 bits: each byte gathers its 7 successors' bits above its own.
    for (; x + 8 <= roi.width; x += 8) {
      std::uint64_t bytes;
      std::memcpy(&bytes, row + x, 8);
      bytes |= bytes >> 7;
      bytes |= bytes >> 14;
      bytes |= bytes >> 28;
      out[x >> 6] |= (bytes & 0xFF) << (x & 63);
    }
    for (; x < roi.width; ++x) {
      out[x >> 6] |= std::uint64_t{row[x] != 0} << (x & 63);
    }
  }
}

}  // namespace

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
  data.roi = cv::boundingRect(data.mask01);
  PackMask(data.mask01, data.roi, &data.packed, &data.packed_words);
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
  sat.roi = view.roi;
  if (!sat.roi.empty()) {
    cv::integral(view.mask01(sat.roi), sat.sum, CV_32S);
  }
  return sat;
}

// The rectangles of 8 boxes of voxel centres, each as its middle c and half extents e. For
// X = c + d (|d_a| <= e_a), u(X) - u(c) = ((P0 - u(c) P2) . d) / w(X) (the same for v with
// P1), and w(X) >= w(c) - sum_a |P2a| e_a: two divisions bound the rectangle of a whole box
// (its corners' projections would take eight; the bound is as tight up to the variation of w
// over the box, a fraction of a percent for a block at the station's distances).
void VisualHull::RectsOfBoxes(const Matrix34d& p, const BoxBatch& boxes, ProjectedRect* rects) {
  double pr[3][4];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) pr[r][c] = p(r, c);
  }
  double u[BoxBatch::kSize], v[BoxBatch::kSize], reach_u[BoxBatch::kSize], reach_v[BoxBatch::kSize];
  int state[BoxBatch::kSize];  // 0: in front, 1: behind, 2: straddles the camera's plane
  for (int i = 0; i < BoxBatch::kSize; ++i) {
    const double cx = boxes.cx[i], cy = boxes.cy[i], cz = boxes.cz[i];
    const double ex = boxes.ex[i], ey = boxes.ey[i], ez = boxes.ez[i];
    // Project's expression, in its order.
    const double hx = pr[0][0] * cx + pr[0][1] * cy + pr[0][2] * cz + pr[0][3];
    const double hy = pr[1][0] * cx + pr[1][1] * cy + pr[1][2] * cz + pr[1][3];
    const double hw = pr[2][0] * cx + pr[2][1] * cy + pr[2][2] * cz + pr[2][3];
    const double w_spread =
        std::abs(pr[2][0]) * ex + std::abs(pr[2][1]) * ey + std::abs(pr[2][2]) * ez;
    // Far beyond the rounding of w (relative ~1e-16); a block near the camera's plane is mixed.
    const double w_tolerance = 1e-9 * (std::abs(hw) + w_spread);
    const double w_min = hw - w_spread;
    const bool behind = hw + w_spread < -w_tolerance;
    const bool front = w_min > w_tolerance;  // false for NaN
    state[i] = front ? 0 : (behind ? 1 : 2);
    const double inv_w = 1.0 / hw;
    const double ui = hx * inv_w;
    const double vi = hy * inv_w;
    const double inv_w_min = 1.0 / w_min;
    u[i] = ui;
    v[i] = vi;
    reach_u[i] =
        (std::abs(pr[0][0] - ui * pr[2][0]) * ex + std::abs(pr[0][1] - ui * pr[2][1]) * ey +
         std::abs(pr[0][2] - ui * pr[2][2]) * ez) *
        inv_w_min;
    reach_v[i] =
        (std::abs(pr[1][0] - vi * pr[2][0]) * ex + std::abs(pr[1][1] - vi * pr[2][1]) * ey +
         std::abs(pr[1][2] - vi * pr[2][2]) * ez) *
        inv_w_min;
  }
  for (int i = 0; i < BoxBatch::kSize; ++i) {
    ProjectedRect& rect = rects[i];
    rect = ProjectedRect{};
    if (state[i] == 1) {
      rect.behind = 8;  // all behind the camera
    } else if (state[i] == 2) {
      rect.behind = 1;  // straddles the camera's plane (or a non-finite value)
      rect.in_front = 7;
    } else {
      rect.u_min = u[i] - reach_u[i];
      rect.u_max = u[i] + reach_u[i];
      rect.v_min = v[i] - reach_v[i];
      rect.v_max = v[i] + reach_v[i];
      rect.in_front = 8;
    }
  }
}

void VisualHull::AddBox(BoxBatch* boxes, int i, const Eigen::Vector3i& lo,
                        const Eigen::Vector3i& hi) const {
  const Eigen::Vector3d l = grid_.Centre(lo.x(), lo.y(), lo.z());
  const Eigen::Vector3d h = grid_.Centre(hi.x(), hi.y(), hi.z());
  boxes->cx[i] = 0.5 * (l.x() + h.x());
  boxes->cy[i] = 0.5 * (l.y() + h.y());
  boxes->cz[i] = 0.5 * (l.z() + h.z());
  boxes->ex[i] = 0.5 * (h.x() - l.x());
  boxes->ey[i] = 0.5 * (h.y() - l.y());
  boxes->ez[i] = 0.5 * (h.z() - l.z());
}

VisualHull::BlockClass VisualHull::ClassifyRect(const ViewData& view, const Sat& sat,
                                                const ProjectedRect& rect) {
  if (rect.in_front == 0) {
    return BlockClass::kUnaffected;  // all behind the camera: not seen
  }
  if (rect.behind > 0) {
    return BlockClass::kMixed;
  }
  const double u_min = rect.u_min, u_max = rect.u_max, v_min = rect.v_min, v_max = rect.v_max;
  // Nearest pixels, clamped to [-1, size] (enough to tell inside from outside).
  auto pixel = [](double x, int size) {
    // floor of the clamped value (in int's range: truncation, one less below a negative
    // non-integer; no libm call or SSE4.1 rounding needed).
    const double clamped = std::clamp(x + 0.5, -1.0, size + 1.0);
    const int truncated = static_cast<int>(clamped);
    return truncated - (clamped < truncated ? 1 : 0);
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
  return rect_inside ? BlockClass::kMixedInImage : BlockClass::kMixed;
}

namespace {

// CarveBrick's test of the occupied voxels (`word`) of a brick whose voxel centres' nearest
// pixels are all in the image and in front of the camera: the bits of those off the silhouette. A
// row of 4 voxels along x at a time, in 4-wide vectors: per lane the same operations in the same
// order as the point test, so the same values (no contraction: this file is built with
// -ffp-contract=off). Built for AVX2 too where the processor has it (the same results, twice as
// wide).
#if defined(__x86_64__) && defined(__GNUC__)
[[gnu::target_clones("avx2", "default")]]
#endif
std::uint64_t
CarvedInBrickInImage(const double (*px)[3], const double (*py)[3], const double (*pz)[3],
                     double p03, double p13, double p23, std::uint64_t word,
                     const std::uint8_t* mask, std::size_t step) {
  using Double4 = double __attribute__((vector_size(32)));
  using Int4 = std::int32_t __attribute__((vector_size(16)));
  Double4 row_x[3];
  for (int r = 0; r < 3; ++r) row_x[r] = Double4{px[0][r], px[1][r], px[2][r], px[3][r]};
  std::uint64_t carved = 0;
  for (int row = 0; row < 16; ++row) {
    const std::uint64_t occupied = (word >> (4 * row)) & 0xF;
    if (occupied == 0) continue;
    const int y = row & 3;
    const int z = row >> 2;
    const Double4 hx = row_x[0] + py[y][0] + pz[z][0] + p03;
    const Double4 hy = row_x[1] + py[y][1] + pz[z][1] + p13;
    const Double4 hw = row_x[2] + py[y][2] + pz[z][2] + p23;
    const Double4 inv_w = 1.0 / hw;
    const Int4 iu = __builtin_convertvector(hx * inv_w + 0.5, Int4);
    const Int4 iv = __builtin_convertvector(hy * inv_w + 0.5, Int4);
    std::uint64_t bits = 0;
    for (int x = 0; x < 4; ++x) {
      // Only occupied voxels are read: those past the grid's end may project out of the image.
      const bool carve = ((occupied >> x) & 1) != 0 && hw[x] > 0.0 &&
                         mask[step * static_cast<std::size_t>(iv[x]) + iu[x]] == 0;
      bits |= std::uint64_t{carve} << x;
    }
    carved |= bits << (4 * row);
  }
  return carved;
}

}  // namespace

template <bool kInImage>
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
  if constexpr (kInImage) {
    carved = CarvedInBrickInImage(px, py, pz, p(0, 3), p(1, 3), p(2, 3), word, view.mask01.data,
                                  view.mask01.step[0]);
  } else {
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
  if (level <= kClearByRowsLevel) {
    // A small cube of bricks: its rows cleared at once (and the flags below this level), without
    // looking for parts already empty.
    for (int l = level - 1; l >= 0; --l) {
      const int span = 1 << (level - l);
      const Eigen::Vector3i& dims = level_dims_[l];
      const Eigen::Vector3i lo = node * span;
      const Eigen::Vector3i hi = (lo + Eigen::Vector3i::Constant(span)).cwiseMin(dims);
      for (int z = lo.z(); z < hi.z(); ++z) {
        for (int y = lo.y(); y < hi.y(); ++y) {
          const Eigen::Vector3i first(lo.x(), y, z);
          if (l == 0) {
            std::fill_n(bricks_.begin() + BrickIndex(first), hi.x() - lo.x(), 0);
          } else {
            std::fill_n(alive_[l].begin() + NodeIndex(l, first), hi.x() - lo.x(), 0);
          }
        }
      }
    }
    return;
  }
  const Eigen::Vector3i& child_dims = level_dims_[level - 1];
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3i child = 2 * node + Eigen::Vector3i(c & 1, (c >> 1) & 1, (c >> 2) & 1);
    if ((child.array() < child_dims.array()).all()) {
      ClearBlock(level - 1, child);
    }
  }
}

bool VisualHull::Visit(const ViewData& view, const Sat& sat, int level, const Eigen::Vector3i& node,
                       BlockClass block_class) {
  if (level == 0) {
    return block_class == BlockClass::kMixedInImage ? CarveBrick<true>(view, node)
                                                    : CarveBrick<false>(view, node);
  }
  // The children that still hold occupied voxels, classified together.
  Eigen::Vector3i children[8];
  int count = 0;
  BoxBatch boxes;
  const Eigen::Vector3i& child_dims = level_dims_[level - 1];
  const int size = kBrick << (level - 1);
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3i child = 2 * node + Eigen::Vector3i(c & 1, (c >> 1) & 1, (c >> 2) & 1);
    if (!(child.array() < child_dims.array()).all()) continue;
    const bool occupied = level == 1 ? bricks_[BrickIndex(child)] != 0
                                     : alive_[level - 1][NodeIndex(level - 1, child)] != 0;
    if (!occupied) continue;
    const Eigen::Vector3i lo = child * size;
    const Eigen::Vector3i hi =
        (lo + Eigen::Vector3i::Constant(size - 1)).cwiseMin(grid_.dims - Eigen::Vector3i::Ones());
    AddBox(&boxes, count, lo, hi);
    children[count++] = child;
  }
  for (int i = count; i < BoxBatch::kSize; ++i) {
    AddBox(&boxes, i, Eigen::Vector3i::Zero(), Eigen::Vector3i::Zero());  // unused
  }
  ProjectedRect rects[BoxBatch::kSize];
  RectsOfBoxes(view.pixel_from_object, boxes, rects);
  bool any = false;
  for (int i = 0; i < count; ++i) {
    const BlockClass child_class = ClassifyRect(view, sat, rects[i]);
    switch (child_class) {
      case BlockClass::kUnaffected:
        any = true;
        break;
      case BlockClass::kCarve:
        ClearBlock(level - 1, children[i]);
        break;
      case BlockClass::kMixed:
      case BlockClass::kMixedInImage:
        any |= Visit(view, sat, level - 1, children[i], child_class);
        break;
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
  // The root: the whole grid.
  const int root = static_cast<int>(level_dims_.size()) - 1;
  if (root == 0 ? bricks_[0] != 0 : alive_[root][0] != 0) {
    BoxBatch boxes;
    AddBox(&boxes, 0, Eigen::Vector3i::Zero(), grid_.dims - Eigen::Vector3i::Ones());
    for (int i = 1; i < BoxBatch::kSize; ++i) {
      AddBox(&boxes, i, Eigen::Vector3i::Zero(), Eigen::Vector3i::Zero());  // unused
    }
    ProjectedRect rects[BoxBatch::kSize];
    RectsOfBoxes(data->pixel_from_object, boxes, rects);
    const BlockClass root_class = ClassifyRect(*data, sat, rects[0]);
    if (root_class == BlockClass::kCarve) {
      ClearBlock(root, Eigen::Vector3i::Zero());
    } else if (root_class != BlockClass::kUnaffected) {
      Visit(*data, sat, root, Eigen::Vector3i::Zero(), root_class);
    }
  }
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
  // With a clip plane, the first layer of samples kept (centres at or above the plane).
  int k_min = 0;
  if (options.clip_below_z_mm) {
    const double k =
        std::ceil((*options.clip_below_z_mm - grid_.origin_mm.z()) / grid_.voxel_mm - 0.5);
    k_min = static_cast<int>(std::clamp(k, 0.0, static_cast<double>(grid_.dims.z())));
  }
  for (int z = 0; z < brick_dims_.z(); ++z) {
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
  }
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
  const cv::Mat& mask = view.mask01;
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
    const int u1 = std::min(std::max(iu, end_u), mask.cols - 1);
    const int v0 = std::max(std::min(iv, end_v), 0);
    const int v1 = std::min(std::max(iv, end_v), mask.rows - 1);
    bool all_on = true;
    for (int y = v0; y <= v1 && all_on; ++y) {
      const std::uint8_t* row = mask.ptr<std::uint8_t>(y);
      for (int x = u0; x <= u1; ++x) {
        all_on = all_on && row[x] != 0;
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
  const int cols = view.mask01.cols;
  const int rows = view.mask01.rows;
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

namespace {

// How far (px, along u and along v) a segment of at most one voxel along grid axis `axis` can
// move in a view's image, for segments inside the box whose 8 corners project to `projected`
// (P * [X; 1]); infinite when part of the box is not in front of the camera. With
// u(X) = x / w and a step d (x, w change by a = P0 . d, c = P2 . d), u(X + t d) - u(X) =
// t (a - c u(X)) / w(X + t d), so |du| <= (|a - c u0| + |c| |u(X) - u0|) / w_min for any u0:
// u0 at the middle of the box's u range (the box projects into the corners' convex hull) and
// w_min the corners' least w (w is linear) bound it for every point of the box.
struct StepBound {
  double u_px[3];
  double v_px[3];
};
StepBound MaxStepPx(const Matrix34d& p, const double (*projected)[3], double voxel_mm) {
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  StepBound bound{{kInfinity, kInfinity, kInfinity}, {kInfinity, kInfinity, kInfinity}};
  double w_min = kInfinity;
  double u_min = kInfinity, v_min = kInfinity, u_max = -kInfinity, v_max = -kInfinity;
  for (int c = 0; c < 8; ++c) {
    const double w = projected[c][2];
    if (!(w > 0.0)) return bound;
    w_min = std::min(w_min, w);
    const double u = projected[c][0] / w;
    const double v = projected[c][1] / w;
    u_min = std::min(u_min, u);
    u_max = std::max(u_max, u);
    v_min = std::min(v_min, v);
    v_max = std::max(v_max, v);
  }
  const double u0 = 0.5 * (u_min + u_max), half_u = 0.5 * (u_max - u_min);
  const double v0 = 0.5 * (v_min + v_max), half_v = 0.5 * (v_max - v_min);
  const double scale = voxel_mm / w_min;
  for (int axis = 0; axis < 3; ++axis) {
    const double c = std::abs(p(2, axis));
    const double u = (std::abs(p(0, axis) - u0 * p(2, axis)) + c * half_u) * scale;
    const double v = (std::abs(p(1, axis) - v0 * p(2, axis)) + c * half_v) * scale;
    if (std::isfinite(u) && std::isfinite(v)) {
      bound.u_px[axis] = u;
      bound.v_px[axis] = v;
    }
  }
  return bound;
}

// Tests on a view's silhouette packed one bit per pixel over the bounding rectangle of its
// non-zero pixels (ViewData::packed: a row fits a few cache lines, and the surface tests read
// it at random).
class PackedMask {
 public:
  // Rows of `words` words from `bits` over `roi` (as PackMask writes them).
  PackedMask(const cv::Rect& roi, int words, const std::uint64_t* bits)
      : roi_(roi), words_(words), bits_(bits) {}
  // Whether every pixel of [u0, u1] x [v0, v1] (image pixels; empty: true) is on the
  // silhouette. Pixels outside the rectangle are off. Inlined: the surface placement calls it
  // about 1.5 million times.
  [[gnu::always_inline]] bool AllOn(int u0, int v0, int u1, int v1) const {
    if (u0 > u1 || v0 > v1) return true;
    u0 -= roi_.x;
    u1 -= roi_.x;
    v0 -= roi_.y;
    v1 -= roi_.y;
    if (u0 < 0 || v0 < 0 || u1 >= roi_.width || v1 >= roi_.height) return false;
    const int cols = u1 - u0 + 1;
    if (cols > 57) return AllOnWide(u0, v0, u1, v1);
    const std::uint64_t want = (std::uint64_t{1} << cols) - 1;
    const int word = u0 >> 6;
    const int shift = u0 & 63;
    // Up to 4 rows without a branch per row (the outcome is hard to predict).
    const int rows = v1 - v0 + 1;
    std::uint64_t all = ~std::uint64_t{0};
    for (int r = 0; r < std::max(rows, 4); ++r) {
      const std::uint64_t* row =
          &bits_[static_cast<std::size_t>(std::min(v0 + r, v1)) * words_ + word];
      // (x << 1) << (63 - shift): the next word's low bits, 0 when shift is 0.
      const std::uint64_t value = (row[0] >> shift) | ((row[1] << 1) << (63 - shift));
      all &= value;
    }
    return (all & want) == want;
  }

  // on[i] = AllOn(u0[i], v0[i], u1[i], v1[i]) (1 or 0) for the `count` rectangles: with AVX2
  // where the processor has it, four at a time.
  void AllOnEach(const int* u0, const int* v0, const int* u1, const int* v1, std::size_t count,
                 std::uint8_t* on) const {
#if defined(REVOLVE_X86_AVX2)
    static const bool avx2 = __builtin_cpu_supports("avx2");
    // (With no bits, every rectangle is empty or outside: nothing to gather from.)
    if (avx2 && roi_.width > 0 && roi_.height > 0) {
      AllOnEachAvx2(u0, v0, u1, v1, count, on);
      return;
    }
#endif
    for (std::size_t i = 0; i < count; ++i) on[i] = AllOn(u0[i], v0[i], u1[i], v1[i]) ? 1 : 0;
  }

  // Whether every point of the convex hull of 8 points (their projections P * [X; 1]) that
  // the view sees lands on the silhouette: ClassifyRect's kUnaffected.
  bool AllOnOrUnseen(const double (*projected)[3], int width, int height) const {
    double u_min = std::numeric_limits<double>::infinity();
    double v_min = u_min, u_max = -u_min, v_max = -u_min;
    int in_front = 0;
    for (int c = 0; c < 8; ++c) {
      if (!(projected[c][2] > 0.0)) continue;
      ++in_front;
      const double inv_w = 1.0 / projected[c][2];
      const double u = projected[c][0] * inv_w;
      const double v = projected[c][1] * inv_w;
      u_min = std::min(u_min, u);
      u_max = std::max(u_max, u);
      v_min = std::min(v_min, v);
      v_max = std::max(v_max, v);
    }
    if (in_front == 0) return true;  // all behind the camera
    if (in_front < 8) return false;  // straddles the camera's plane
    auto pixel = [](double x, int size) {
      return static_cast<int>(std::floor(std::clamp(x + 0.5, -1.0, size + 1.0)));
    };
    const int u0 = std::max(pixel(u_min - kRectMarginPx, width), 0);
    const int u1 = std::min(pixel(u_max + kRectMarginPx, width), width - 1);
    const int v0 = std::max(pixel(v_min - kRectMarginPx, height), 0);
    const int v1 = std::min(pixel(v_max + kRectMarginPx, height), height - 1);
    return AllOn(u0, v0, u1, v1);  // empty (outside the image): not seen
  }

 private:
  // AllOnEach four rectangles at a time, with AVX2 (a row's two words of the four gathered at
  // once); the rectangles of more than 4 rows or 57 columns, which AllOn does not do branch-free
  // either, are left to it.
#if defined(REVOLVE_X86_AVX2)
  [[gnu::target("avx2")]] void AllOnEachAvx2(const int* u0, const int* v0, const int* u1,
                                             const int* v1, std::size_t count,
                                             std::uint8_t* on) const {
    const __m128i roi_x = _mm_set1_epi32(roi_.x), roi_y = _mm_set1_epi32(roi_.y);
    const __m128i last_x = _mm_set1_epi32(roi_.width - 1);
    const __m128i last_y = _mm_set1_epi32(roi_.height - 1);
    const __m128i zero = _mm_setzero_si128(), one = _mm_set1_epi32(1);
    const __m128i words = _mm_set1_epi32(words_);
    const __m128i max_cols = _mm_set1_epi32(57), max_rows = _mm_set1_epi32(4);
    const auto* bits = reinterpret_cast<const long long*>(bits_);
    std::size_t i = 0;
    for (; i + 4 <= count; i += 4) {
      const __m128i x0 =
          _mm_sub_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(u0 + i)), roi_x);
      const __m128i x1 =
          _mm_sub_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(u1 + i)), roi_x);
      const __m128i y0 =
          _mm_sub_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(v0 + i)), roi_y);
      const __m128i y1 =
          _mm_sub_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(v1 + i)), roi_y);
      // Lanes: empty (true), outside the rectangle of bits (false), too large (AllOn).
      const __m128i empty = _mm_or_si128(_mm_cmpgt_epi32(x0, x1), _mm_cmpgt_epi32(y0, y1));
      const __m128i outside =
          _mm_or_si128(_mm_or_si128(_mm_cmplt_epi32(x0, zero), _mm_cmplt_epi32(y0, zero)),
                       _mm_or_si128(_mm_cmpgt_epi32(x1, last_x), _mm_cmpgt_epi32(y1, last_y)));
      const __m128i cols = _mm_add_epi32(_mm_sub_epi32(x1, x0), one);
      const __m128i rows = _mm_add_epi32(_mm_sub_epi32(y1, y0), one);
      const __m128i large =
          _mm_or_si128(_mm_cmpgt_epi32(cols, max_cols), _mm_cmpgt_epi32(rows, max_rows));
      // The rows of every lane, clamped into the bits (the results of lanes decided above
      // are not used).
      const __m128i x = _mm_min_epi32(_mm_max_epi32(x0, zero), last_x);
      const __m128i first_row = _mm_min_epi32(_mm_max_epi32(y0, zero), last_y);
      const __m128i last_row = _mm_max_epi32(_mm_min_epi32(y1, last_y), first_row);
      const __m128i word = _mm_srai_epi32(x, 6);
      const __m256i shift = _mm256_cvtepi32_epi64(_mm_and_si128(x, _mm_set1_epi32(63)));
      const __m256i back = _mm256_sub_epi64(_mm256_set1_epi64x(63), shift);
      __m256i all = _mm256_set1_epi64x(-1);
      for (int r = 0; r < 4; ++r) {
        const __m128i row = _mm_min_epi32(_mm_add_epi32(first_row, _mm_set1_epi32(r)), last_row);
        const __m128i at = _mm_add_epi32(_mm_mullo_epi32(row, words), word);
        const __m256i low = _mm256_i32gather_epi64(bits, at, 8);
        const __m256i high = _mm256_i32gather_epi64(bits + 1, at, 8);
        // (high << 1) << (63 - shift): the next word's low bits, 0 when shift is 0.
        const __m256i value = _mm256_or_si256(_mm256_srlv_epi64(low, shift),
                                              _mm256_sllv_epi64(_mm256_slli_epi64(high, 1), back));
        all = _mm256_and_si256(all, value);
      }
      const __m256i width =
          _mm256_cvtepi32_epi64(_mm_min_epi32(_mm_max_epi32(cols, one), max_cols));
      const __m256i want =
          _mm256_sub_epi64(_mm256_sllv_epi64(_mm256_set1_epi64x(1), width), _mm256_set1_epi64x(1));
      const int full = _mm256_movemask_pd(
          _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_and_si256(all, want), want)));
      const int empty_mask = _mm_movemask_ps(_mm_castsi128_ps(empty));
      const int outside_mask = _mm_movemask_ps(_mm_castsi128_ps(outside));
      const int large_mask = _mm_movemask_ps(_mm_castsi128_ps(large));
      for (int lane = 0; lane < 4; ++lane) {
        const int bit = 1 << lane;
        if (empty_mask & bit) {
          on[i + lane] = 1;
        } else if (outside_mask & bit) {
          on[i + lane] = 0;
        } else if (large_mask & bit) {
          on[i + lane] = AllOn(u0[i + lane], v0[i + lane], u1[i + lane], v1[i + lane]) ? 1 : 0;
        } else {
          on[i + lane] = (full & bit) ? 1 : 0;
        }
      }
    }
    for (; i < count; ++i) on[i] = AllOn(u0[i], v0[i], u1[i], v1[i]) ? 1 : 0;
  }
#endif

  bool AllOnWide(int u0, int v0, int u1, int v1) const {
    for (int v = v0; v <= v1; ++v) {
      for (int u = u0; u <= u1; ++u) {
        if (!((bits_[static_cast<std::size_t>(v) * words_ + (u >> 6)] >> (u & 63)) & 1)) {
          return false;
        }
      }
    }
    return true;
  }

  cv::Rect roi_;
  int words_ = 0;
  const std::uint64_t* bits_ = nullptr;
};

// P * [X; 1] = (hx, hy, w) and the pixel (u, v) = (hx / w, hy / w) of `count` points (SoA),
// each as Project computes it (the same operations in the same order, so the same values; the
// loop is vectorised).
void ProjectPoints(const Matrix34d& p, const double* __restrict x, const double* __restrict y,
                   const double* __restrict z, std::size_t count, double* __restrict hx_out,
                   double* __restrict hy_out, double* __restrict w, double* __restrict u,
                   double* __restrict v) {
  const double p00 = p(0, 0), p01 = p(0, 1), p02 = p(0, 2), p03 = p(0, 3);
  const double p10 = p(1, 0), p11 = p(1, 1), p12 = p(1, 2), p13 = p(1, 3);
  const double p20 = p(2, 0), p21 = p(2, 1), p22 = p(2, 2), p23 = p(2, 3);
  for (std::size_t i = 0; i < count; ++i) {
    const double hx = p00 * x[i] + p01 * y[i] + p02 * z[i] + p03;
    const double hy = p10 * x[i] + p11 * y[i] + p12 * z[i] + p13;
    const double hw = p20 * x[i] + p21 * y[i] + p22 * z[i] + p23;
    hx_out[i] = hx;
    hy_out[i] = hy;
    w[i] = hw;
    u[i] = hx / hw;
    v[i] = hy / hw;
  }
}

// The nearest pixel of x (used in front of the camera only; NaN and huge values are clamped so
// that the conversion is defined).
inline int NearestPixel(double x) {
  return static_cast<int>(std::floor((x > -1e9 ? (x < 1e9 ? x : 1e9) : -1e9) + 0.5));
}

// The nearest pixels (NearestPixel) of `count` points (hx / w, hy / w), as FirstExit computes
// its end pixel. A loop of its own, apart from the tests that depend on it, so that the
// divisions of successive points overlap; the AVX2 build (where the processor has it) rounds
// with one instruction.
#if defined(__x86_64__) && defined(__GNUC__)
[[gnu::target_clones("avx2", "default")]]
#endif
void NearestPixels(const double* __restrict hx, const double* __restrict hy,
                   const double* __restrict w, std::size_t count, int* __restrict u,
                   int* __restrict v) {
  for (std::size_t i = 0; i < count; ++i) {
    u[i] = NearestPixel(hx[i] / w[i]);
    v[i] = NearestPixel(hy[i] / w[i]);
  }
}

}  // namespace

std::vector<double> VisualHull::PlaceOnEdges(const std::vector<GridEdge>& edges,
                                             std::optional<double> clip_below_z_mm,
                                             bool cull_views) const {
  const std::size_t n = edges.size();
  const int views = view_count();
  // Each edge with the part of it that can hold the crossing (all of it, or up to the grid's
  // face for an edge leaving the grid, or up to the clip plane), grouped by its inside sample,
  // the samples sorted by block of 16 voxels, brick, then voxel. Per view, a block the view
  // cannot act on (its box grown by one voxel contains every segment of its edges) is skipped;
  // in the others, a sample whose neighbourhood (as far as its segments can move in the image)
  // is all on the silhouette skips its edges, then an edge whose end pixels' rectangle is all
  // on the silhouette; the rest are walked.
  struct Item {
    double t_max;
    std::uint32_t edge;
    std::int8_t axis;
    std::int8_t sign;
  };
  const Eigen::Vector3i block_dims = (brick_dims_ + Eigen::Vector3i::Constant(3)) / 4;
  auto block_of = [&](const Eigen::Vector3i& voxel) {
    const Eigen::Vector3i block = voxel / (4 * kBrick);
    return static_cast<std::uint32_t>(
        (std::int64_t{block.z()} * block_dims.y() + block.y()) * block_dims.x() + block.x());
  };
  // A voxel's place in its block: brick within the block (bits 6-11), voxel within the brick.
  auto local_key = [](const Eigen::Vector3i& voxel) {
    const Eigen::Vector3i brick = voxel / kBrick;
    const Eigen::Vector3i local = brick - 4 * (brick / 4);
    const Eigen::Vector3i in_brick = voxel - kBrick * brick;
    return static_cast<std::uint64_t>(local.x() | local.y() << 2 | local.z() << 4) << 6 |
           static_cast<std::uint64_t>(in_brick.x() | in_brick.y() << 2 | in_brick.z() << 4);
  };
  // The edges as (what the placement needs of the edge << 44 | local key << 32 | edge index),
  // grouped by block (a counting sort), then sorted by local key within each block (a few
  // hundred edges). What it needs: the axis (bits 0-1), whether the step is positive (bit 2)
  // and whether the edge leaves the grid (bit 3).
  std::vector<std::size_t> start(static_cast<std::size_t>(block_dims.prod()) + 1, 0);
  for (const GridEdge& edge : edges) ++start[block_of(edge.inside.cwiseMax(0)) + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  const auto order = std::make_unique_for_overwrite<std::uint64_t[]>(n);
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t e = 0; e < n; ++e) {
      const GridEdge& edge = edges[e];
      const Eigen::Vector3i voxel = edge.inside.cwiseMax(0);
      const Eigen::Vector3i step = edge.outside - edge.inside;
      const int axis = step.x() != 0 ? 0 : (step.y() != 0 ? 1 : 2);
      const bool leaves =
          ((edge.outside.array() < 0) || (edge.outside.array() >= grid_.dims.array())).any();
      const std::uint64_t need = static_cast<std::uint64_t>(axis) |
                                 static_cast<std::uint64_t>(step[axis] > 0) << 2 |
                                 static_cast<std::uint64_t>(leaves) << 3;
      order[fill[block_of(voxel)]++] = (need << 12 | local_key(voxel)) << 32 | e;
    }
  }
  {
    // Within a block: a radix sort on the local key, 6 bits at a time (stable: the edges of a
    // sample stay in the order of their indices).
    std::size_t most = 0;
    for (std::size_t b = 0; b + 1 < start.size(); ++b) {
      most = std::max(most, start[b + 1] - start[b]);
    }
    const auto scratch = std::make_unique_for_overwrite<std::uint64_t[]>(most);
    for (std::size_t b = 0; b + 1 < start.size(); ++b) {
      const std::size_t count = start[b + 1] - start[b];
      if (count < 2) continue;
      std::uint64_t* from = &order[start[b]];
      std::uint64_t* to = scratch.get();
      for (const int shift : {32, 38}) {
        std::array<std::uint32_t, 65> at{};
        for (std::size_t i = 0; i < count; ++i) ++at[((from[i] >> shift) & 63) + 1];
        std::partial_sum(at.begin(), at.end(), at.begin());
        for (std::size_t i = 0; i < count; ++i) to[at[(from[i] >> shift) & 63]++] = from[i];
        std::swap(from, to);
      }
    }
  }

  struct Sample {  // an inside sample and its edges, items[first, first + count)
    std::uint8_t count;
    std::uint8_t axes;  // bit a: an edge along axis a
    std::uint32_t first;
  };
  struct Block {
    std::size_t begin, end;  // bricks
    Eigen::Vector3d corners[8];
  };
  // Points as structure of arrays (a sample's or a brick's centre).
  struct Points {
    std::vector<double> x, y, z;
    void Add(const Eigen::Vector3d& c) {
      x.push_back(c.x());
      y.push_back(c.y());
      z.push_back(c.z());
    }
  };
  std::vector<Item> items;  // in the order of `order`
  std::vector<Sample> samples;
  Points sample_centre;
  std::vector<std::size_t> brick_start;  // samples of brick b: [brick_start[b], brick_start[b + 1])
  Points brick_centre;
  // Per brick: the box of its samples' segments (grid coordinates, voxels).
  std::vector<Eigen::Vector3d> brick_lo, brick_hi;
  std::vector<Block> blocks;
  // At most one sample, brick and block per edge: room for them, so that the arrays are not
  // moved as they grow (only the pages written are given memory).
  const std::size_t brick_bound = std::min(n, static_cast<std::size_t>(brick_dims_.prod()));
  items.reserve(n);
  samples.reserve(n);
  brick_start.reserve(brick_bound + 1);
  brick_lo.reserve(brick_bound);
  brick_hi.reserve(brick_bound);
  blocks.reserve(std::min(n, static_cast<std::size_t>(block_dims.prod())));
  for (auto [points, size] :
       {std::pair{&sample_centre, n}, std::pair{&brick_centre, brick_bound}}) {
    points->x.reserve(size);
    points->y.reserve(size);
    points->z.reserve(size);
  }
  for (std::size_t b = 0; b + 1 < start.size(); ++b) {
    const std::size_t end = start[b + 1];
    if (start[b] == end) continue;
    Block& block = blocks.emplace_back();
    block.begin = brick_start.size();
    // The block's first voxel.
    const auto index = static_cast<int>(b);
    const Eigen::Vector3i block_voxel =
        4 * kBrick *
        Eigen::Vector3i(index % block_dims.x(), index / block_dims.x() % block_dims.y(),
                        index / (block_dims.x() * block_dims.y()));
    {
      // The block's voxel centres grown by one voxel.
      const Eigen::Vector3i lo = block_voxel - Eigen::Vector3i::Ones();
      const Eigen::Vector3i hi = lo + Eigen::Vector3i::Constant(4 * kBrick + 1);
      const Eigen::Vector3d l = grid_.Centre(lo.x(), lo.y(), lo.z());
      const Eigen::Vector3d h = grid_.Centre(hi.x(), hi.y(), hi.z());
      for (int c = 0; c < 8; ++c) {
        block.corners[c] =
            Eigen::Vector3d(c & 1 ? h.x() : l.x(), c & 2 ? h.y() : l.y(), c & 4 ? h.z() : l.z());
      }
    }
    std::uint64_t brick_key = ~std::uint64_t{0};
    for (std::size_t i = start[b]; i < end;) {
      const std::uint64_t key = order[i] >> 32 & 0xFFF;
      const auto local = static_cast<int>(key);
      const Eigen::Vector3i voxel =
          block_voxel + kBrick * Eigen::Vector3i(local >> 6 & 3, local >> 8 & 3, local >> 10 & 3) +
          Eigen::Vector3i(local & 3, local >> 2 & 3, local >> 4 & 3);
      // The sample's edges become items.
      std::size_t j = i;
      std::uint8_t axes = 0;
      for (; j < end && (order[j] >> 32 & 0xFFF) == key; ++j) {
        const std::uint64_t need = order[j] >> 44;
        Item& item = items.emplace_back();
        item.axis = static_cast<std::int8_t>(need & 3);
        item.sign = static_cast<std::int8_t>(need & 4 ? 1 : -1);
        item.edge = static_cast<std::uint32_t>(order[j]);
        item.t_max = need & 8 ? 0.5 : 1.0;
        if (clip_below_z_mm && item.axis == 2 && item.sign < 0) {
          const double z = grid_.Centre(0, 0, voxel.z()).z();
          const double to_plane = (z - *clip_below_z_mm) / grid_.voxel_mm;
          if (to_plane >= 0.0 && to_plane < item.t_max) {
            item.t_max = to_plane;
          }
        }
        axes |= 1 << item.axis;
      }
      if ((key >> 6) != brick_key) {
        brick_key = key >> 6;
        brick_start.push_back(samples.size());
        brick_lo.push_back(voxel.cast<double>());
        brick_hi.push_back(voxel.cast<double>());
        block.end = brick_start.size();
      }
      // The segments' ends.
      for (std::size_t k = i; k < j; ++k) {
        Eigen::Vector3d tip = voxel.cast<double>();
        tip[items[k].axis] += items[k].sign * items[k].t_max;
        brick_lo.back() = brick_lo.back().cwiseMin(tip);
        brick_hi.back() = brick_hi.back().cwiseMax(tip);
      }
      samples.push_back(
          Sample{static_cast<std::uint8_t>(j - i), axes, static_cast<std::uint32_t>(i)});
      sample_centre.Add(grid_.Centre(voxel.x(), voxel.y(), voxel.z()));
      i = j;
    }
  }
  brick_start.push_back(samples.size());
  // Each brick's middle (mm) and half extents (voxels).
  std::vector<Eigen::Vector3d> brick_half(brick_lo.size());
  for (std::size_t b = 0; b < brick_lo.size(); ++b) {
    brick_centre.Add(grid_.Centre(0, 0, 0) + grid_.voxel_mm * 0.5 * (brick_lo[b] + brick_hi[b]));
    brick_half[b] = 0.5 * (brick_hi[b] - brick_lo[b]);
  }
  std::size_t largest_block = 0;  // in samples
  std::size_t most_bricks = 0;
  std::size_t most_items = 0;
  for (const Block& block : blocks) {
    const std::size_t first = brick_start[block.begin];
    const std::size_t last = brick_start[block.end];
    largest_block = std::max(largest_block, last - first);
    most_bricks = std::max(most_bricks, block.end - block.begin);
    most_items = std::max<std::size_t>(
        most_items, samples[last - 1].first + samples[last - 1].count - samples[first].first);
  }
  // Per block and view: the bricks' projections, then the samples of the bricks the view may
  // act on (gathered), their projections, and the samples to walk.
  std::vector<double> brick_hx(most_bricks), brick_hy(most_bricks), brick_w(most_bricks);
  std::vector<double> brick_u(most_bricks), brick_v(most_bricks);
  Points gathered;
  gathered.x.resize(largest_block);
  gathered.y.resize(largest_block);
  gathered.z.resize(largest_block);
  std::vector<std::uint32_t> gathered_sample(largest_block);
  std::vector<double> sample_hx(largest_block), sample_hy(largest_block), sample_w(largest_block);
  std::vector<double> sample_u(largest_block), sample_v(largest_block);
  std::vector<std::uint32_t> walk(largest_block);
  // Rectangles of pixels to test together (AllOnEach): the samples', then the items'.
  const std::size_t most_rects = std::max(largest_block, most_items);
  std::vector<int> rect_u0(most_rects), rect_v0(most_rects), rect_u1(most_rects),
      rect_v1(most_rects);
  std::vector<std::uint8_t> rect_on(most_rects);
  // The items of the samples to walk: item, sample (gathered), the part of the segment that
  // can matter, and its end (P * [X; 1]; then the nearest pixel).
  std::vector<std::uint32_t> walk_item(most_items), walk_sample(most_items);
  std::vector<double> walk_t(most_items), end_x(most_items), end_y(most_items), end_w(most_items);
  std::vector<int> end_u(most_items), end_v(most_items);
  std::vector<double> t_item(n);
  for (std::size_t k = 0; k < n; ++k) t_item[k] = items[k].t_max + 1.0;
  // Per sample, the longest part of its edges that can still hold a crossing (in voxels).
  std::vector<double> sample_t(samples.size());
  for (std::size_t s = 0; s < samples.size(); ++s) {
    for (std::size_t k = samples[s].first; k < samples[s].first + samples[s].count; ++k) {
      sample_t[s] = std::max(sample_t[s], items[k].t_max);
    }
  }
  for (int v = 0; v < views; ++v) {
    const ViewData& view = views_[v];
    const Matrix34d& p = view.pixel_from_object;
    const cv::Mat& mask = view.mask01;
    const PackedMask packed(view.roi, view.packed_words, view.packed.data());
    // P * d for the six steps (axis, sign), as FirstExit computes it.
    double step_h[3][2][3];
    for (int axis = 0; axis < 3; ++axis) {
      for (int s = 0; s < 2; ++s) {
        Eigen::Vector3d d = Eigen::Vector3d::Zero();
        d[axis] = (s == 0 ? -1 : 1) * grid_.voxel_mm;
        for (int r = 0; r < 3; ++r) {
          step_h[axis][s][r] = p(r, 0) * d.x() + p(r, 1) * d.y() + p(r, 2) * d.z();
        }
      }
    }
    // Whether the nearest pixels of [u - reach_u, u + reach_u] x [v - reach_v, v + reach_v]
    // (shifted by half a pixel) are all in the image and on the silhouette.
    auto all_on_around = [&](double w, double u, double pv, double reach_u, double reach_v)
        __attribute__((always_inline)) {
      const double u_lo = u + 0.5 - reach_u, u_hi = u + 0.5 + reach_u;
      const double v_lo = pv + 0.5 - reach_v, v_hi = pv + 0.5 + reach_v;
      return w > 0.0 && u_lo >= 0.0 && v_lo >= 0.0 && u_hi < mask.cols && v_hi < mask.rows &&
             packed.AllOn(static_cast<int>(u_lo), static_cast<int>(v_lo), static_cast<int>(u_hi),
                          static_cast<int>(v_hi));
    };
    for (const Block& block : blocks) {
      // How far the segments can move in the image (px): per set of axes (bit a: axis a) for a
      // sample's segments of one voxel, and per voxel along each axis for a brick's (below).
      // Infinite (NaN when multiplied by 0) where part of the block is behind the camera: then
      // nothing is left out.
      double reach_u[8], reach_v[8];
      std::fill(std::begin(reach_u), std::end(reach_u), std::numeric_limits<double>::infinity());
      std::fill(std::begin(reach_v), std::end(reach_v), std::numeric_limits<double>::infinity());
      StepBound bound{};
      if (cull_views) {
        double projected[8][3];
        for (int c = 0; c < 8; ++c) {
          const Homogeneous h = Project(p, block.corners[c]);
          projected[c][0] = h.x;
          projected[c][1] = h.y;
          projected[c][2] = h.w;
        }
        if (packed.AllOnOrUnseen(projected, mask.cols, mask.rows)) continue;
        bound = MaxStepPx(p, projected, grid_.voxel_mm);
        for (int axes = 1; axes < 8; ++axes) {
          double u = 0.0, w = 0.0;
          for (int axis = 0; axis < 3; ++axis) {
            if (axes & (1 << axis)) {
              u = std::max(u, bound.u_px[axis]);
              w = std::max(w, bound.v_px[axis]);
            }
          }
          reach_u[axes] = u;
          reach_v[axes] = w;
        }
      }
      // Bricks: those whose box is all on the silhouette are left out.
      const std::size_t bricks = block.end - block.begin;
      ProjectPoints(p, &brick_centre.x[block.begin], &brick_centre.y[block.begin],
                    &brick_centre.z[block.begin], bricks, brick_hx.data(), brick_hy.data(),
                    brick_w.data(), brick_u.data(), brick_v.data());
      std::size_t count = 0;
      for (std::size_t b = 0; b < bricks; ++b) {
        // From the middle to a corner of the box of the brick's segments: three legs along the
        // axes, each inside the block's box, plus a margin for the rounding of the projections
        // (~1e-12 px).
        const Eigen::Vector3d& half = brick_half[block.begin + b];
        const double brick_reach_u =
            half.x() * bound.u_px[0] + half.y() * bound.u_px[1] + half.z() * bound.u_px[2] + 1e-6;
        const double brick_reach_v =
            half.x() * bound.v_px[0] + half.y() * bound.v_px[1] + half.z() * bound.v_px[2] + 1e-6;
        if (cull_views &&
            all_on_around(brick_w[b], brick_u[b], brick_v[b], brick_reach_u, brick_reach_v)) {
          continue;
        }
        for (std::size_t s = brick_start[block.begin + b]; s < brick_start[block.begin + b + 1];
             ++s) {
          gathered.x[count] = sample_centre.x[s];
          gathered.y[count] = sample_centre.y[s];
          gathered.z[count] = sample_centre.z[s];
          gathered_sample[count++] = static_cast<std::uint32_t>(s);
        }
      }
      ProjectPoints(p, gathered.x.data(), gathered.y.data(), gathered.z.data(), count,
                    sample_hx.data(), sample_hy.data(), sample_w.data(), sample_u.data(),
                    sample_v.data());
      // Samples: those whose segments all stay on the silhouette are left out (no branch on
      // the outcome: it is hard to predict).
      // The rectangles are made first (all_on_around's; one outside the silhouette's where
      // that is false before any pixel is read), then tested together.
      for (std::size_t g = 0; g < count; ++g) {
        const std::uint32_t s = gathered_sample[g];
        const std::uint8_t axes = samples[s].axes;
        // The segments are as long as the part of them that can still hold the crossing.
        const double t = sample_t[s];
        const double around_u = reach_u[axes] * t + 1e-6, around_v = reach_v[axes] * t + 1e-6;
        const double u_lo = sample_u[g] + 0.5 - around_u, u_hi = sample_u[g] + 0.5 + around_u;
        const double v_lo = sample_v[g] + 0.5 - around_v, v_hi = sample_v[g] + 0.5 + around_v;
        const bool in_image =
            sample_w[g] > 0.0 && u_lo >= 0.0 && v_lo >= 0.0 && u_hi < mask.cols && v_hi < mask.rows;
        rect_u0[g] = static_cast<int>(in_image ? u_lo : -1.0);
        rect_v0[g] = static_cast<int>(in_image ? v_lo : -1.0);
        rect_u1[g] = static_cast<int>(in_image ? u_hi : -1.0);
        rect_v1[g] = static_cast<int>(in_image ? v_hi : -1.0);
      }
      packed.AllOnEach(rect_u0.data(), rect_v0.data(), rect_u1.data(), rect_v1.data(), count,
                       rect_on.data());
      std::size_t walks = 0;
      for (std::size_t g = 0; g < count; ++g) {
        walk[walks] = static_cast<std::uint32_t>(g);
        walks += rect_on[g] != 0 ? 0 : 1;
      }
      // The items of the samples to walk, with the end of the part of their segment that can
      // matter: only the part before the nearest exit found so far (the walk of the shorter
      // segment visits a prefix of the same cells, the same result where it matters, and its
      // end rectangle is smaller, so it more often ends at once).
      std::size_t m = 0;
      for (std::size_t q = 0; q < walks; ++q) {
        const std::size_t g = walk[q];
        const Sample& sample = samples[gathered_sample[g]];
        double longest = 0.0;
        for (std::size_t k = sample.first; k < sample.first + sample.count; ++k) {
          const Item& item = items[k];
          const double t_max = std::min(item.t_max, t_item[k]);
          longest = std::max(longest, t_max);
          const double* hd = step_h[item.axis][item.sign > 0 ? 1 : 0];
          walk_item[m] = static_cast<std::uint32_t>(k);
          walk_sample[m] = static_cast<std::uint32_t>(g);
          walk_t[m] = t_max;
          end_x[m] = sample_hx[g] + t_max * hd[0];
          end_y[m] = sample_hy[g] + t_max * hd[1];
          end_w[m] = sample_w[g] + t_max * hd[2];
          ++m;
        }
        sample_t[gathered_sample[g]] = longest;
      }
      NearestPixels(end_x.data(), end_y.data(), end_w.data(), m, end_u.data(), end_v.data());
      // FirstExit's first test, on the same values, for the segments in front of the camera:
      // the rectangle of the end pixels, clamped to the image (the others' is not used).
      for (std::size_t r = 0; r < m; ++r) {
        const std::size_t g = walk_sample[r];
        const int iu = NearestPixel(sample_u[g]);
        const int iv = NearestPixel(sample_v[g]);
        rect_u0[r] = std::max(std::min(iu, end_u[r]), 0);
        rect_u1[r] = std::min(std::max(iu, end_u[r]), mask.cols - 1);
        rect_v0[r] = std::max(std::min(iv, end_v[r]), 0);
        rect_v1[r] = std::min(std::max(iv, end_v[r]), mask.rows - 1);
      }
      packed.AllOnEach(rect_u0.data(), rect_v0.data(), rect_u1.data(), rect_v1.data(), m,
                       rect_on.data());
      for (std::size_t r = 0; r < m; ++r) {
        const std::size_t k = walk_item[r];
        const std::size_t g = walk_sample[r];
        const Item& item = items[k];
        const double t_max = walk_t[r];
        const double hx = sample_hx[g];
        const double hy = sample_hy[g];
        const double hw = sample_w[g];
        const double* hd = step_h[item.axis][item.sign > 0 ? 1 : 0];
        if (hw > 0.0 && end_w[r] > 0.0) {
          if (rect_on[r] != 0) continue;
          t_item[k] =
              std::min(t_item[k], WalkCells(view, hx, hy, hw, hd, t_max, NearestPixel(sample_u[g]),
                                            NearestPixel(sample_v[g]), end_u[r], end_v[r]));
          continue;
        }
        const Eigen::Vector3d a(gathered.x[g], gathered.y[g], gathered.z[g]);
        Eigen::Vector3d d = Eigen::Vector3d::Zero();
        d[item.axis] = item.sign * grid_.voxel_mm;
        t_item[k] = std::min(t_item[k], FirstExit(view, a, d, t_max));
      }
    }
  }
  // No view cuts the segment: its end (the grid's face, the plane, or rounding for an edge
  // inside the grid, whose outside sample some view carved).
  std::vector<double> t(n);
  for (std::size_t k = 0; k < n; ++k) t[items[k].edge] = std::min(t_item[k], items[k].t_max);
  return t;
}

}  // namespace revolve::reconstruct
