// VisualHull::PlaceOnEdges: the sub-voxel crossing of every cut edge, all edges of a block and
// view at a time (packed silhouettes, step bounds, walks along the segments).
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
#include <tbb/enumerable_thread_specific.h>
#include <opencv2/imgproc.hpp>

#include "reconstruct/hull/hull_internal.h"
#include "reconstruct/hull/marching_cubes.h"
#include "reconstruct/parallel.h"

namespace revolve::reconstruct {

using namespace hull_internal;  // NOLINT(google-build-using-namespace): this library's own parts

namespace {

// Blocks of 16 voxels per task of the placement (a few hundred edges each).
constexpr std::size_t kBlocksPerTask = 4;

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
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
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

// The edges of one PlaceOnEdges laid out for its per-view passes, and those passes. Each edge
// with the part of it that can hold the crossing (all of it, or up to the grid's face for an
// edge leaving the grid, or up to the clip plane), grouped by its inside sample, the samples
// sorted by block of 16 voxels, brick, then voxel. Per view, a block the view cannot act on (its
// box grown by one voxel contains every segment of its edges) is skipped; in the others, a
// sample whose neighbourhood (as far as its segments can move in the image) is all on the
// silhouette skips its edges, then an edge whose end pixels' rectangle is all on the
// silhouette; the rest are walked.
class VisualHull::EdgePlacer {
 public:
  // Points as structure of arrays (a sample's or a brick's centre).
  struct Points {
    std::vector<double> x, y, z;
    void Add(const Eigen::Vector3d& c) {
      x.push_back(c.x());
      y.push_back(c.y());
      z.push_back(c.z());
    }
  };
  // Per block and view, one per thread: the bricks' projections, then the samples of the
  // bricks the view may act on (gathered), their projections, and the samples to walk.
  struct Scratch {
    std::vector<double> brick_hx_, brick_hy_, brick_w_, brick_u_, brick_v_;
    Points gathered_;
    std::vector<std::uint32_t> gathered_sample_;
    std::vector<double> sample_hx_, sample_hy_, sample_w_, sample_u_, sample_v_;
    std::vector<std::uint32_t> walk_;
    // Rectangles of pixels to test together (AllOnEach): the samples', then the items'.
    std::vector<int> rect_u0_, rect_v0_, rect_u1_, rect_v1_;
    std::vector<std::uint8_t> rect_on_;
    // The items of the samples to walk: item, sample (gathered), the part of the segment that
    // can matter, and its end (P * [X; 1]; then the nearest pixel).
    std::vector<std::uint32_t> walk_item_, walk_sample_;
    std::vector<double> walk_t_, end_x_, end_y_, end_w_;
    std::vector<int> end_u_, end_v_;
  };

  EdgePlacer(const VisualHull& hull, const std::vector<GridEdge>& edges,
             std::optional<double> clip_below_z_mm)
      : hull_(hull),
        n_(edges.size()),
        block_dims_((hull.brick_dims_ + Eigen::Vector3i::Constant(3)) / 4) {
    SortByBlock(edges);
    LayOut(clip_below_z_mm);
    AllocateScratch();
  }

  // Each edge's crossing moved to where `view` cuts it first, when that is sooner. The blocks
  // are spread over the cores: each writes only its own items' and samples' t, and goes through
  // the views in the same order whatever the threads, so the result is the same.
  void PlaceInView(const ViewData& view, bool cull_views,
                   tbb::enumerable_thread_specific<Scratch>& scratch) {
    const PackedMask packed(view.roi, view.packed_words, view.packed.data());
    // P * d for the six steps (axis, sign), as FirstExit computes it.
    const Matrix34d& p = view.pixel_from_object;
    double step_h[3][2][3];
    for (int axis = 0; axis < 3; ++axis) {
      for (int s = 0; s < 2; ++s) {
        Eigen::Vector3d d = Eigen::Vector3d::Zero();
        d[axis] = (s == 0 ? -1 : 1) * hull_.grid_.voxel_mm;
        for (int r = 0; r < 3; ++r) {
          step_h[axis][s][r] = p(r, 0) * d.x() + p(r, 1) * d.y() + p(r, 2) * d.z();
        }
      }
    }
    ParallelChunks(0, blocks_.size(), kBlocksPerTask, [&](std::size_t lo, std::size_t hi) {
      Scratch& sc = scratch.local();
      for (std::size_t b = lo; b < hi; ++b) {
        const Block& block = blocks_[b];
        Reach reach;
        if (cull_views && !ReachOfBlock(view, packed, block, &reach)) continue;
        const std::size_t count = GatherSamples(sc, view, packed, block, reach, cull_views);
        const std::size_t walks = SamplesToWalk(sc, view, packed, reach, count);
        const std::size_t m = ItemsToWalk(sc, view, packed, step_h, walks);
        WalkItems(sc, view, step_h, m);
      }
    });
  }

