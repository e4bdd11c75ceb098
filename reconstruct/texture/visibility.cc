#include <algorithm>
#include <bit>
#include <limits>
#include <span>

#include <tbb/enumerable_thread_specific.h>

#include "reconstruct/parallel.h"
#include "reconstruct/texture/texture_internal.h"

namespace revolve::reconstruct::texture_internal {
namespace {

// Makes *v at least n long (scratch kept across views: growing only, so that it is not zeroed
// again each time).
template <typename T>
void GrowTo(std::vector<T>* v, std::size_t n) {
  if (v->size() < n) v->resize(n);
}

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
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
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
    GrowTo(index, static_cast<std::size_t>(count));
    GrowTo(depth, static_cast<std::size_t>(count));
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

// How far ahead of a gather its records are fetched (__builtin_prefetch).
constexpr int kGatherAhead = 16;

// A vertex's sample from a view, weighted (b, g, r, weight).
struct VertexSample {
  int index;
  Float4 value;
};

// The sweep over the views; one SeeView() per view with an image, its scratch kept across views.
class ViewSweep {
 public:
  // `seen`: where the faces' cosines are recorded (each face slot belongs to one view, so views
  // seen at once write apart).
  ViewSweep(const SweepInputs& in, Sightings* seen)
      : in_(in), vertices_(in.mesh.vertices), seen_(*seen) {}

  // View k's sightings: the faces' cosines recorded, the vertices' weighted samples in
  // *samples (in the order they are to be added).
  void SeeView(int k, std::vector<VertexSample>* samples) {
    samples->clear();
    const ViewGeometry& g = in_.geometry[k];
    const float mm_per_px = MmPerPx(g, in_.ranking.Direction(k));
    const int cell_px =
        std::clamp(static_cast<int>(std::ceil(1.5f * in_.surface.mean_edge_mm / mm_per_px)), 1, 16);
    const float cell_mm = cell_px * mm_per_px;
    Window window;
    PendVertices(k, g, cell_mm, &window);
    PendFaces(k, g, cell_mm, &window);
    if (face_count_ == 0 && vertex_count_ == 0) return;
    DepthCells cells(g.width, g.height, cell_px, window.u_min, window.v_min, window.u_max,
                     window.v_max);
    for (const Pending& p : PendingFaces()) cells.Mark(p.u, p.v);
    for (const VertexPending& p : PendingVertices()) cells.Mark(p.u, p.v);
    cells.EndMarks();
    Splat(k, g, &cells);
    Record(k, cells, samples);
  }

 private:
  struct Pending {  // a candidate face to test in a view, with its centroid's PointTerms
    int index;
    int slot;    // the face's candidate slot
    float u, v;  // its pixel
    float cos_angle;
    float depth, tolerance;
  };
  struct VertexPending {  // a candidate vertex to test in a view, with its PointTerms
    int index;
    float u, v;
    float depth, tolerance, weight;
  };

  // Millimetres per pixel at the mesh's centre, across the direction to the camera d (1 when
  // it does not project).
  float MmPerPx(const ViewGeometry& g, const Eigen::Vector3f& d) const {
    float mm_per_px = 1.0f;
    float u0, v0, u1, v1;
    if (g.Project(in_.surface.centre, &u0, &v0) &&
        g.Project(in_.surface.centre + d.unitOrthogonal(), &u1, &v1)) {
      mm_per_px = 1.0f / std::max(1e-6f, std::hypot(u1 - u0, v1 - v0));
    }
    return mm_per_px;
  }

  // pending_vertices_: the vertices view k may colour (ranked for it, facing it within
  // max_angle_deg, in its image) with their PointTerms; their pixels added to *window.
  void PendVertices(int k, const ViewGeometry& g, float cell_mm, Window* window) {
    vertex_count_ = 0;
    const int first = in_.vertices.start[k];
    const int count = in_.vertices.start[k + 1] - first;
    for (auto* scratch : {&cx_, &cy_, &cz_, &cnx_, &cny_, &cnz_, &c_cos_, &c_u_, &c_v_, &c_depth_,
                          &c_tolerance_, &c_weight_}) {
      GrowTo(scratch, static_cast<std::size_t>(count));
    }
    GrowTo(&c_front_, static_cast<std::size_t>(count));
    const std::vector<Eigen::Vector3f>& vertex_normal = in_.surface.vertex_normal;
    const int* entries = &in_.vertices.entries[first];
    for (int j = 0; j < count; ++j) {
      if (j + kGatherAhead < count) {
        __builtin_prefetch(&vertices_[entries[j + kGatherAhead]]);
        __builtin_prefetch(&vertex_normal[entries[j + kGatherAhead]]);
      }
      const int vi = entries[j];
      cx_[j] = vertices_[vi].x();
      cy_[j] = vertices_[vi].y();
      cz_[j] = vertices_[vi].z();
      cnx_[j] = vertex_normal[vi].x();
      cny_[j] = vertex_normal[vi].y();
      cnz_[j] = vertex_normal[vi].z();
    }
    ComputePointTerms(
        g, in_.max_tan, 2.0f * in_.surface.mean_edge_mm, 4.0f * cell_mm, count,
        PointTerms{cx_.data(), cy_.data(), cz_.data(), cnx_.data(), cny_.data(), cnz_.data(),
                   c_cos_.data(), c_u_.data(), c_v_.data(), c_depth_.data(), c_tolerance_.data(),
                   c_weight_.data(), c_front_.data()});
    GrowTo(&pending_vertices_, static_cast<std::size_t>(count));
    int kept = 0;
    for (int j = 0; j < count; ++j) {
      if (c_cos_[j] < in_.cos_min || !c_front_[j] || !g.InImage(c_u_[j], c_v_[j])) continue;
      pending_vertices_[kept++] = VertexPending{in_.vertices.entries[first + j],
                                                c_u_[j],
                                                c_v_[j],
                                                c_depth_[j],
                                                c_tolerance_[j],
                                                c_weight_[j]};
      window->Add(c_u_[j], c_v_[j]);
    }
    vertex_count_ = kept;
  }

