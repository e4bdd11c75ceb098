#include "reconstruct/texture/texture.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>

#include <fmt/format.h>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "reconstruct/union_find.h"

namespace revolve::reconstruct {
namespace {

constexpr int kChartMarginPx = 2;  // image pixels around a chart's rectangle
constexpr int kSmoothingPasses = 3;
constexpr float kNeighbourBonus = 0.1f;
constexpr int kNormalSmoothingPasses = 6;
constexpr int kCandidates = 3;  // views ranked per face and vertex
const Color kUnseenColor(128, 128, 128);

// One view's projection, in float for speed.
struct ViewGeometry {
  Eigen::Matrix<float, 3, 4> p;
  bool affine = false;
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();     // pinhole centre
  Eigen::Vector3f direction = Eigen::Vector3f::Zero();  // affine: toward the camera
  Eigen::Vector4f depth_row = Eigen::Vector4f::Zero();  // depth (mm) = depth_row . [X; 1]
  int width = 0;
  int height = 0;

  explicit ViewGeometry(const View& view) : width(view.width_px), height(view.height_px) {
    p = view.pixel_from_object.cast<float>();
    affine = view.IsAffine();
    const Eigen::Matrix3d m = view.pixel_from_object.leftCols<3>();
    if (affine) {
      direction = view.DirectionToCamera(Eigen::Vector3d::Zero()).cast<float>();
      depth_row << -direction, 0.0f;
    } else {
      centre = (-m.inverse() * view.pixel_from_object.col(3)).cast<float>();
      const double scale = m.row(2).norm();
      depth_row = (view.pixel_from_object.row(2) / scale).transpose().cast<float>();
    }
  }