  // Per edge (in the order of `edges`): the t of its crossing. No view cuts the segment: its end
  // (the grid's face, the plane, or rounding for an edge inside the grid, whose outside sample
  // some view carved).
  std::vector<double> Result() const {
    std::vector<double> t(n_);
    for (std::size_t k = 0; k < n_; ++k) t[items_[k].edge] = std::min(t_item_[k], items_[k].t_max);
    return t;
  }

 private:
  struct Item {
    double t_max;
    std::uint32_t edge;
    std::int8_t axis;
    std::int8_t sign;
  };
  struct Sample {  // an inside sample and its edges, items[first, first + count)
    std::uint8_t count;
    std::uint8_t axes;  // bit a: an edge along axis a
    std::uint32_t first;
  };
  struct Block {
    std::size_t begin, end;  // bricks
    Eigen::Vector3d corners[8];
  };
  // How far the segments of a block can move in a view's image (px): per set of axes (bit a:
  // axis a) for a sample's segments of one voxel, and per voxel along each axis for a brick's.
  // Infinite (NaN when multiplied by 0) where part of the block is behind the camera, or without
  // culling: then nothing is left out.
  struct Reach {
    double u[8], v[8];
    StepBound bound{};
    Reach() {
      std::fill(std::begin(u), std::end(u), std::numeric_limits<double>::infinity());
      std::fill(std::begin(v), std::end(v), std::numeric_limits<double>::infinity());
    }
  };

  std::uint32_t BlockOf(const Eigen::Vector3i& voxel) const {
    const Eigen::Vector3i block = voxel / (4 * kBrick);
    return static_cast<std::uint32_t>(
        (std::int64_t{block.z()} * block_dims_.y() + block.y()) * block_dims_.x() + block.x());
  }
  // A voxel's place in its block: brick within the block (bits 6-11), voxel within the brick.
  static std::uint64_t LocalKey(const Eigen::Vector3i& voxel) {
    const Eigen::Vector3i brick = voxel / kBrick;
    const Eigen::Vector3i local = brick - 4 * (brick / 4);
    const Eigen::Vector3i in_brick = voxel - kBrick * brick;
    return static_cast<std::uint64_t>(local.x() | local.y() << 2 | local.z() << 4) << 6 |
           static_cast<std::uint64_t>(in_brick.x() | in_brick.y() << 2 | in_brick.z() << 4);
  }