  // pending_faces_: the same for the faces view k may texture (their centroids, with the
  // smoothed normal's PointTerms; a face whose own normal does not face the camera is left out).
  // Gathered, then computed in the vectorised loops as the vertices are.
  void PendFaces(int k, const ViewGeometry& g, float cell_mm, Window* window) {
    face_count_ = 0;
    const Surface& s = in_.surface;
    const int first = in_.faces.start[k];
    const int count = in_.faces.start[k + 1] - first;
    for (auto* scratch : {&cx_, &cy_, &cz_, &cnx_, &cny_, &cnz_, &c_cos_, &c_u_, &c_v_, &c_depth_,
                          &c_tolerance_, &c_weight_, &cfx_, &cfy_, &cfz_, &c_own_cos_}) {
      GrowTo(scratch, static_cast<std::size_t>(count));
    }
    GrowTo(&c_front_, static_cast<std::size_t>(count));
    // The records are gathered from all over the mesh (a view's candidates are about one face
    // in twelve): each is fetched ahead, so that the loads overlap.
    const std::int64_t* entries = &in_.faces.entries[first];
    for (int j = 0; j < count; ++j) {
      if (j + kGatherAhead < count) {
        const char* ahead = reinterpret_cast<const char*>(
            &s.face_point[static_cast<std::size_t>(entries[j + kGatherAhead] / kCandidates)]);
        __builtin_prefetch(ahead);
        __builtin_prefetch(ahead + sizeof(Surface::FacePoint) - 1);
      }
      const Surface::FacePoint& f =
          s.face_point[static_cast<std::size_t>(entries[j] / kCandidates)];
      cx_[j] = f.x;
      cy_[j] = f.y;
      cz_[j] = f.z;
      cnx_[j] = f.sx;
      cny_[j] = f.sy;
      cnz_[j] = f.sz;
      cfx_[j] = f.fx;
      cfy_[j] = f.fy;
      cfz_[j] = f.fz;
    }
    ComputePointTerms(
        g, in_.max_tan, 2.0f * s.mean_edge_mm, 4.0f * cell_mm, count,
        PointTerms{cx_.data(), cy_.data(), cz_.data(), cnx_.data(), cny_.data(), cnz_.data(),
                   c_cos_.data(), c_u_.data(), c_v_.data(), c_depth_.data(), c_tolerance_.data(),
                   c_weight_.data(), c_front_.data()});
    if (g.affine) {
      CosinesToDirection(g.direction, count, cfx_.data(), cfy_.data(), cfz_.data(),
                         c_own_cos_.data());
    } else {
      CosinesToCentre(g.centre, count, cx_.data(), cy_.data(), cz_.data(), cfx_.data(), cfy_.data(),
                      cfz_.data(), c_own_cos_.data());
    }
    GrowTo(&pending_faces_, static_cast<std::size_t>(count));
    int kept = 0;
    for (int j = 0; j < count; ++j) {
      if (c_own_cos_[j] <= 0.0f) continue;
      if (c_cos_[j] < in_.cos_min || !c_front_[j] || !g.InImage(c_u_[j], c_v_[j])) continue;
      const std::int64_t entry = in_.faces.entries[first + j];
      pending_faces_[kept++] = Pending{static_cast<int>(entry / kCandidates),
                                       static_cast<int>(entry % kCandidates),
                                       c_u_[j],
                                       c_v_[j],
                                       c_cos_[j],
                                       c_depth_[j],
                                       c_tolerance_[j]};
      window->Add(c_u_[j], c_v_[j]);
    }
    face_count_ = kept;
  }