  // Pixel of x; false behind the camera.
  bool Project(const Eigen::Vector3f& x, float* u, float* v) const {
    // Written out: Eigen's expression is not inlined here and this runs per vertex and view.
    const float hw = p(2, 0) * x.x() + p(2, 1) * x.y() + p(2, 2) * x.z() + p(2, 3);
    if (!(hw > 0.0f)) {
      return false;
    }
    *u = (p(0, 0) * x.x() + p(0, 1) * x.y() + p(0, 2) * x.z() + p(0, 3)) / hw;
    *v = (p(1, 0) * x.x() + p(1, 1) * x.y() + p(1, 2) * x.z() + p(1, 3)) / hw;
    return true;
  }
  float Depth(const Eigen::Vector3f& x) const { return depth_row.head<3>().dot(x) + depth_row[3]; }
  Eigen::Vector3f ToCamera(const Eigen::Vector3f& x) const {
    if (affine) return direction;
    const float dx = centre.x() - x.x(), dy = centre.y() - x.y(), dz = centre.z() - x.z();
    const float squared = dx * dx + dy * dy + dz * dz;
    const float inv = squared > 0.0f ? 1.0f / std::sqrt(squared) : 0.0f;
    return Eigen::Vector3f(dx * inv, dy * inv, dz * inv);
  }
  bool InImage(float u, float v) const {
    return u >= -0.5f && v >= -0.5f && u < width - 0.5f && v < height - 0.5f;
  }
};

// What a view needs to know of candidate points (SoA, `count` of them): inputs x, y, z (the
// position) and nx, ny, nz (the unit normal); outputs, for each point, the cosine between its
// normal and the direction to the camera (n . ViewGeometry::ToCamera(X)), its pixel (u, v)
// (ViewGeometry::Project; meaningless unless in_front) and whether it is in front of the camera,
// its depth (ViewGeometry::Depth), how far behind its depth cell it may lie and still be seen
// (edge_term + cell_term * the tangent of its angle to the camera, at most max_tan), and its
// blending weight cos^8.
struct PointTerms {
  const float *x, *y, *z, *nx, *ny, *nz;
  float *cos_angle, *u, *v, *depth, *tolerance, *weight;
  int* in_front;
};

// The loops of ComputePointTerms, each over arrays passed as restrict parameters (so that the
// compiler vectorises them) and each doing the operations of the functions named there in the
// same order as they do (Eigen's dot: x + (y + z)), so the same values. Built for AVX2 too where
// the processor has it (AVX2 brings no fused multiply-add).
#if defined(__x86_64__) && defined(__GNUC__)
#define REVOLVE_AVX2_TOO [[gnu::target_clones("avx2", "default")]]
#else
#define REVOLVE_AVX2_TOO
#endif
REVOLVE_AVX2_TOO void CosinesToCentre(const Eigen::Vector3f& centre, int count,
                                      const float* __restrict x, const float* __restrict y,
                                      const float* __restrict z, const float* __restrict nx,
                                      const float* __restrict ny, const float* __restrict nz,
                                      float* __restrict cos_angle) {
  const float ox = centre.x(), oy = centre.y(), oz = centre.z();
  for (int i = 0; i < count; ++i) {
    const float dx = ox - x[i], dy = oy - y[i], dz = oz - z[i];
    const float squared = dx * dx + dy * dy + dz * dz;
    // 1 / |d|, or 0 where d = 0 (a mask rather than a branch, so that the loop vectorises).
    const float inv_length = 1.0f / std::sqrt(squared);
    const std::uint32_t keep = 0u - static_cast<std::uint32_t>(squared > 0.0f);
    const float inv = std::bit_cast<float>(std::bit_cast<std::uint32_t>(inv_length) & keep);
    cos_angle[i] = nx[i] * (dx * inv) + (ny[i] * (dy * inv) + nz[i] * (dz * inv));
  }
}
REVOLVE_AVX2_TOO void CosinesToDirection(const Eigen::Vector3f& direction, int count,
                                         const float* __restrict nx, const float* __restrict ny,
                                         const float* __restrict nz, float* __restrict cos_angle) {
  const float tx = direction.x(), ty = direction.y(), tz = direction.z();
  for (int i = 0; i < count; ++i) cos_angle[i] = nx[i] * tx + (ny[i] * ty + nz[i] * tz);
}
REVOLVE_AVX2_TOO void PixelsAndDepths(const Eigen::Matrix<float, 3, 4>& p,
                                      const Eigen::Vector4f& depth_row, int count,
                                      const float* __restrict x, const float* __restrict y,
                                      const float* __restrict z, float* __restrict u,
                                      float* __restrict v, float* __restrict depth,
                                      int* __restrict in_front) {
  const float p00 = p(0, 0), p01 = p(0, 1), p02 = p(0, 2), p03 = p(0, 3);
  const float p10 = p(1, 0), p11 = p(1, 1), p12 = p(1, 2), p13 = p(1, 3);
  const float p20 = p(2, 0), p21 = p(2, 1), p22 = p(2, 2), p23 = p(2, 3);
  const float r0 = depth_row[0], r1 = depth_row[1], r2 = depth_row[2], r3 = depth_row[3];
  for (int i = 0; i < count; ++i) {
    const float hw = p20 * x[i] + p21 * y[i] + p22 * z[i] + p23;
    in_front[i] = static_cast<int>(hw > 0.0f);
    u[i] = (p00 * x[i] + p01 * y[i] + p02 * z[i] + p03) / hw;
    v[i] = (p10 * x[i] + p11 * y[i] + p12 * z[i] + p13) / hw;
    depth[i] = (r0 * x[i] + (r1 * y[i] + r2 * z[i])) + r3;
  }
}
REVOLVE_AVX2_TOO void TolerancesAndWeights(float max_tan, float edge_term, float cell_term,
                                           int count, const float* __restrict cos_angle,
                                           float* __restrict tolerance, float* __restrict weight) {
  for (int i = 0; i < count; ++i) {
    const float c = cos_angle[i];
    const float tan_angle =
        std::min(max_tan, std::sqrt(std::max(0.0f, 1.0f - c * c)) / std::max(c, 1e-3f));
    tolerance[i] = edge_term + cell_term * tan_angle;
    const float c2 = c * c;
    const float c4 = c2 * c2;
    weight[i] = c4 * c4;
  }
}

// PointTerms for `count` points in view g.
void ComputePointTerms(const ViewGeometry& g, float max_tan, float edge_term, float cell_term,
                       int count, const PointTerms& t) {
  if (g.affine) {
    CosinesToDirection(g.direction, count, t.nx, t.ny, t.nz, t.cos_angle);
  } else {
    CosinesToCentre(g.centre, count, t.x, t.y, t.z, t.nx, t.ny, t.nz, t.cos_angle);
  }
  PixelsAndDepths(g.p, g.depth_row, count, t.x, t.y, t.z, t.u, t.v, t.depth, t.in_front);
  TolerancesAndWeights(max_tan, edge_term, cell_term, count, t.cos_angle, t.tolerance, t.weight);
}

// A window of depth cells: cell_px-wide cells over the image (all_cols x all_rows), of which
// the window [c0, c0 + cols) x [r0, r0 + rows) is stored.
struct CellGrid {
  float inv_cell;
  int all_cols, all_rows;
  int c0, r0, cols, rows;
};

// For each point i (coordinates x, y, z; normal nx, ny, nz): its cell in the window (row-major
// index), or -1 when its normal does not face `toward` within `margin` (n . toward >= -margin),
// it is behind the camera or outside the window; and its depth depth_row . [X; 1]. One loop,
// vectorised; built for AVX2 too where the processor has it (the same results: each lane does
// the same operations, and AVX2 brings no fused multiply-add).
REVOLVE_AVX2_TOO void CellsOfPoints(const Eigen::Matrix<float, 3, 4>& p,
                                    const Eigen::Vector4f& depth_row, const Eigen::Vector3f& toward,
                                    float margin, const CellGrid& grid, const float* __restrict x,
                                    const float* __restrict y, const float* __restrict z,
                                    const float* __restrict nx, const float* __restrict ny,
                                    const float* __restrict nz, int count, int* __restrict cell_of,
                                    float* __restrict depth_of) {
  const float p00 = p(0, 0), p01 = p(0, 1), p02 = p(0, 2), p03 = p(0, 3);
  const float p10 = p(1, 0), p11 = p(1, 1), p12 = p(1, 2), p13 = p(1, 3);
  const float p20 = p(2, 0), p21 = p(2, 1), p22 = p(2, 2), p23 = p(2, 3);
  const float r0 = depth_row[0], r1 = depth_row[1], r2 = depth_row[2], r3 = depth_row[3];
  const float dx = toward.x(), dy = toward.y(), dz = toward.z();
  const float inv_cell = grid.inv_cell;
  const float all_cols = static_cast<float>(grid.all_cols);
  const float all_rows = static_cast<float>(grid.all_rows);
  const int c0 = grid.c0, w0 = grid.r0, cols = grid.cols, rows = grid.rows;
  for (int i = 0; i < count; ++i) {
    const float facing = nx[i] * dx + ny[i] * dy + nz[i] * dz;
    const float hw = p20 * x[i] + p21 * y[i] + p22 * z[i] + p23;
    const float inv = 1.0f / hw;
    const float u = (p00 * x[i] + p01 * y[i] + p02 * z[i] + p03) * inv;
    const float v = (p10 * x[i] + p11 * y[i] + p12 * z[i] + p13) * inv;
    // DepthCells::Cell(): (px + 0.5) / cell_px, its integer part when in [0, n).
    const float cu = (u + 0.5f) * inv_cell;
    const float cv = (v + 0.5f) * inv_cell;
    // Bitwise tests and clamps (NaN to 0) rather than branches, so the loop vectorises.
    const int seen = static_cast<int>(facing >= -margin) & static_cast<int>(hw > 0.0f) &
                     static_cast<int>(cu >= 0.0f) & static_cast<int>(cv >= 0.0f) &
                     static_cast<int>(cu < all_cols) & static_cast<int>(cv < all_rows);
    const int c = static_cast<int>(std::min(std::max(0.0f, cu), all_cols)) - c0;
    const int r = static_cast<int>(std::min(std::max(0.0f, cv), all_rows)) - w0;
    const int in_window = seen & static_cast<int>(c >= 0) & static_cast<int>(r >= 0) &
                          static_cast<int>(c < cols) & static_cast<int>(r < rows);
    cell_of[i] = in_window != 0 ? r * cols + c : -1;
    depth_of[i] = r0 * x[i] + r1 * y[i] + r2 * z[i] + r3;
  }
}

// The nearest depth of the vertices facing the camera in each cell of cell_px x cell_px pixels.
// Only the cells of `window` (pixels; the mesh's projection) are stored: the others hold no
// vertex, so they read as infinitely far, as they would in a full table (and the table stays
// small enough for the cache).
class DepthCells {
 public:
  DepthCells(int width, int height, int cell_px, float u_min, float v_min, float u_max, float v_max)
      : inv_cell_(1.0f / static_cast<float>(cell_px)),
        all_cols_((width + cell_px - 1) / cell_px + 1),
        all_rows_((height + cell_px - 1) / cell_px + 1) {
    // One cell of margin against rounding; the window is clamped to the table.
    c0_ = std::clamp(Cell(u_min, all_cols_) - 1, 0, all_cols_ - 1);
    r0_ = std::clamp(Cell(v_min, all_rows_) - 1, 0, all_rows_ - 1);
    const int c1 = std::clamp(Cell(u_max, all_cols_) + 1, c0_, all_cols_ - 1);
    const int r1 = std::clamp(Cell(v_max, all_rows_) + 1, r0_, all_rows_ - 1);
    cols_ = c1 - c0_ + 1;
    rows_ = r1 - r0_ + 1;
    depth_.assign(static_cast<std::size_t>(cols_) * rows_, std::numeric_limits<float>::infinity());
    marked_.assign(depth_.size(), 0);
  }
  // Splat of every point i (coordinates x, y, z) whose normal (nx, ny, nz) faces `toward`
  // within `margin` (n . toward >= -margin) and that lies in front of the camera, at the pixel
  // p projects it to, with the depth depth_row . [X; 1]. The projections of all points are
  // computed first, in one vectorised loop; `index` and `depth` are scratch space.
  void SplatFacing(const Eigen::Matrix<float, 3, 4>& p, const Eigen::Vector4f& depth_row,
                   const Eigen::Vector3f& toward, float margin, const float* __restrict x,
                   const float* __restrict y, const float* __restrict z, const float* __restrict nx,
                   const float* __restrict ny, const float* __restrict nz, int count,
                   std::vector<int>* index, std::vector<float>* depth) {
    index->resize(count);
    depth->resize(count);
    int* __restrict cell_of = index->data();
    float* __restrict depth_of = depth->data();
    const CellGrid grid{inv_cell_, all_cols_, all_rows_, c0_, r0_, cols_, rows_};
    CellsOfPoints(p, depth_row, toward, margin, grid, x, y, z, nx, ny, nz, count, cell_of,
                  depth_of);
    for (int i = 0; i < count; ++i) {
      if (cell_of[i] >= 0) {
        float& cell = depth_[static_cast<std::size_t>(cell_of[i])];
        cell = std::min(cell, depth_of[i]);
      }
    }
  }
  // Marks the cell a point at pixel (u, v) reads (At). Once every such point is marked and
  // EndMarks called, AnyMarked tells whether a point projecting into [u_min, u_max] x
  // [v_min, v_max] (finite; widened by a pixel against the rounding of projections) can land in
  // a marked cell: only the depths of those are read.
  void Mark(float u, float v) {
    const int c = std::clamp(Cell(u, all_cols_), 0, all_cols_ - 1) - c0_;
    const int r = std::clamp(Cell(v, all_rows_), 0, all_rows_ - 1) - r0_;
    if (c < 0 || r < 0 || c >= cols_ || r >= rows_) return;
    marked_[static_cast<std::size_t>(r) * cols_ + c] = 1;
  }
  void EndMarks() {
    // Summed-area table, one row and column of zeros first.
    const std::size_t stride = static_cast<std::size_t>(cols_) + 1;
    marked_sums_.assign(stride * (rows_ + 1), 0);
    for (int r = 0; r < rows_; ++r) {
      int row_sum = 0;
      for (int c = 0; c < cols_; ++c) {
        row_sum += marked_[static_cast<std::size_t>(r) * cols_ + c];
        marked_sums_[(r + 1) * stride + c + 1] = marked_sums_[r * stride + c + 1] + row_sum;
      }
    }
  }
  bool AnyMarked(float u_min, float v_min, float u_max, float v_max) const {
    const int c0 = std::max(Cell(u_min - 1.0f, all_cols_), 0) - c0_;
    const int c1 = std::min(Cell(u_max + 1.0f, all_cols_), all_cols_ - 1) - c0_;
    const int r0 = std::max(Cell(v_min - 1.0f, all_rows_), 0) - r0_;
    const int r1 = std::min(Cell(v_max + 1.0f, all_rows_), all_rows_ - 1) - r0_;
    const int lo_c = std::max(c0, 0), hi_c = std::min(c1, cols_ - 1);
    const int lo_r = std::max(r0, 0), hi_r = std::min(r1, rows_ - 1);
    if (lo_c > hi_c || lo_r > hi_r) return false;
    const std::size_t stride = static_cast<std::size_t>(cols_) + 1;
    const int sum = marked_sums_[(hi_r + 1) * stride + hi_c + 1] -
                    marked_sums_[lo_r * stride + hi_c + 1] -
                    marked_sums_[(hi_r + 1) * stride + lo_c] + marked_sums_[lo_r * stride + lo_c];
    return sum > 0;
  }
  float At(float u, float v) const {
    const int c = std::clamp(Cell(u, all_cols_), 0, all_cols_ - 1) - c0_;
    const int r = std::clamp(Cell(v, all_rows_), 0, all_rows_ - 1) - r0_;
    if (c < 0 || r < 0 || c >= cols_ || r >= rows_) return std::numeric_limits<float>::infinity();
    return depth_[static_cast<std::size_t>(r) * cols_ + c];
  }