  // order_: the edges as (what the placement needs of the edge << 44 | local key << 32 | edge
  // index), grouped by block (a counting sort; block b's are [start_[b], start_[b + 1])), then
  // sorted by local key within each block (a few hundred edges). What it needs: the axis (bits
  // 0-1), whether the step is positive (bit 2) and whether the edge leaves the grid (bit 3).
  void SortByBlock(const std::vector<GridEdge>& edges) {
    // A counting sort on all cores, in fixed chunks of edges: each chunk counts its edges per
    // block, then writes them where the chunks before it end (stable, as one pass would be).
    constexpr std::size_t kEdgesPerChunk = 32768;
    const std::size_t blocks = static_cast<std::size_t>(block_dims_.prod());
    const std::size_t chunks = (n_ + kEdgesPerChunk - 1) / kEdgesPerChunk;
    std::vector<std::uint32_t> block_of(n_);
    std::vector<std::size_t> counts(chunks * blocks, 0);  // chunk-major
    ParallelFor(0, chunks, [&](std::size_t chunk) {
      std::size_t* own = &counts[chunk * blocks];
      for (std::size_t e = chunk * kEdgesPerChunk; e < std::min(n_, (chunk + 1) * kEdgesPerChunk);
           ++e) {
        block_of[e] = BlockOf(edges[e].inside.cwiseMax(0));
        ++own[block_of[e]];
      }
    });
    start_.assign(blocks + 1, 0);
    std::size_t next = 0;
    for (std::size_t b = 0; b < blocks; ++b) {
      start_[b] = next;
      for (std::size_t chunk = 0; chunk < chunks; ++chunk) {
        const std::size_t c = counts[chunk * blocks + b];
        counts[chunk * blocks + b] = next;
        next += c;
      }
    }
    start_[blocks] = next;
    order_ = std::make_unique_for_overwrite<std::uint64_t[]>(n_);
    ParallelFor(0, chunks, [&](std::size_t chunk) {
      std::size_t* fill = &counts[chunk * blocks];
      for (std::size_t e = chunk * kEdgesPerChunk; e < std::min(n_, (chunk + 1) * kEdgesPerChunk);
           ++e) {
        const GridEdge& edge = edges[e];
        const Eigen::Vector3i voxel = edge.inside.cwiseMax(0);
        const Eigen::Vector3i step = edge.outside - edge.inside;
        const int axis = step.x() != 0 ? 0 : (step.y() != 0 ? 1 : 2);
        const bool leaves =
            ((edge.outside.array() < 0) || (edge.outside.array() >= hull_.grid_.dims.array()))
                .any();
        const std::uint64_t need = static_cast<std::uint64_t>(axis) |
                                   static_cast<std::uint64_t>(step[axis] > 0) << 2 |
                                   static_cast<std::uint64_t>(leaves) << 3;
        order_[fill[block_of[e]]++] = (need << 12 | LocalKey(voxel)) << 32 | e;
      }
    });
    // Within a block: a radix sort on the local key, 6 bits at a time (stable: the edges of a
    // sample stay in the order of their indices).
    // The blocks on all cores (each sorts its own range), a scratch per thread.
    std::size_t most = 0;
    for (std::size_t b = 0; b + 1 < start_.size(); ++b) {
      most = std::max(most, start_[b + 1] - start_[b]);
    }
    tbb::enumerable_thread_specific<std::vector<std::uint64_t>> scratch(most);
    ParallelChunks(0, start_.size() - 1, 64, [&](std::size_t lo, std::size_t hi) {
      std::uint64_t* const own = scratch.local().data();
      for (std::size_t b = lo; b < hi; ++b) {
        const std::size_t count = start_[b + 1] - start_[b];
        if (count < 2) continue;
        std::uint64_t* from = &order_[start_[b]];
        std::uint64_t* to = own;
        for (const int shift : {32, 38}) {
          std::array<std::uint32_t, 65> at{};
          for (std::size_t i = 0; i < count; ++i) ++at[((from[i] >> shift) & 63) + 1];
          std::partial_sum(at.begin(), at.end(), at.begin());
          for (std::size_t i = 0; i < count; ++i) to[at[(from[i] >> shift) & 63]++] = from[i];
          std::swap(from, to);
        }
      }
    });
  }