  // Every vertex facing view k's camera (within the margin) and in front of it is splatted into
  // the cells the candidates read; a cluster whose normals all face away, or whose box projects
  // away from every such cell, holds none that lands in one.
  void Splat(int k, const ViewGeometry& g, DepthCells* cells) {
    const Eigen::Vector3f& d = in_.ranking.Direction(k);
    const float margin = in_.ranking.Margin(k);
    const float facing_limit = std::acos(std::clamp(-margin, -1.0f, 1.0f)) + 1e-3f;
    const VertexClusters& vc = in_.clusters;
    for (const Cluster& cluster : vc.clusters) {
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
      if (in_front && !cells->AnyMarked(c_u_min, c_v_min, c_u_max, c_v_max)) continue;
      const int count = cluster.end - cluster.begin;
      const int b = cluster.begin;
      cells->SplatFacing(g.p, g.depth_row, d, margin, &vc.x[b], &vc.y[b], &vc.z[b], &vc.nx[b],
                         &vc.ny[b], &vc.nz[b], count, &splat_cell_, &splat_depth_);
    }
  }

  // The pending faces and vertices view k sees (not behind their cell's depth by more than
  // their tolerance): a face's cosine recorded in its slot, a vertex's weighted sample added.
  void Record(int k, const DepthCells& cells, std::vector<VertexSample>* samples) {
    for (const Pending& p : PendingFaces()) {
      if (!(p.depth <= cells.At(p.u, p.v) + p.tolerance)) continue;
      seen_.face_cos[static_cast<std::size_t>(p.index) * kCandidates + p.slot] = p.cos_angle;
    }
    const cv::Mat& image = in_.images[k];
    // Frame coordinates less the window's origin: exact (an integer off a float no smaller).
    const auto ox = static_cast<float>(in_.origins[k].x);
    const auto oy = static_cast<float>(in_.origins[k].y);
    samples->reserve(static_cast<std::size_t>(vertex_count_));
    for (const VertexPending& p : PendingVertices()) {
      if (!(p.depth <= cells.At(p.u, p.v) + p.tolerance)) continue;
      samples->push_back(
          VertexSample{p.index, p.weight * SampleBilinearWithOne(image, p.u - ox, p.v - oy)});
    }
  }

  const SweepInputs& in_;
  const std::vector<Eigen::Vector3f>& vertices_;
  Sightings& seen_;
  // Scratch for a view's candidate vertices: positions and normals, then their PointTerms.
  std::vector<float> cx_, cy_, cz_, cnx_, cny_, cnz_, c_cos_, c_u_, c_v_, c_depth_, c_tolerance_,
      c_weight_;
  // A view's candidate faces' own (unsmoothed) normals and their cosines to the camera.
  std::vector<float> cfx_, cfy_, cfz_, c_own_cos_;
  std::vector<int> c_front_;
  std::vector<int> splat_cell_;  // scratch for the splats
  std::vector<float> splat_depth_;
  // The view's pending faces and vertices: the first face_count_ and vertex_count_ (the
  // arrays only grow).
  std::span<const Pending> PendingFaces() const {
    return {pending_faces_.data(), static_cast<std::size_t>(face_count_)};
  }
  std::span<const VertexPending> PendingVertices() const {
    return {pending_vertices_.data(), static_cast<std::size_t>(vertex_count_)};
  }
  std::vector<Pending> pending_faces_;
  std::vector<VertexPending> pending_vertices_;
  int face_count_ = 0;
  int vertex_count_ = 0;
};

}  // namespace

Sightings SweepViews(const SweepInputs& in) {
  Sightings seen;
  seen.face_cos.assign(in.atlas ? in.mesh.faces.size() * kCandidates : 0, -2.0f);  // -2: unseen
  seen.color_sum.assign(in.vertex_colors ? in.mesh.vertices.size() : 0,
                        Float4{0.0f, 0.0f, 0.0f, 0.0f});
  std::vector<int> views;
  for (int k = 0; k < static_cast<int>(in.geometry.size()); ++k) {
    if (!in.images[k].empty()) views.push_back(k);
  }
  seen.views_used = static_cast<int>(views.size());
  // The views on all cores, each sweep's scratch kept across the views of its thread; the
  // vertices' samples are added afterwards in view order, so the sums do not depend on it.
  std::vector<std::vector<VertexSample>> samples(views.size());
  tbb::enumerable_thread_specific<ViewSweep> sweeps([&] { return ViewSweep(in, &seen); });
  ParallelFor(0, views.size(),
              [&](std::size_t i) { sweeps.local().SeeView(views[i], &samples[i]); });
  // Each view's samples are in vertex order, so a range of vertices finds its samples in every
  // view's list by bisection: the ranges on all cores, each vertex's sum in view order.
  if (in.vertex_colors) {
    ParallelChunks(0, seen.color_sum.size(), 16384, [&](std::size_t lo, std::size_t hi) {
      for (const std::vector<VertexSample>& view_samples : samples) {
        auto it = std::lower_bound(view_samples.begin(), view_samples.end(), lo,
                                   [](const VertexSample& sample, std::size_t v) {
                                     return sample.index < static_cast<int>(v);
                                   });
        for (; it != view_samples.end() && it->index < static_cast<int>(hi); ++it) {
          seen.color_sum[it->index] += it->value;
        }
      }
    });
  }
  return seen;
}

}  // namespace revolve::reconstruct::texture_internal