 private:
  // The cell holding pixel coordinate px, clamped to [-1, n] (NaN: -1).
  int Cell(float px, int n) const {
    const float x = (px + 0.5f) * inv_cell_;
    if (!(x >= 0.0f)) return -1;
    return x >= static_cast<float>(n) ? n : static_cast<int>(x);
  }

  float inv_cell_;
  int all_cols_;  // the whole image's table
  int all_rows_;
  int c0_ = 0;  // the window's first cell
  int r0_ = 0;
  int cols_ = 0;
  int rows_ = 0;
  std::vector<float> depth_;
  std::vector<std::uint8_t> marked_;
  std::vector<int> marked_sums_;
};

// Four floats as one value (GCC's vector extension: one register where the processor has them).
using Float4 = float __attribute__((vector_size(16)));

// SampleBilinear(bgr, u, v) as (b, g, r, 1): each lane does the same operations in the same
// order (float(b) - float(a) is the integer difference exactly), so it gives the same values.
[[gnu::always_inline]] inline Float4 SampleBilinearWithOne(const cv::Mat& bgr, float u, float v) {
  const float x = std::clamp(u, 0.0f, static_cast<float>(bgr.cols - 1));
  const float y = std::clamp(v, 0.0f, static_cast<float>(bgr.rows - 1));
  const int x0 = std::min(static_cast<int>(x), bgr.cols - 2 < 0 ? 0 : bgr.cols - 2);
  const int y0 = std::min(static_cast<int>(y), bgr.rows - 2 < 0 ? 0 : bgr.rows - 2);
  const int x1 = std::min(x0 + 1, bgr.cols - 1);
  const int y1 = std::min(y0 + 1, bgr.rows - 1);
  const float fx = x - x0;
  const float fy = y - y0;
  const cv::Vec3b* r0 = bgr.ptr<cv::Vec3b>(y0);
  const cv::Vec3b* r1 = bgr.ptr<cv::Vec3b>(y1);
  auto pixel = [](const cv::Vec3b& p, float last) {
    return Float4{static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]),
                  last};
  };
  // The fourth lane: 1 + fx * (1 - 1) = 1, and the same down the column.
  const Float4 top = pixel(r0[x0], 1.0f) + fx * (pixel(r0[x1], 1.0f) - pixel(r0[x0], 1.0f));
  const Float4 bottom = pixel(r1[x0], 1.0f) + fx * (pixel(r1[x1], 1.0f) - pixel(r1[x0], 1.0f));
  return top + fy * (bottom - top);
}

// The image's colour (b, g, r) at pixel (u, v), bilinear, clamped to the image.
Eigen::Vector3f SampleBilinear(const cv::Mat& bgr, float u, float v) {
  const Float4 sample = SampleBilinearWithOne(bgr, u, v);
  return {sample[0], sample[1], sample[2]};
}

// The (up to 3) faces sharing an edge with each face; -1 for a border edge.
std::vector<std::array<int, 3>> FaceNeighbours(const Mesh& mesh) {
  const int nv = static_cast<int>(mesh.vertices.size());
  const int nf = static_cast<int>(mesh.faces.size());
  std::vector<int> start(nv + 1, 0);
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int c = 0; c < 3; ++c) ++start[f[c] + 1];
  }
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<int> faces_of(start.back());
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (int i = 0; i < nf; ++i) {
    for (int c = 0; c < 3; ++c) faces_of[fill[mesh.faces[i][c]]++] = i;
  }
  std::vector<std::array<int, 3>> neighbours(nf, {-1, -1, -1});
  for (int i = 0; i < nf; ++i) {
    const Eigen::Vector3i& f = mesh.faces[i];
    for (int c = 0; c < 3; ++c) {
      const int a = f[c];
      const int b = f[(c + 1) % 3];
      for (int k = start[a]; k < start[a + 1]; ++k) {
        const int g = faces_of[k];
        if (g == i) continue;
        const Eigen::Vector3i& h = mesh.faces[g];
        if (h[0] == b || h[1] == b || h[2] == b) {
          neighbours[i][c] = g;
          break;
        }
      }
    }
  }
  return neighbours;
}

struct Rect {
  int x = 0, y = 0, w = 0, h = 0;
};

// Shelf packing of `sizes` (w, h) into a strip `width` wide; returns the height used, or -1
// when a rectangle is wider than the strip.
int PackShelves(const std::vector<Rect>& sizes, int width, std::vector<Rect>* placed) {
  std::vector<int> order(sizes.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return sizes[a].h > sizes[b].h; });
  placed->assign(sizes.size(), Rect{});
  int x = 0, y = 0, shelf = 0;
  for (int i : order) {
    const Rect& s = sizes[i];
    if (s.w > width) return -1;
    if (x + s.w > width) {
      y += shelf;
      x = 0;
      shelf = 0;
    }
    (*placed)[i] = Rect{x, y, s.w, s.h};
    x += s.w;
    shelf = std::max(shelf, s.h);
  }
  return y + shelf;
}

}  // namespace