  // From order_: items_ (in its order), samples_ and their centres, bricks (their samples, the
  // middle and half extents of the box of their samples' segments) and blocks_.
  void LayOut(std::optional<double> clip_below_z_mm) {
    // At most one sample, brick and block per edge: room for them, so that the arrays are not
    // moved as they grow (only the pages written are given memory).
    const std::size_t brick_bound =
        std::min(n_, static_cast<std::size_t>(hull_.brick_dims_.prod()));
    items_.reserve(n_);
    samples_.reserve(n_);
    brick_start_.reserve(brick_bound + 1);
    brick_lo_.reserve(brick_bound);
    brick_hi_.reserve(brick_bound);
    blocks_.reserve(std::min(n_, static_cast<std::size_t>(block_dims_.prod())));
    for (auto [points, size] :
         {std::pair{&sample_centre_, n_}, std::pair{&brick_centre_, brick_bound}}) {
      points->x.reserve(size);
      points->y.reserve(size);
      points->z.reserve(size);
    }
    for (std::size_t b = 0; b + 1 < start_.size(); ++b) {
      if (start_[b] != start_[b + 1]) AddBlock(b, clip_below_z_mm);
    }
    brick_start_.push_back(samples_.size());
    // Each brick's middle (mm) and half extents (voxels).
    const VoxelGrid& grid = hull_.grid_;
    brick_half_.resize(brick_lo_.size());
    for (std::size_t b = 0; b < brick_lo_.size(); ++b) {
      brick_centre_.Add(grid.Centre(0, 0, 0) + grid.voxel_mm * 0.5 * (brick_lo_[b] + brick_hi_[b]));
      brick_half_[b] = 0.5 * (brick_hi_[b] - brick_lo_[b]);
    }
  }

  // LayOut's part for block b, which holds edges.
  void AddBlock(std::size_t b, std::optional<double> clip_below_z_mm) {
    const VoxelGrid& grid = hull_.grid_;
    const std::size_t end = start_[b + 1];
    Block& block = blocks_.emplace_back();
    block.begin = brick_start_.size();
    // The block's first voxel.
    const auto index = static_cast<int>(b);
    const Eigen::Vector3i block_voxel =
        4 * kBrick *
        Eigen::Vector3i(index % block_dims_.x(), index / block_dims_.x() % block_dims_.y(),
                        index / (block_dims_.x() * block_dims_.y()));
    {
      // The block's voxel centres grown by one voxel.
      const Eigen::Vector3i lo = block_voxel - Eigen::Vector3i::Ones();
      const Eigen::Vector3i hi = lo + Eigen::Vector3i::Constant(4 * kBrick + 1);
      const Eigen::Vector3d l = grid.Centre(lo.x(), lo.y(), lo.z());
      const Eigen::Vector3d h = grid.Centre(hi.x(), hi.y(), hi.z());
      for (int c = 0; c < 8; ++c) {
        block.corners[c] =
            Eigen::Vector3d(c & 1 ? h.x() : l.x(), c & 2 ? h.y() : l.y(), c & 4 ? h.z() : l.z());
      }
    }
    std::uint64_t brick_key = ~std::uint64_t{0};
    for (std::size_t i = start_[b]; i < end;) {
      const std::uint64_t key = order_[i] >> 32 & 0xFFF;
      const auto local = static_cast<int>(key);
      const Eigen::Vector3i voxel =
          block_voxel + kBrick * Eigen::Vector3i(local >> 6 & 3, local >> 8 & 3, local >> 10 & 3) +
          Eigen::Vector3i(local & 3, local >> 2 & 3, local >> 4 & 3);
      // The sample's edges become items.
      std::size_t j = i;
      std::uint8_t axes = 0;
      for (; j < end && (order_[j] >> 32 & 0xFFF) == key; ++j) {
        const std::uint64_t need = order_[j] >> 44;
        Item& item = items_.emplace_back();
        item.axis = static_cast<std::int8_t>(need & 3);
        item.sign = static_cast<std::int8_t>(need & 4 ? 1 : -1);
        item.edge = static_cast<std::uint32_t>(order_[j]);
        item.t_max = need & 8 ? 0.5 : 1.0;
        if (clip_below_z_mm && item.axis == 2 && item.sign < 0) {
          const double z = grid.Centre(0, 0, voxel.z()).z();
          const double to_plane = (z - *clip_below_z_mm) / grid.voxel_mm;
          if (to_plane >= 0.0 && to_plane < item.t_max) {
            item.t_max = to_plane;
          }
        }
        axes |= 1 << item.axis;
      }
      if ((key >> 6) != brick_key) {
        brick_key = key >> 6;
        brick_start_.push_back(samples_.size());
        brick_lo_.push_back(voxel.cast<double>());
        brick_hi_.push_back(voxel.cast<double>());
        block.end = brick_start_.size();
      }
      // The segments' ends.
      for (std::size_t k = i; k < j; ++k) {
        Eigen::Vector3d tip = voxel.cast<double>();
        tip[items_[k].axis] += items_[k].sign * items_[k].t_max;
        brick_lo_.back() = brick_lo_.back().cwiseMin(tip);
        brick_hi_.back() = brick_hi_.back().cwiseMax(tip);
      }
      samples_.push_back(
          Sample{static_cast<std::uint8_t>(j - i), axes, static_cast<std::uint32_t>(i)});
      sample_centre_.Add(grid.Centre(voxel.x(), voxel.y(), voxel.z()));
      i = j;
    }
  }

