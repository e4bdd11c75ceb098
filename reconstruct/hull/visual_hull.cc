#include "reconstruct/hull/visual_hull.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/mask_bits.h"
#include "base/mask_rect.h"
#include "reconstruct/hull/hull_internal.h"
#include "reconstruct/hull/marching_cubes.h"
#include "reconstruct/parallel.h"

namespace revolve::reconstruct {

using namespace hull_internal;  // NOLINT(google-build-using-namespace): this library's own parts

namespace {

// Rectangles up to this many pixels are counted on the mask rather than the summed-area table.
constexpr std::int64_t kDirectCountMaxArea = 16;
// Carved blocks up to this level (8 bricks a side) are cleared row by row.
constexpr int kClearByRowsLevel = 3;
// The children of blocks from this level up (64 voxels a side) are carved on all cores.
constexpr int kParallelLevel = 4;

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

std::optional<double> VoxelStepBoundPx(const VoxelGrid& grid, const View& view) {
  // u = a / w with a and w affine in X: du/dX_k = (P0k - u P2k) / w. The box, wholly in front
  // of the camera, projects into the hull of its corners' projections and w is least at a
  // corner, so |u|, |v| <= their largest at the corners and w >= its least there.
  const Matrix34d& p = view.pixel_from_object;
  const Eigen::Vector3d lo = grid.origin_mm;
  const Eigen::Vector3d hi = grid.MaxCorner();
  double max_u = 0.0;
  double max_v = 0.0;
  double min_w = std::numeric_limits<double>::infinity();
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d x((corner & 1) ? hi.x() : lo.x(), (corner & 2) ? hi.y() : lo.y(),
                            (corner & 4) ? hi.z() : lo.z());
    const Eigen::Vector3d h = p.leftCols<3>() * x + p.col(3);
    if (!(h.z() > 0.0)) return std::nullopt;
    const double u = h.x() / h.z();
    const double v = h.y() / h.z();
    if (!(u >= -0.5 && v >= -0.5 && u < view.width_px - 0.5 && v < view.height_px - 0.5)) {
      return std::nullopt;
    }
    max_u = std::max(max_u, std::abs(u));
    max_v = std::max(max_v, std::abs(v));
    min_w = std::min(min_w, h.z());
  }
  double step = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double z = std::abs(p(2, k));
    step = std::max(step, std::max(std::abs(p(0, k)) + max_u * z, std::abs(p(1, k)) + max_v * z));
  }
  return step * grid.voxel_mm / min_w;
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

namespace hull_internal {

void PackMask(const cv::Mat& mask01, const cv::Rect& roi, std::vector<std::uint64_t>* bits,
              int* words) {
  *words = (roi.width + 63) / 64 + 1;
  *bits = PackMaskBits(mask01, roi, *words);
}

}  // namespace hull_internal

Expected<VisualHull::ViewData> VisualHull::Prepare(const cv::Mat& mask, const View& view) {
  // A whole mask: the window of the whole image (the view's other checks are PrepareWindow's).
  if (view.width_px > 0 && view.height_px > 0 &&
      (mask.type() != CV_8UC1 || mask.cols != view.width_px || mask.rows != view.height_px)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("silhouette mask must be CV_8UC1 {}x{} (the view's size), got "
                                 "type {} {}x{}",
                                 view.width_px, view.height_px, mask.type(), mask.cols, mask.rows));
  }
  return PrepareWindow(mask, cv::Point(0, 0), view);
}