Expected<TextureStats> TextureMesh(Mesh* mesh, const std::vector<View>& views,
                                   const std::vector<cv::Mat>& images,
                                   const TextureOptions& options) {
  if (views.size() != images.size()) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{} views but {} images", views.size(), images.size()));
  }
  if (options.texture_size_px < 64 || options.texture_size_px > 16384) {
    return MakeError(ErrorCode::kBadInput, fmt::format("texture size {} px is out of range "
                                                       "[64, 16384]",
                                                       options.texture_size_px));
  }
  for (std::size_t k = 0; k < views.size(); ++k) {
    if (!images[k].empty() && (images[k].type() != CV_8UC3 || images[k].cols != views[k].width_px ||
                               images[k].rows != views[k].height_px)) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("image {} must be CV_8UC3 {}x{} (its view's size)", k,
                                   views[k].width_px, views[k].height_px));
    }
  }
  TextureStats stats;
  const int nv = static_cast<int>(mesh->vertices.size());
  const int nf = static_cast<int>(mesh->faces.size());
  if (nf == 0) {
    return stats;
  }
  const std::vector<Eigen::Vector3f>& vertices = mesh->vertices;

  // Per-face unit normals and centroids (structure of arrays for the per-view sweeps; for the
  // atlas only), vertex normals, and the mesh's scale.
  const int atlas_faces = options.atlas ? nf : 0;
  std::vector<float> fnx(atlas_faces), fny(atlas_faces), fnz(atlas_faces);
  std::vector<Eigen::Vector3f> centroid(atlas_faces);
  std::vector<Eigen::Vector3f> vertex_normal(nv, Eigen::Vector3f::Zero());
  double edge_sum = 0.0;
  Eigen::Vector3f lo = vertices[mesh->faces[0][0]];
  Eigen::Vector3f hi = lo;
  for (int i = 0; i < nf; ++i) {
    const Eigen::Vector3i& f = mesh->faces[i];
    const Eigen::Vector3f& a = vertices[f[0]];
    const Eigen::Vector3f& b = vertices[f[1]];
    const Eigen::Vector3f& c = vertices[f[2]];
    const Eigen::Vector3f n = (b - a).cross(c - a);
    for (int k = 0; k < 3; ++k) vertex_normal[f[k]] += n;
    if (i < atlas_faces) {
      const float length = n.norm();
      const Eigen::Vector3f unit =
          length > 0.0f ? Eigen::Vector3f(n / length) : Eigen::Vector3f::Zero();
      fnx[i] = unit.x();
      fny[i] = unit.y();
      fnz[i] = unit.z();
      centroid[i] = (a + b + c) / 3.0f;
    }
    edge_sum += (b - a).norm();
    lo = lo.cwiseMin(a);
    hi = hi.cwiseMax(a);
  }
  // The mesh keeps them too (Mesh::normals: +z where they vanish), for the writers.
  mesh->normals.resize(nv);
  for (int i = 0; i < nv; ++i) {
    Eigen::Vector3f& n = vertex_normal[i];
    const float length = n.norm();
    mesh->normals[i] = length > 0.0f && std::isfinite(length) ? Eigen::Vector3f(n / length)
                                                              : Eigen::Vector3f::UnitZ();
    n = length > 0.0f ? Eigen::Vector3f(n / length) : Eigen::Vector3f::Zero();
  }
  // Every vertex's box (lo and hi above take the faces' first corners only).
  Eigen::Vector3f box_lo = vertices[0];
  Eigen::Vector3f box_hi = box_lo;
  for (const Eigen::Vector3f& x : vertices) {
    box_lo = box_lo.cwiseMin(x);
    box_hi = box_hi.cwiseMax(x);
  }
  const float mean_edge_mm = static_cast<float>(edge_sum / nf);
  const Eigen::Vector3f mesh_centre = 0.5f * (lo + hi);
  const float mesh_radius = 0.5f * (hi - lo).norm();
  const float cos_min = static_cast<float>(std::cos(options.max_angle_deg * M_PI / 180.0));
  const float max_tan =
      std::sqrt(std::max(0.0f, 1.0f - cos_min * cos_min)) / std::max(cos_min, 0.05f);
  const std::vector<std::array<int, 3>> neighbours =
      options.atlas ? FaceNeighbours(*mesh) : std::vector<std::array<int, 3>>();

  // Smoothed face normals choose the views: the voxel staircase of the silhouettes tilts single
  // facets, and views chosen per raw facet would shatter the charts.
  // Start from the mean of the corners' (area-weighted) normals: already two rings wide.
  std::vector<float> snx(nf), sny(nf), snz(nf);
  for (int i = 0; i < nf && options.atlas; ++i) {
    const Eigen::Vector3i& f = mesh->faces[i];
    const Eigen::Vector3f n =
        (vertex_normal[f[0]] + vertex_normal[f[1]] + vertex_normal[f[2]]).normalized();
    snx[i] = n.x();
    sny[i] = n.y();
    snz[i] = n.z();
  }
  {
    std::vector<float> tx(nf), ty(nf), tz(nf);
    for (int pass = 0; options.atlas && pass < kNormalSmoothingPasses; ++pass) {
      for (int i = 0; i < nf; ++i) {
        float x = snx[i], y = sny[i], z = snz[i];
        for (int nb : neighbours[i]) {
          if (nb < 0) continue;
          x += snx[nb];
          y += sny[nb];
          z += snz[nb];
        }
        const float length = std::sqrt(x * x + y * y + z * z);
        const float inv = length > 0.0f ? 1.0f / length : 0.0f;
        tx[i] = x * inv;
        ty[i] = y * inv;
        tz[i] = z * inv;
      }
      snx.swap(tx);
      sny.swap(ty);
      snz.swap(tz);
    }
  }

  // Ranking: each face's and each vertex's kCandidates best views by the cosine to the
  // direction from the mesh's centre to the camera (within the mesh's angular radius of the
  // exact one); the exact cosine and visibility are then tested for these only.
  const int nviews = static_cast<int>(views.size());
  std::vector<ViewGeometry> geometry;
  geometry.reserve(nviews);
  for (const View& view : views) geometry.emplace_back(view);
  std::vector<Eigen::Vector3f> view_direction(nviews);
  std::vector<float> view_margin(nviews, 0.0f);
  for (int k = 0; k < nviews; ++k) {
    const ViewGeometry& g = geometry[k];
    view_direction[k] = g.ToCamera(mesh_centre);
    if (!g.affine) {
      const float distance = (g.centre - mesh_centre).norm();
      view_margin[k] =
          distance > mesh_radius ? std::min(1.0f, 1.05f * mesh_radius / distance) : 2.0f;
    }
  }
  struct Candidates {  // best first; empty slots: score -2, view -1
    std::array<float, kCandidates> score;
    std::array<std::int16_t, kCandidates> view;
    Candidates() {
      score.fill(-2.0f);
      view.fill(-1);
    }
    // Keeps (s, k) if it is among the kCandidates best so far (ties: the earlier first).
    void Insert(float s, int k) {
      if (s <= score[kCandidates - 1]) return;
      int slot = kCandidates - 1;
      while (slot > 0 && score[slot - 1] < s) {
        score[slot] = score[slot - 1];
        view[slot] = view[slot - 1];
        --slot;
      }
      score[slot] = s;
      view[slot] = static_cast<std::int16_t>(k);
    }
  };
  // The ranking is looked up: the sphere of directions is binned as a cube map, each bin holds
  // the views ranked for its centre, and a normal takes its bin's views, rescored with itself.
  constexpr int kBins = 48;  // per cube face side (under 2 degrees)
  std::vector<Candidates> bins(std::size_t{6} * kBins * kBins);
  std::vector<int> used_views;  // those with an image, and their directions
  std::vector<float> used_x, used_y, used_z;
  for (int k = 0; k < nviews; ++k) {
    if (images[k].empty()) continue;
    used_views.push_back(k);
    used_x.push_back(view_direction[k].x());
    used_y.push_back(view_direction[k].y());
    used_z.push_back(view_direction[k].z());
  }
  std::vector<float> used_score(used_views.size());
  for (int face = 0; face < 6; ++face) {
    for (int bt = 0; bt < kBins; ++bt) {
      for (int bs = 0; bs < kBins; ++bs) {
        const float a = 2.0f * (bs + 0.5f) / kBins - 1.0f;
        const float b = 2.0f * (bt + 0.5f) / kBins - 1.0f;
        Eigen::Vector3f n;
        const float sign = face & 1 ? -1.0f : 1.0f;
        switch (face / 2) {
          case 0:
            n = Eigen::Vector3f(sign, a, b);
            break;
          case 1:
            n = Eigen::Vector3f(a, sign, b);
            break;
          default:
            n = Eigen::Vector3f(a, b, sign);
            break;
        }
        n.normalize();
        // The scores first (one loop the compiler vectorises; the products summed in the order
        // of Eigen's dot: x + (y + z)), then the best kCandidates, in a local copy.
        for (std::size_t j = 0; j < used_views.size(); ++j) {
          used_score[j] = n.x() * used_x[j] + (n.y() * used_y[j] + n.z() * used_z[j]);
        }
        Candidates c;
        for (std::size_t j = 0; j < used_views.size(); ++j) c.Insert(used_score[j], used_views[j]);
        bins[(face * kBins + bt) * kBins + bs] = c;
      }
    }
  }
  auto bin_of = [&](float x, float y, float z) {
    const float ax = std::abs(x), ay = std::abs(y), az = std::abs(z);
    int face;
    float a, b, m;
    if (ax >= ay && ax >= az) {
      face = x >= 0.0f ? 0 : 1, a = y, b = z, m = ax;
    } else if (ay >= az) {
      face = y >= 0.0f ? 2 : 3, a = x, b = z, m = ay;
    } else {
      face = z >= 0.0f ? 4 : 5, a = x, b = y, m = az;
    }
    const float inv = m > 0.0f ? 0.5f * kBins / m : 0.0f;
    const int bs = std::clamp(static_cast<int>((a + m) * inv), 0, kBins - 1);
    const int bt = std::clamp(static_cast<int>((b + m) * inv), 0, kBins - 1);
    return (face * kBins + bt) * kBins + bs;
  };
  // The candidates of a normal (x, y, z): its bin's views that may see it, best first.
  auto rank_one = [&](float x, float y, float z) {
    Candidates c;
    if (x == 0.0f && y == 0.0f && z == 0.0f) return c;
    const Candidates& bin = bins[bin_of(x, y, z)];
    for (int slot = 0; slot < kCandidates; ++slot) {
      const int k = bin.view[slot];
      if (k < 0) break;
      const Eigen::Vector3f& d = view_direction[k];
      const float score = x * d.x() + y * d.y() + z * d.z();
      // Above -2 (cos_min - margin >= cos 85 deg - 2), so it takes a slot.
      if (score < cos_min - view_margin[k]) continue;
      c.Insert(score, k);
    }
    return c;
  };
  auto rank = [&](int count, const float* x, const float* y, const float* z) {
    std::vector<Candidates> out(count);
    for (int i = 0; i < count; ++i) out[i] = rank_one(x[i], y[i], z[i]);
    return out;
  };

  const std::vector<Candidates> face_candidates =
      options.atlas ? rank(nf, snx.data(), sny.data(), snz.data()) : std::vector<Candidates>();
  // The vertices and their normals as arrays, grouped in clusters by a coarse grid over their
  // box, each cluster with its box and normal cone: a view splats only the clusters that can
  // face it and project near its candidates.
  struct Cluster {
    int begin = 0, end = 0;  // in the arrays below
    Eigen::Vector3f lo, hi;
    Eigen::Vector3f axis = Eigen::Vector3f::Zero();
    float half_angle = static_cast<float>(M_PI);  // pi: no test
  };
  constexpr int kClusterSide = 8;
  std::vector<Cluster> clusters(std::size_t{kClusterSide} * kClusterSide * kClusterSide);
  std::vector<float> vx(nv), vy(nv), vz(nv), vnx(nv), vny(nv), vnz(nv);
  {
    const Eigen::Vector3f scale = kClusterSide * (box_hi - box_lo).cwiseMax(1e-6f).cwiseInverse();
    std::vector<int> cluster_of(nv);
    std::vector<int> start(clusters.size() + 1, 0);
    for (int i = 0; i < nv; ++i) {
      int cell[3];
      for (int a = 0; a < 3; ++a) {
        const float x = (vertices[i][a] - box_lo[a]) * scale[a];
        cell[a] = std::clamp(static_cast<int>(x >= 0.0f ? x : 0.0f), 0, kClusterSide - 1);
      }
      cluster_of[i] = (cell[2] * kClusterSide + cell[1]) * kClusterSide + cell[0];
      ++start[cluster_of[i] + 1];
    }
    std::partial_sum(start.begin(), start.end(), start.begin());
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (int i = 0; i < nv; ++i) {
      const int at = fill[cluster_of[i]]++;
      vx[at] = vertices[i].x();
      vy[at] = vertices[i].y();
      vz[at] = vertices[i].z();
      vnx[at] = vertex_normal[i].x();
      vny[at] = vertex_normal[i].y();
      vnz[at] = vertex_normal[i].z();
    }
    for (std::size_t c = 0; c < clusters.size(); ++c) {
      Cluster& cluster = clusters[c];
      cluster.begin = start[c];
      cluster.end = start[c + 1];
      if (cluster.begin == cluster.end) continue;
      cluster.lo = cluster.hi =
          Eigen::Vector3f(vx[cluster.begin], vy[cluster.begin], vz[cluster.begin]);
      bool unit_normals = true;
      for (int i = cluster.begin; i < cluster.end; ++i) {
        const Eigen::Vector3f x(vx[i], vy[i], vz[i]);
        cluster.lo = cluster.lo.cwiseMin(x);
        cluster.hi = cluster.hi.cwiseMax(x);
        const Eigen::Vector3f n(vnx[i], vny[i], vnz[i]);
        unit_normals = unit_normals && n.squaredNorm() > 0.5f;
        cluster.axis += n;
      }
      if (!unit_normals || !(cluster.axis.norm() > 1e-3f)) continue;  // no cone
      cluster.axis.normalize();
      float min_cos = 1.0f;
      for (int i = cluster.begin; i < cluster.end; ++i) {
        min_cos = std::min(min_cos, cluster.axis.dot(Eigen::Vector3f(vnx[i], vny[i], vnz[i])));
      }
      cluster.half_angle = std::acos(std::clamp(min_cos, -1.0f, 1.0f));
    }
  }
  // Per view, the faces it is a candidate for (slot in the low bits).
  std::vector<int> face_start(nviews + 1, 0);
  for (const Candidates& c : face_candidates) {
    for (int s = 0; s < kCandidates; ++s) {
      if (c.view[s] >= 0) ++face_start[c.view[s] + 1];
    }
  }
  std::partial_sum(face_start.begin(), face_start.end(), face_start.begin());
  std::vector<std::int64_t> face_entries(face_start.back());
  {
    std::vector<int> fill(face_start.begin(), face_start.end() - 1);
    for (std::size_t i = 0; i < face_candidates.size(); ++i) {
      for (int s = 0; s < kCandidates; ++s) {
        const int k = face_candidates[i].view[s];
        if (k >= 0) face_entries[fill[k]++] = static_cast<std::int64_t>(i) * kCandidates + s;
      }
    }
  }
  struct Pending {  // a candidate face to test in a view
    int index;
    int slot;    // the face's candidate slot
    float u, v;  // its pixel
    float cos_angle;
  };
  struct Window {  // pixels
    float u_min = std::numeric_limits<float>::infinity();
    float v_min = std::numeric_limits<float>::infinity();
    float u_max = -std::numeric_limits<float>::infinity();
    float v_max = -std::numeric_limits<float>::infinity();
    void Add(float u, float v) {
      u_min = std::min(u_min, u);
      u_max = std::max(u_max, u);
      v_min = std::min(v_min, v);
      v_max = std::max(v_max, v);
    }
  };
  // Per view, the vertices it is a candidate for, in the mesh's order.
  std::vector<int> vertex_start(nviews + 1, 0);
  std::vector<int> vertex_entries;
  if (options.vertex_colors) {
    std::vector<std::array<std::int16_t, kCandidates>> ranked(nv);
    for (int vi = 0; vi < nv; ++vi) {
      const Eigen::Vector3f& n = vertex_normal[vi];
      ranked[vi] = rank_one(n.x(), n.y(), n.z()).view;
      for (int slot = 0; slot < kCandidates && ranked[vi][slot] >= 0; ++slot) {
        ++vertex_start[ranked[vi][slot] + 1];
      }
    }
    std::partial_sum(vertex_start.begin(), vertex_start.end(), vertex_start.begin());
    vertex_entries.resize(vertex_start.back());
    std::vector<int> fill(vertex_start.begin(), vertex_start.end() - 1);
    for (int vi = 0; vi < nv; ++vi) {
      for (int slot = 0; slot < kCandidates && ranked[vi][slot] >= 0; ++slot) {
        vertex_entries[fill[ranked[vi][slot]]++] = vi;
      }
    }
  }
  // Scratch for a view's candidate vertices: positions and normals, then their PointTerms.
  std::vector<float> cx, cy, cz, cnx, cny, cnz, c_cos, c_u, c_v, c_depth, c_tolerance, c_weight;
  std::vector<int> c_front;

  // Per view: the depth of the surface facing the camera, splatted from the vertices into cells
  // about 1.5 mean edges wide, then the visibility of the candidates.
  std::vector<float> face_cos(options.atlas ? static_cast<std::size_t>(nf) * kCandidates : 0,
                              -2.0f);  // -2: unseen
  // Per vertex: the weighted sum of its samples (b, g, r) and of their weights.
  std::vector<Float4> color_sum(options.vertex_colors ? nv : 0, Float4{0.0f, 0.0f, 0.0f, 0.0f});
  std::vector<int> splat_cell;  // scratch for the splats
  std::vector<float> splat_depth;
  std::vector<Pending> pending_faces;
  struct VertexPending {  // a candidate vertex to test in a view, with its PointTerms
    int index;
    float u, v;
    float depth, tolerance, weight;
  };
  std::vector<VertexPending> pending_vertices;
  for (int k = 0; k < nviews; ++k) {
    if (images[k].empty()) continue;
    ++stats.views_used;
    const ViewGeometry& g = geometry[k];
    const cv::Mat& image = images[k];
    const Eigen::Vector3f& d = view_direction[k];
    float mm_per_px = 1.0f;
    {
      float u0, v0, u1, v1;
      if (g.Project(mesh_centre, &u0, &v0) &&
          g.Project(mesh_centre + d.unitOrthogonal(), &u1, &v1)) {
        mm_per_px = 1.0f / std::max(1e-6f, std::hypot(u1 - u0, v1 - v0));
      }
    }
    const int cell_px =
        std::clamp(static_cast<int>(std::ceil(1.5f * mean_edge_mm / mm_per_px)), 1, 16);
    const float cell_mm = cell_px * mm_per_px;
    // The vertices this view may colour (ranked for it, facing it within max_angle_deg, in its
    // image), their pixels, and the window of depth cells they need.
    Window window;
    pending_vertices.clear();
    {
      const int first = vertex_start[k];
      const int count = vertex_start[k + 1] - first;
      for (auto* scratch : {&cx, &cy, &cz, &cnx, &cny, &cnz, &c_cos, &c_u, &c_v, &c_depth,
                            &c_tolerance, &c_weight}) {
        scratch->resize(count);
      }
      c_front.resize(count);
      for (int j = 0; j < count; ++j) {
        const int vi = vertex_entries[first + j];
        cx[j] = vertices[vi].x();
        cy[j] = vertices[vi].y();
        cz[j] = vertices[vi].z();
        cnx[j] = vertex_normal[vi].x();
        cny[j] = vertex_normal[vi].y();
        cnz[j] = vertex_normal[vi].z();
      }
      ComputePointTerms(g, max_tan, 2.0f * mean_edge_mm, 4.0f * cell_mm, count,
                        PointTerms{cx.data(), cy.data(), cz.data(), cnx.data(), cny.data(),
                                   cnz.data(), c_cos.data(), c_u.data(), c_v.data(), c_depth.data(),
                                   c_tolerance.data(), c_weight.data(), c_front.data()});
      pending_vertices.resize(count);
      int kept = 0;
      for (int j = 0; j < count; ++j) {
        if (c_cos[j] < cos_min || !c_front[j] || !g.InImage(c_u[j], c_v[j])) continue;
        pending_vertices[kept++] = VertexPending{
            vertex_entries[first + j], c_u[j], c_v[j], c_depth[j], c_tolerance[j], c_weight[j]};
        window.Add(c_u[j], c_v[j]);
      }
      pending_vertices.resize(kept);
    }
    // The same for the faces this view may texture.
    pending_faces.clear();
    for (int e = face_start[k]; e < face_start[k + 1]; ++e) {
      const int i = static_cast<int>(face_entries[e] / kCandidates);
      const int slot = static_cast<int>(face_entries[e] % kCandidates);
      const Eigen::Vector3f to_camera = g.ToCamera(centroid[i]);
      if (Eigen::Vector3f(fnx[i], fny[i], fnz[i]).dot(to_camera) <= 0.0f) continue;
      const float cos_angle = Eigen::Vector3f(snx[i], sny[i], snz[i]).dot(to_camera);
      float u, v;
      if (cos_angle < cos_min || !g.Project(centroid[i], &u, &v) || !g.InImage(u, v)) continue;
      pending_faces.push_back(Pending{i, slot, u, v, cos_angle});
      window.Add(u, v);
    }
    if (pending_faces.empty() && pending_vertices.empty()) continue;
    DepthCells cells(g.width, g.height, cell_px, window.u_min, window.v_min, window.u_max,
                     window.v_max);
    for (const Pending& p : pending_faces) cells.Mark(p.u, p.v);
    for (const VertexPending& p : pending_vertices) cells.Mark(p.u, p.v);
    cells.EndMarks();
    // Every vertex facing the camera (within the margin) and in front of it is splatted into
    // the cells the candidates read; a cluster whose normals all face away, or whose box
    // projects away from every such cell, holds none that lands in one.
    const float margin = view_margin[k];
    const float facing_limit = std::acos(std::clamp(-margin, -1.0f, 1.0f)) + 1e-3f;
    for (const Cluster& cluster : clusters) {
      if (cluster.begin == cluster.end) continue;
      if (cluster.half_angle < static_cast<float>(M_PI) &&
          std::acos(std::clamp(cluster.axis.dot(d), -1.0f, 1.0f)) - cluster.half_angle >
              facing_limit) {
        continue;
      }
      float c_u_min = std::numeric_limits<float>::infinity(), c_v_min = c_u_min;
      float c_u_max = -c_u_min, c_v_max = -c_u_min;
      bool in_front = true;
      for (int c = 0; c < 8 && in_front; ++c) {
        const Eigen::Vector3f corner(c & 1 ? cluster.hi.x() : cluster.lo.x(),
                                     c & 2 ? cluster.hi.y() : cluster.lo.y(),
                                     c & 4 ? cluster.hi.z() : cluster.lo.z());
        float u = 0.0f, v = 0.0f;
        in_front = g.Project(corner, &u, &v) && std::isfinite(u) && std::isfinite(v);
        c_u_min = std::min(c_u_min, u);
        c_u_max = std::max(c_u_max, u);
        c_v_min = std::min(c_v_min, v);
        c_v_max = std::max(c_v_max, v);
      }
      if (in_front && !cells.AnyMarked(c_u_min, c_v_min, c_u_max, c_v_max)) continue;
      const int count = cluster.end - cluster.begin;
      cells.SplatFacing(g.p, g.depth_row, d, margin, &vx[cluster.begin], &vy[cluster.begin],
                        &vz[cluster.begin], &vnx[cluster.begin], &vny[cluster.begin],
                        &vnz[cluster.begin], count, &splat_cell, &splat_depth);
    }
    auto visible = [&](const Eigen::Vector3f& x, const Pending& p) {
      const float tan_angle =
          std::min(max_tan, std::sqrt(std::max(0.0f, 1.0f - p.cos_angle * p.cos_angle)) /
                                std::max(p.cos_angle, 1e-3f));
      const float tolerance = 2.0f * mean_edge_mm + 4.0f * cell_mm * tan_angle;
      return g.Depth(x) <= cells.At(p.u, p.v) + tolerance;
    };
    for (const Pending& p : pending_faces) {
      if (!visible(centroid[p.index], p)) continue;
      face_cos[static_cast<std::size_t>(p.index) * kCandidates + p.slot] = p.cos_angle;
    }
    for (const VertexPending& p : pending_vertices) {
      if (!(p.depth <= cells.At(p.u, p.v) + p.tolerance)) continue;
      color_sum[p.index] += p.weight * SampleBilinearWithOne(image, p.u, p.v);
    }
  }

  if (options.vertex_colors) {
    mesh->colors.assign(nv, kUnseenColor);
    for (int vi = 0; vi < nv; ++vi) {
      const float weight = color_sum[vi][3];
      if (weight <= 0.0f) {
        ++stats.unseen_vertices;
        continue;
      }
      const Float4 bgr = color_sum[vi] / weight;
      auto byte = [](float x) {
        return static_cast<std::uint8_t>(std::clamp(std::lround(x), 0L, 255L));
      };
      mesh->colors[vi] = Color(byte(bgr[2]), byte(bgr[1]), byte(bgr[0]));
    }
  }
  if (!options.atlas) {
    return stats;
  }

  // Labels: the best visible candidate, then smoothed.
  std::vector<int> label(nf, -1);
  for (int i = 0; i < nf; ++i) {
    float best = -2.0f;
    for (int s = 0; s < kCandidates; ++s) {
      const float c = face_cos[static_cast<std::size_t>(i) * kCandidates + s];
      if (c > best) {
        best = c;
        label[i] = face_candidates[i].view[s];
      }
    }
  }
  // Iterated conditional modes: each face takes the visible candidate maximising its cosine plus
  // kNeighbourBonus per edge-neighbour with the same view, so the small islands and ragged
  // borders that nearly equal views leave behind merge into their surroundings.
  {
    std::vector<int> next(nf);
    for (int pass = 0; pass < kSmoothingPasses; ++pass) {
      for (int i = 0; i < nf; ++i) {
        next[i] = label[i];
        float best = -std::numeric_limits<float>::infinity();
        for (int s = 0; s < kCandidates; ++s) {
          const float c = face_cos[static_cast<std::size_t>(i) * kCandidates + s];
          if (c <= -2.0f) continue;
          const int view = face_candidates[i].view[s];
          float score = c;
          for (int nb : neighbours[i]) {
            if (nb >= 0 && label[nb] == view) score += kNeighbourBonus;
          }
          if (score > best) {
            best = score;
            next[i] = view;
          }
        }
      }
      label.swap(next);
    }
  }

  // Charts: connected faces with the same view.
  UnionFind sets(nf);
  for (int i = 0; i < nf; ++i) {
    for (int nb : neighbours[i]) {
      if (nb >= 0 && label[nb] == label[i] && label[i] >= 0) sets.Unite(i, nb);
    }
  }
  std::vector<int> chart_of(nf, -1);
  std::vector<int> chart_view;
  for (int i = 0; i < nf; ++i) {
    if (label[i] < 0) {
      ++stats.unseen_faces;
      continue;
    }
    const int root = sets.Find(i);
    if (chart_of[root] < 0) {
      chart_of[root] = static_cast<int>(chart_view.size());
      chart_view.push_back(label[i]);
    }
    chart_of[i] = chart_of[root];
  }
  const int charts = static_cast<int>(chart_view.size());
  stats.charts = charts;
  // Faces grouped by chart (counting sort); the unseen faces last.
  std::vector<int> chart_start(charts + 2, 0);
  for (int i = 0; i < nf; ++i) ++chart_start[(chart_of[i] < 0 ? charts : chart_of[i]) + 1];
  std::partial_sum(chart_start.begin(), chart_start.end(), chart_start.begin());
  std::vector<int> faces_by_chart(nf);
  {
    std::vector<int> fill(chart_start.begin(), chart_start.end() - 1);
    for (int i = 0; i < nf; ++i) faces_by_chart[fill[chart_of[i] < 0 ? charts : chart_of[i]]++] = i;
  }

  // Each chart's rectangle in its view (pixel ranges, inclusive, margin included).
  std::vector<Rect> source(charts);
  std::vector<int> chart_stamp(nv, -1);
  std::vector<Eigen::Vector2f> chart_pixel(nv);
  for (int c = 0; c < charts; ++c) {
    const ViewGeometry& g = geometry[chart_view[c]];
    float u0 = std::numeric_limits<float>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
    for (int k = chart_start[c]; k < chart_start[c + 1]; ++k) {
      for (int corner = 0; corner < 3; ++corner) {
        const int vi = mesh->faces[faces_by_chart[k]][corner];
        float u = 0.0f, v = 0.0f;
        if (!g.Project(vertices[vi], &u, &v)) continue;
        u0 = std::min(u0, u);
        u1 = std::max(u1, u);
        v0 = std::min(v0, v);
        v1 = std::max(v1, v);
      }
    }
    Rect r;
    r.x = std::clamp(static_cast<int>(std::floor(u0)) - kChartMarginPx, 0, g.width - 1);
    r.y = std::clamp(static_cast<int>(std::floor(v0)) - kChartMarginPx, 0, g.height - 1);
    const int x1 = std::clamp(static_cast<int>(std::ceil(u1)) + kChartMarginPx, r.x, g.width - 1);
    const int y1 = std::clamp(static_cast<int>(std::ceil(v1)) + kChartMarginPx, r.y, g.height - 1);
    r.w = x1 - r.x + 1;
    r.h = y1 - r.y + 1;
    source[c] = r;
  }

  // Packing: the unseen patch is rectangle `charts`.
  constexpr int kUnseenPatch = 4;
  const int max_side = options.texture_size_px;
  std::vector<Rect> placed;
  std::vector<Rect> sizes(charts + 1);
  double scale = 1.0;
  int atlas_width = 0;
  int atlas_height = 0;
  for (int attempt = 0; attempt < 40 && atlas_width == 0; ++attempt) {
    if (attempt > 0) scale *= 0.85;
    int widest = kUnseenPatch;
    for (int c = 0; c < charts; ++c) {
      sizes[c].w = std::max(1, static_cast<int>(std::ceil(source[c].w * scale)));
      sizes[c].h = std::max(1, static_cast<int>(std::ceil(source[c].h * scale)));
      widest = std::max(widest, sizes[c].w);
    }
    sizes[charts] = Rect{0, 0, kUnseenPatch, kUnseenPatch};
    for (int width = 64; width <= max_side; width *= 2) {
      if (width < widest) continue;
      const int height = PackShelves(sizes, width, &placed);
      if (height > 0 && (height <= width || (width * 2 > max_side && height <= max_side))) {
        atlas_width = width;
        atlas_height = (height + 3) / 4 * 4;
        break;
      }
    }
  }
  if (atlas_width == 0) {
    return MakeError(ErrorCode::kInternal,
                     fmt::format("cannot pack {} charts into a {} px atlas", charts, max_side));
  }
  stats.atlas_scale = scale;

  cv::Mat atlas(atlas_height, atlas_width, CV_8UC3, cv::Scalar(0, 0, 0));
  atlas(cv::Rect(placed[charts].x, placed[charts].y, kUnseenPatch, kUnseenPatch))
      .setTo(cv::Scalar(kUnseenColor[2], kUnseenColor[1], kUnseenColor[0]));
  for (int c = 0; c < charts; ++c) {
    const Rect& s = source[c];
    const Rect& d = placed[c];
    const cv::Mat from = images[chart_view[c]](cv::Rect(s.x, s.y, s.w, s.h));
    cv::Mat to = atlas(cv::Rect(d.x, d.y, d.w, d.h));
    if (s.w == d.w && s.h == d.h) {
      from.copyTo(to);
    } else {
      cv::resize(from, to, to.size(), 0, 0, cv::INTER_AREA);
    }
  }

  // uvs: one per (chart, vertex), plus the unseen patch's centre.
  std::vector<Eigen::Vector2f> uvs;
  std::vector<Eigen::Vector3i> uv_faces(nf);
  uvs.reserve(nv + nv / 4);
  const float inv_w = 1.0f / atlas_width;
  const float inv_h = 1.0f / atlas_height;
  std::vector<int> uv_of(nv, -1);
  for (int c = 0; c < charts; ++c) {
    const ViewGeometry& g = geometry[chart_view[c]];
    const Rect& s = source[c];
    const Rect& d = placed[c];
    const float sx = static_cast<float>(d.w) / s.w;
    const float sy = static_cast<float>(d.h) / s.h;
    for (int k = chart_start[c]; k < chart_start[c + 1]; ++k) {
      const int fi = faces_by_chart[k];
      for (int corner = 0; corner < 3; ++corner) {
        const int vi = mesh->faces[fi][corner];
        if (chart_stamp[vi] != c) {
          chart_stamp[vi] = c;
          float u = 0.0f, v = 0.0f;
          if (!g.Project(vertices[vi], &u, &v)) {
            u = static_cast<float>(s.x);
            v = static_cast<float>(s.y);
          }
          // Image pixel centre u sits at texel coordinate d.x + (u - s.x + 0.5) * sx - 0.5.
          const float tx = d.x + (u - s.x + 0.5f) * sx;
          const float ty = d.y + (v - s.y + 0.5f) * sy;
          uv_of[vi] = static_cast<int>(uvs.size());
          uvs.emplace_back(std::clamp(tx * inv_w, 0.0f, 1.0f), std::clamp(ty * inv_h, 0.0f, 1.0f));
        }
        uv_faces[fi][corner] = uv_of[vi];
      }
    }
  }
  if (chart_start[charts + 1] > chart_start[charts]) {
    const int unseen_uv = static_cast<int>(uvs.size());
    uvs.emplace_back((placed[charts].x + 0.5f * kUnseenPatch) * inv_w,
                     (placed[charts].y + 0.5f * kUnseenPatch) * inv_h);
    for (int k = chart_start[charts]; k < chart_start[charts + 1]; ++k) {
      uv_faces[faces_by_chart[k]] = Eigen::Vector3i::Constant(unseen_uv);
    }
  }
  mesh->uvs = std::move(uvs);
  mesh->uv_faces = std::move(uv_faces);
  mesh->texture = atlas;
  return stats;
}