  // The sizes of the per-view scratch (the largest block's); each item's t so far (t_max + 1:
  // no cut yet) and each sample's longest part of its edges that can still hold a crossing
  // (voxels).
  void AllocateScratch() {
    for (const Block& block : blocks_) {
      const std::size_t first = brick_start_[block.begin];
      const std::size_t last = brick_start_[block.end];
      largest_block_ = std::max(largest_block_, last - first);
      most_bricks_ = std::max(most_bricks_, block.end - block.begin);
      most_items_ = std::max<std::size_t>(
          most_items_, samples_[last - 1].first + samples_[last - 1].count - samples_[first].first);
    }
    t_item_.resize(n_);
    for (std::size_t k = 0; k < n_; ++k) t_item_[k] = items_[k].t_max + 1.0;
    sample_t_.assign(samples_.size(), 0.0);
    for (std::size_t s = 0; s < samples_.size(); ++s) {
      for (std::size_t k = samples_[s].first; k < samples_[s].first + samples_[s].count; ++k) {
        sample_t_[s] = std::max(sample_t_[s], items_[k].t_max);
      }
    }
  }

 public:
  // A thread's scratch, sized for the largest block.
  Scratch MakeScratch() const {
    Scratch s;
    for (std::vector<double>* a :
         {&s.brick_hx_, &s.brick_hy_, &s.brick_w_, &s.brick_u_, &s.brick_v_}) {
      a->resize(most_bricks_);
    }
    for (std::vector<double>* a : {&s.gathered_.x, &s.gathered_.y, &s.gathered_.z, &s.sample_hx_,
                                   &s.sample_hy_, &s.sample_w_, &s.sample_u_, &s.sample_v_}) {
      a->resize(largest_block_);
    }
    s.gathered_sample_.resize(largest_block_);
    s.walk_.resize(largest_block_);
    const std::size_t most_rects = std::max(largest_block_, most_items_);
    for (std::vector<int>* a : {&s.rect_u0_, &s.rect_v0_, &s.rect_u1_, &s.rect_v1_}) {
      a->resize(most_rects);
    }
    s.rect_on_.resize(most_rects);
    s.walk_item_.resize(most_items_);
    s.walk_sample_.resize(most_items_);
    for (std::vector<double>* a : {&s.walk_t_, &s.end_x_, &s.end_y_, &s.end_w_}) {
      a->resize(most_items_);
    }
    s.end_u_.resize(most_items_);
    s.end_v_.resize(most_items_);
    return s;
  }