Expected<VisualHull::ViewData> VisualHull::PrepareWindow(const cv::Mat& window, cv::Point origin,
                                                         const View& view) {
  if (view.width_px <= 0 || view.height_px <= 0) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("view has no image size ({}x{})", view.width_px, view.height_px));
  }
  const cv::Rect image(0, 0, view.width_px, view.height_px);
  const cv::Rect held(origin, window.size());
  if (window.type() != CV_8UC1 || (held & image) != held) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("silhouette mask window must be CV_8UC1 within the view's {}x{} "
                                 "image, got type {} {}x{} at ({}, {})",
                                 view.width_px, view.height_px, window.type(), window.cols,
                                 window.rows, origin.x, origin.y));
  }
  if (!view.pixel_from_object.allFinite()) {
    return MakeError(ErrorCode::kBadInput, "view projection matrix is not finite");
  }
  ViewData data;
  data.pixel_from_object = view.pixel_from_object;
  data.width = view.width_px;
  data.height = view.height_px;
  const cv::Rect in_window = MaskRect(window);
  if (!in_window.empty()) {
    data.roi = in_window + origin;
    data.window =
        cv::Rect(data.roi.x - kWindowMarginPx, data.roi.y - kWindowMarginPx,
                 data.roi.width + 2 * kWindowMarginPx, data.roi.height + 2 * kWindowMarginPx) &
        image;
    data.mask01 = cv::Mat::zeros(data.window.size(), CV_8UC1);
    const cv::Rect both = held & data.window;
    cv::min(window(both - origin), 1, data.mask01(both - data.window.tl()));
  }
  PackMask(data.mask01, data.roi - data.window.tl(), &data.packed, &data.packed_words);
  return data;
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
  sat.width = view.width;
  sat.height = view.height;
  sat.roi = view.roi;
  if (!sat.roi.empty()) {
    cv::integral(view.mask01(sat.roi - view.window.tl()), sat.sum, CV_32S);
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
    // Within the held window (0 outside it).
    const cv::Rect& held = view.window;
    const int hu0 = std::max(cu0, held.x) - held.x;
    const int hu1 = std::min(cu1, held.x + held.width - 1) - held.x;
    const int hv0 = std::max(cv0, held.y) - held.y;
    const int hv1 = std::min(cv1, held.y + held.height - 1) - held.y;
    for (int v = hv0; v <= hv1; ++v) {
      const std::uint8_t* row = view.mask01.ptr<std::uint8_t>(v);
      for (int u = hu0; u <= hu1; ++u) {
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
  // The vectors' test reads the held window only.
  const cv::Rect& held = view.window;
  const bool rect_held =
      u0 >= held.x && v0 >= held.y && u1 < held.x + held.width && v1 < held.y + held.height;
  return rect_held ? BlockClass::kMixedInImage : BlockClass::kMixed;
}

namespace {

// CarveBrick's test of the occupied voxels (`word`) of a brick whose voxel centres' nearest
// pixels are all in the image and in front of the camera: the bits of those off the silhouette. A
// row of 4 voxels along x at a time, in 4-wide vectors: per lane the same operations in the same
// order as the point test, so the same values (no contraction: this file is built with
// -ffp-contract=off). Built for AVX2 too where the processor has it (the same results, twice as
// wide).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
std::uint64_t
CarvedInBrickInImage(const double (*px)[3], const double (*py)[3], const double (*pz)[3],
                     double p03, double p13, double p23, std::uint64_t word,
                     const std::uint8_t* mask, std::size_t step, int mask_u0, int mask_v0) {
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
                         mask[step * static_cast<std::size_t>(iv[x] - mask_v0) +
                              static_cast<std::size_t>(iu[x] - mask_u0)] == 0;
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
                                  view.mask01.step[0], view.window.x, view.window.y);
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
  // Whether each child still holds occupied voxels. Each child writes only its own bricks and
  // flags, so near the top of the tree they are visited on all cores.
  std::uint8_t child_any[BoxBatch::kSize] = {};
  const auto visit_child = [&](std::size_t i) {
    const BlockClass child_class = ClassifyRect(view, sat, rects[i]);
    switch (child_class) {
      case BlockClass::kUnaffected:
        child_any[i] = 1;
        break;
      case BlockClass::kCarve:
        ClearBlock(level - 1, children[i]);
        break;
      case BlockClass::kMixed:
      case BlockClass::kMixedInImage:
        child_any[i] = Visit(view, sat, level - 1, children[i], child_class) ? 1 : 0;
        break;
    }
  };
  if (level >= kParallelLevel) {
    ParallelFor(0, static_cast<std::size_t>(count), visit_child);
  } else {
    for (int i = 0; i < count; ++i) visit_child(static_cast<std::size_t>(i));
  }
  bool any = false;
  for (int i = 0; i < count; ++i) any |= child_any[i] != 0;
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
  Carve(*data, MakeSat(*data));
  views_.push_back(std::move(*data));
  return {};
}

Expected<VisualHull::PreparedView> VisualHull::PrepareView(const cv::Mat& mask, const View& view) {
  Expected<ViewData> data = Prepare(mask, view);
  if (!data) {
    return std::unexpected(data.error());
  }
  PreparedView prepared;
  prepared.data_ = std::make_shared<const ViewData>(std::move(*data));
  return prepared;
}

Expected<VisualHull::PreparedView> VisualHull::PrepareView(const cv::Mat& window, cv::Point origin,
                                                           const View& view) {
  Expected<ViewData> data = PrepareWindow(window, origin, view);
  if (!data) {
    return std::unexpected(data.error());
  }
  PreparedView prepared;
  prepared.data_ = std::make_shared<const ViewData>(std::move(*data));
  return prepared;
}

cv::Rect VisualHull::PreparedView::mask_rect() const { return data_ ? data_->roi : cv::Rect(); }

void VisualHull::Integrate(const PreparedView& view) {
  // The summed-area table is made for each hull (1.5 bytes a pixel more per view to keep).
  Carve(*view.data_, MakeSat(*view.data_));
  views_.push_back(*view.data_);
}

VisualHull::LeaveOneOut::LeaveOneOut(const VoxelGrid& grid, std::vector<PreparedView> views)
    : grid_(grid), views_(std::move(views)), survivors_(views_.size()) {
  ParallelFor(0, views_.size(), [&](std::size_t j) {
    VisualHull hull(grid_);
    const ViewData& data = *views_[j].data_;
    hull.Carve(data, MakeSat(data));
    survivors_[j] = std::move(hull.bricks_);
  });
}

VisualHull VisualHull::LeaveOneOut::Without(std::size_t i, bool keep_views, int tolerated) const {
  VisualHull hull(grid_);
  // carved[k]: the voxels at least k + 1 of the other views carve (bit-sliced counts, capped).
  const std::size_t levels = static_cast<std::size_t>(std::max(0, tolerated)) + 1;
  std::vector<std::vector<std::uint64_t>> carved(
      levels, std::vector<std::uint64_t>(hull.bricks_.size(), 0));
  for (std::size_t j = 0; j < views_.size(); ++j) {
    if (j == i) continue;
    const std::vector<std::uint64_t>& survivors = survivors_[j];
    for (std::size_t b = 0; b < hull.bricks_.size(); ++b) {
      const std::uint64_t carves = ~survivors[b];
      for (std::size_t k = levels - 1; k > 0; --k) carved[k][b] |= carved[k - 1][b] & carves;
      carved[0][b] |= carves;
    }
    if (keep_views) hull.views_.push_back(*views_[j].data_);
  }
  for (std::size_t b = 0; b < hull.bricks_.size(); ++b) hull.bricks_[b] &= ~carved[levels - 1][b];
  hull.RebuildFlags();
  return hull;
}

void VisualHull::Carve(const ViewData& data, const Sat& sat) {
  // The root: the whole grid.
  const int root = static_cast<int>(level_dims_.size()) - 1;
  if (root == 0 ? bricks_[0] != 0 : alive_[root][0] != 0) {
    BoxBatch boxes;
    AddBox(&boxes, 0, Eigen::Vector3i::Zero(), grid_.dims - Eigen::Vector3i::Ones());
    for (int i = 1; i < BoxBatch::kSize; ++i) {
      AddBox(&boxes, i, Eigen::Vector3i::Zero(), Eigen::Vector3i::Zero());  // unused
    }
    ProjectedRect rects[BoxBatch::kSize];
    RectsOfBoxes(data.pixel_from_object, boxes, rects);
    const BlockClass root_class = ClassifyRect(data, sat, rects[0]);
    if (root_class == BlockClass::kCarve) {
      ClearBlock(root, Eigen::Vector3i::Zero());
    } else if (root_class != BlockClass::kUnaffected) {
      Visit(data, sat, root, Eigen::Vector3i::Zero(), root_class);
    }
  }
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

}  // namespace revolve::reconstruct