MeshRendering RenderMesh(const Mesh& mesh, const View& view) {
  MeshRendering out;
  out.image = cv::Mat(view.height_px, view.width_px, CV_8UC3, cv::Scalar(0, 0, 0));
  out.coverage = cv::Mat(view.height_px, view.width_px, CV_8UC1, cv::Scalar(0));
  const ViewGeometry g(view);
  const bool textured = mesh.HasTexture();
  const bool colors = mesh.HasColors();
  // Nearest first: q = 1 / w (pinhole) or -depth (affine), linear in the image.
  cv::Mat nearest(view.height_px, view.width_px, CV_32F,
                  cv::Scalar(-std::numeric_limits<float>::infinity()));
  const Eigen::Matrix<double, 3, 4> p = view.pixel_from_object;
  for (std::size_t fi = 0; fi < mesh.faces.size(); ++fi) {
    const Eigen::Vector3i& f = mesh.faces[fi];
    Eigen::Vector3d x[3], h[3];
    double q[3];
    bool in_front = true;
    for (int c = 0; c < 3; ++c) {
      x[c] = mesh.vertices[f[c]].cast<double>();
      h[c] = p.leftCols<3>() * x[c] + p.col(3);
      in_front = in_front && h[c].z() > 0.0;
    }
    if (!in_front) continue;
    const Eigen::Vector3d n = (x[1] - x[0]).cross(x[2] - x[0]);
    const Eigen::Vector3d centre = (x[0] + x[1] + x[2]) / 3.0;
    if (!(n.dot(view.DirectionToCamera(centre)) > 0.0)) continue;
    double u[3], v[3];
    for (int c = 0; c < 3; ++c) {
      u[c] = h[c].x() / h[c].z();
      v[c] = h[c].y() / h[c].z();
      q[c] = g.affine ? -static_cast<double>(g.Depth(mesh.vertices[f[c]])) : 1.0 / h[c].z();
    }
    const double area = (u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0]);
    if (area == 0.0) continue;
    const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({u[0], u[1], u[2]}))));
    const int x1 =
        std::min(view.width_px - 1, static_cast<int>(std::floor(std::max({u[0], u[1], u[2]}))));
    const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({v[0], v[1], v[2]}))));
    const int y1 =
        std::min(view.height_px - 1, static_cast<int>(std::floor(std::max({v[0], v[1], v[2]}))));
    for (int py = y0; py <= y1; ++py) {
      float* near_row = nearest.ptr<float>(py);
      for (int px = x0; px <= x1; ++px) {
        double l[3];
        for (int c = 0; c < 3; ++c) {
          const int a = (c + 1) % 3;
          const int b = (c + 2) % 3;
          l[c] = ((u[b] - u[a]) * (py - v[a]) - (px - u[a]) * (v[b] - v[a])) / area;
        }
        if (l[0] < 0.0 || l[1] < 0.0 || l[2] < 0.0) continue;
        const double depth_q = l[0] * q[0] + l[1] * q[1] + l[2] * q[2];
        if (!(depth_q > near_row[px])) continue;
        near_row[px] = static_cast<float>(depth_q);
        // Perspective-correct weights.
        double w[3];
        for (int c = 0; c < 3; ++c) w[c] = g.affine ? l[c] : l[c] * q[c];
        const double sum = w[0] + w[1] + w[2];
        for (double& wc : w) wc /= sum;
        Eigen::Vector3f bgr(160.0f, 160.0f, 160.0f);
        if (textured) {
          Eigen::Vector2d uv = Eigen::Vector2d::Zero();
          for (int c = 0; c < 3; ++c) uv += w[c] * mesh.uvs[mesh.uv_faces[fi][c]].cast<double>();
          bgr = SampleBilinear(mesh.texture, static_cast<float>(uv.x() * mesh.texture.cols - 0.5),
                               static_cast<float>(uv.y() * mesh.texture.rows - 0.5));
        } else if (colors) {
          Eigen::Vector3f rgb = Eigen::Vector3f::Zero();
          for (int c = 0; c < 3; ++c)
            rgb += static_cast<float>(w[c]) * mesh.colors[f[c]].cast<float>();
          bgr = Eigen::Vector3f(rgb[2], rgb[1], rgb[0]);
        }
        cv::Vec3b& pixel = out.image.at<cv::Vec3b>(py, px);
        for (int k = 0; k < 3; ++k) {
          pixel[k] = static_cast<std::uint8_t>(std::clamp(std::lround(bgr[k]), 0L, 255L));
        }
        out.coverage.at<std::uint8_t>(py, px) = 255;
      }
    }
  }
  return out;
}

}  // namespace revolve::reconstruct