 private:
  // With culling: false when `view` cannot act on the block (its box is all on the silhouette or
  // unseen), else *reach for it.
  bool ReachOfBlock(const ViewData& view, const PackedMask& packed, const Block& block,
                    Reach* reach) const {
    const Matrix34d& p = view.pixel_from_object;
    double projected[8][3];
    for (int c = 0; c < 8; ++c) {
      const Homogeneous h = Project(p, block.corners[c]);
      projected[c][0] = h.x;
      projected[c][1] = h.y;
      projected[c][2] = h.w;
    }
    if (packed.AllOnOrUnseen(projected, view.width, view.height)) return false;
    reach->bound = MaxStepPx(p, projected, hull_.grid_.voxel_mm);
    for (int axes = 1; axes < 8; ++axes) {
      double u = 0.0, w = 0.0;
      for (int axis = 0; axis < 3; ++axis) {
        if (axes & (1 << axis)) {
          u = std::max(u, reach->bound.u_px[axis]);
          w = std::max(w, reach->bound.v_px[axis]);
        }
      }
      reach->u[axes] = u;
      reach->v[axes] = w;
    }
    return true;
  }

  // Whether the nearest pixels of [u - reach_u, u + reach_u] x [v - reach_v, v + reach_v]
  // (shifted by half a pixel) are all in the image and on the silhouette.
  [[gnu::always_inline]] static bool AllOnAround(const ViewData& view, const PackedMask& packed,
                                                 double w, double u, double pv, double reach_u,
                                                 double reach_v) {
    const double u_lo = u + 0.5 - reach_u, u_hi = u + 0.5 + reach_u;
    const double v_lo = pv + 0.5 - reach_v, v_hi = pv + 0.5 + reach_v;
    return w > 0.0 && u_lo >= 0.0 && v_lo >= 0.0 && u_hi < view.width && v_hi < view.height &&
           packed.AllOn(static_cast<int>(u_lo), static_cast<int>(v_lo), static_cast<int>(u_hi),
                        static_cast<int>(v_hi));
  }

  // The samples of the block's bricks that `view` may act on (with culling, a brick whose box
  // is all on the silhouette is left out), gathered with their projections; returns how many.
  std::size_t GatherSamples(Scratch& sc, const ViewData& view, const PackedMask& packed,
                            const Block& block, const Reach& reach, bool cull_views) {
    const Matrix34d& p = view.pixel_from_object;
    const StepBound& bound = reach.bound;
    const std::size_t bricks = block.end - block.begin;
    ProjectPoints(p, &brick_centre_.x[block.begin], &brick_centre_.y[block.begin],
                  &brick_centre_.z[block.begin], bricks, sc.brick_hx_.data(), sc.brick_hy_.data(),
                  sc.brick_w_.data(), sc.brick_u_.data(), sc.brick_v_.data());
    std::size_t count = 0;
    for (std::size_t b = 0; b < bricks; ++b) {
      // From the middle to a corner of the box of the brick's segments: three legs along the
      // axes, each inside the block's box, plus a margin for the rounding of the projections
      // (~1e-12 px).
      const Eigen::Vector3d& half = brick_half_[block.begin + b];
      const double brick_reach_u =
          half.x() * bound.u_px[0] + half.y() * bound.u_px[1] + half.z() * bound.u_px[2] + 1e-6;
      const double brick_reach_v =
          half.x() * bound.v_px[0] + half.y() * bound.v_px[1] + half.z() * bound.v_px[2] + 1e-6;
      if (cull_views && AllOnAround(view, packed, sc.brick_w_[b], sc.brick_u_[b], sc.brick_v_[b],
                                    brick_reach_u, brick_reach_v)) {
        continue;
      }
      for (std::size_t s = brick_start_[block.begin + b]; s < brick_start_[block.begin + b + 1];
           ++s) {
        sc.gathered_.x[count] = sample_centre_.x[s];
        sc.gathered_.y[count] = sample_centre_.y[s];
        sc.gathered_.z[count] = sample_centre_.z[s];
        sc.gathered_sample_[count++] = static_cast<std::uint32_t>(s);
      }
    }
    ProjectPoints(p, sc.gathered_.x.data(), sc.gathered_.y.data(), sc.gathered_.z.data(), count,
                  sc.sample_hx_.data(), sc.sample_hy_.data(), sc.sample_w_.data(),
                  sc.sample_u_.data(), sc.sample_v_.data());
    return count;
  }

  // sc.walk_: the gathered samples (of `count`) whose segments may leave the silhouette (those
  // whose segments all stay on it are left out, with no branch on the outcome: it is hard to
  // predict); returns how many.
  std::size_t SamplesToWalk(Scratch& sc, const ViewData& view, const PackedMask& packed,
                            const Reach& reach, std::size_t count) {
    // The rectangles are made first (AllOnAround's; one outside the silhouette's where that is
    // false before any pixel is read), then tested together.
    for (std::size_t g = 0; g < count; ++g) {
      const std::uint32_t s = sc.gathered_sample_[g];
      const std::uint8_t axes = samples_[s].axes;
      // The segments are as long as the part of them that can still hold the crossing.
      const double t = sample_t_[s];
      const double around_u = reach.u[axes] * t + 1e-6, around_v = reach.v[axes] * t + 1e-6;
      const double u_lo = sc.sample_u_[g] + 0.5 - around_u, u_hi = sc.sample_u_[g] + 0.5 + around_u;
      const double v_lo = sc.sample_v_[g] + 0.5 - around_v, v_hi = sc.sample_v_[g] + 0.5 + around_v;
      const bool in_image = sc.sample_w_[g] > 0.0 && u_lo >= 0.0 && v_lo >= 0.0 &&
                            u_hi < view.width && v_hi < view.height;
      sc.rect_u0_[g] = static_cast<int>(in_image ? u_lo : -1.0);
      sc.rect_v0_[g] = static_cast<int>(in_image ? v_lo : -1.0);
      sc.rect_u1_[g] = static_cast<int>(in_image ? u_hi : -1.0);
      sc.rect_v1_[g] = static_cast<int>(in_image ? v_hi : -1.0);
    }
    packed.AllOnEach(sc.rect_u0_.data(), sc.rect_v0_.data(), sc.rect_u1_.data(), sc.rect_v1_.data(),
                     count, sc.rect_on_.data());
    std::size_t walks = 0;
    for (std::size_t g = 0; g < count; ++g) {
      sc.walk_[walks] = static_cast<std::uint32_t>(g);
      walks += sc.rect_on_[g] != 0 ? 0 : 1;
    }
    return walks;
  }

  // The items of the `walks` samples to walk (sc.walk_item_, sc.walk_sample_), with the end of the
  // part of their segment that can matter: only the part before the nearest exit found so far
  // (the walk of the shorter segment visits a prefix of the same cells, the same result where it
  // matters, and its end rectangle is smaller, so it more often ends at once); then FirstExit's
  // first test on them (sc.rect_on_). Returns how many.
  std::size_t ItemsToWalk(Scratch& sc, const ViewData& view, const PackedMask& packed,
                          const double (&step_h)[3][2][3], std::size_t walks) {
    std::size_t m = 0;
    for (std::size_t q = 0; q < walks; ++q) {
      const std::size_t g = sc.walk_[q];
      const Sample& sample = samples_[sc.gathered_sample_[g]];
      double longest = 0.0;
      for (std::size_t k = sample.first; k < sample.first + sample.count; ++k) {
        const Item& item = items_[k];
        const double t_max = std::min(item.t_max, t_item_[k]);
        longest = std::max(longest, t_max);
        const double* hd = step_h[item.axis][item.sign > 0 ? 1 : 0];
        sc.walk_item_[m] = static_cast<std::uint32_t>(k);
        sc.walk_sample_[m] = static_cast<std::uint32_t>(g);
        sc.walk_t_[m] = t_max;
        sc.end_x_[m] = sc.sample_hx_[g] + t_max * hd[0];
        sc.end_y_[m] = sc.sample_hy_[g] + t_max * hd[1];
        sc.end_w_[m] = sc.sample_w_[g] + t_max * hd[2];
        ++m;
      }
      sample_t_[sc.gathered_sample_[g]] = longest;
    }
    NearestPixels(sc.end_x_.data(), sc.end_y_.data(), sc.end_w_.data(), m, sc.end_u_.data(),
                  sc.end_v_.data());
    // FirstExit's first test, on the same values, for the segments in front of the camera:
    // the rectangle of the end pixels, clamped to the image (the others' is not used).
    for (std::size_t r = 0; r < m; ++r) {
      const std::size_t g = sc.walk_sample_[r];
      const int iu = NearestPixel(sc.sample_u_[g]);
      const int iv = NearestPixel(sc.sample_v_[g]);
      sc.rect_u0_[r] = std::max(std::min(iu, sc.end_u_[r]), 0);
      sc.rect_u1_[r] = std::min(std::max(iu, sc.end_u_[r]), view.width - 1);
      sc.rect_v0_[r] = std::max(std::min(iv, sc.end_v_[r]), 0);
      sc.rect_v1_[r] = std::min(std::max(iv, sc.end_v_[r]), view.height - 1);
    }
    packed.AllOnEach(sc.rect_u0_.data(), sc.rect_v0_.data(), sc.rect_u1_.data(), sc.rect_v1_.data(),
                     m, sc.rect_on_.data());
    return m;
  }

  // The m items to walk: each item's t lowered to where its segment first leaves `view`'s
  // silhouette (WalkCells in front of the camera unless the end pixels' rectangle is all on
  // it, FirstExit otherwise).
  void WalkItems(Scratch& sc, const ViewData& view, const double (&step_h)[3][2][3],
                 std::size_t m) {
    for (std::size_t r = 0; r < m; ++r) {
      const std::size_t k = sc.walk_item_[r];
      const std::size_t g = sc.walk_sample_[r];
      const Item& item = items_[k];
      const double t_max = sc.walk_t_[r];
      const double hx = sc.sample_hx_[g];
      const double hy = sc.sample_hy_[g];
      const double hw = sc.sample_w_[g];
      const double* hd = step_h[item.axis][item.sign > 0 ? 1 : 0];
      if (hw > 0.0 && sc.end_w_[r] > 0.0) {
        if (sc.rect_on_[r] != 0) continue;
        t_item_[k] = std::min(t_item_[k],
                              WalkCells(view, hx, hy, hw, hd, t_max, NearestPixel(sc.sample_u_[g]),
                                        NearestPixel(sc.sample_v_[g]), sc.end_u_[r], sc.end_v_[r]));
        continue;
      }
      const Eigen::Vector3d a(sc.gathered_.x[g], sc.gathered_.y[g], sc.gathered_.z[g]);
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      d[item.axis] = item.sign * hull_.grid_.voxel_mm;
      t_item_[k] = std::min(t_item_[k], FirstExit(view, a, d, t_max));
    }
  }

  const VisualHull& hull_;
  const std::size_t n_;  // edges
  const Eigen::Vector3i block_dims_;
  std::vector<std::size_t> start_;
  std::unique_ptr<std::uint64_t[]> order_;
  std::vector<Item> items_;  // in the order of order_
  std::vector<Sample> samples_;
  Points sample_centre_;
  std::vector<std::size_t> brick_start_;  // samples of brick b: [brick_start_[b], [b + 1])
  Points brick_centre_;
  // Per brick: the box of its samples' segments (grid coordinates, voxels), and its half extents.
  std::vector<Eigen::Vector3d> brick_lo_, brick_hi_, brick_half_;
  std::vector<Block> blocks_;
  // The scratch's sizes (AllocateScratch).
  std::size_t largest_block_ = 0, most_bricks_ = 0, most_items_ = 0;
  std::vector<double> t_item_;
  std::vector<double> sample_t_;
};

std::vector<double> VisualHull::PlaceOnEdges(const std::vector<GridEdge>& edges,
                                             std::optional<double> clip_below_z_mm,
                                             bool cull_views) const {
  EdgePlacer placer(*this, edges, clip_below_z_mm);
  tbb::enumerable_thread_specific<EdgePlacer::Scratch> scratch(
      [&placer] { return placer.MakeScratch(); });
  for (const ViewData& view : views_) placer.PlaceInView(view, cull_views, scratch);
  return placer.Result();
}

}  // namespace revolve::reconstruct
