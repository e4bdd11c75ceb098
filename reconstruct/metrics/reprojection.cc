#include "reconstruct/metrics/reprojection.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>

#include <tbb/enumerable_thread_specific.h>
#include <opencv2/core.hpp>

// The x86 SIMD path of the small faces' pixel tests; REVOLVE_PORTABLE (the CMake option) leaves
// it out for the portable loop, which sets the same pixels (./run test checks both).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
#include <immintrin.h>
#define REVOLVE_X86_AVX2 1
#endif

#include "reconstruct/image_set.h"
#include "reconstruct/metrics/outline_internal.h"
#include "reconstruct/parallel.h"

namespace revolve::reconstruct {
namespace {

double Cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Column index for MeshInsideTest: triangles binned by their xy bounding boxes.
struct ColumnIndex {
  std::vector<Eigen::Vector3d> a, b, c;  // triangle corners
  std::vector<double> normal_z;          // sign source
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
  double bin = 1.0;
  int nx = 0;
  int ny = 0;
  std::vector<std::vector<int>> bins;
};

// A triangle's edge: its vector (ex, ey) and its start (px, py).
struct Edge {
  double ex, ey, px, py;
};

// Faces narrower than this (px) are tested pixel by pixel: their rows are too short for runs.
constexpr int kRunMinWidthPx = 8;

// Whether pixel (u, v) passes the edge's test, sign * (ex (v - py) - ey (u - px)) >= 0.
[[gnu::always_inline]] inline bool Inside(const Edge& edge, double sign, int u, int v) {
  return sign * (edge.ex * (static_cast<double>(v) - edge.py) -
                 edge.ey * (static_cast<double>(u) - edge.px)) >=
         0.0;
}

// Narrows [*lo, *hi] on row v to the pixels u where sign * (ex (v - py) - ey (u - px)) >= 0
// (empty: *lo > *hi). The test is monotone in u, so they are a prefix or a suffix.
void ClipRun(const Edge& edge, double sign, int v, int* lo, int* hi) {
  const double c = edge.ex * (static_cast<double>(v) - edge.py);
  const auto inside = [&](int u) {
    return sign * (c - edge.ey * (static_cast<double>(u) - edge.px)) >= 0.0;
  };
  const double slope = sign * edge.ey;  // the test falls with u when positive
  if (slope == 0.0) {
    if (!inside(*lo)) *hi = *lo - 1;
    return;
  }
  // Where the line crosses the row (clamped to the run), a start for the exact search.
  const double cross = edge.px + c / edge.ey;
  const double start = std::isnan(cross) ? static_cast<double>(*lo)
                                         : std::clamp(cross, static_cast<double>(*lo - 1),
                                                      static_cast<double>(*hi + 1));
  if (slope > 0.0) {
    int u = std::min(static_cast<int>(std::floor(start)), *hi);
    while (u < *hi && inside(u + 1)) ++u;
    while (u >= *lo && !inside(u)) --u;
    *hi = u;
  } else {
    int u = std::max(static_cast<int>(std::ceil(start)), *lo);
    while (u > *lo && inside(u - 1)) --u;
    while (u <= *hi && !inside(u)) ++u;
    *lo = u;
  }
}

// A small face's pixels: every pixel of rows v0..v1, columns u0..u1 (box coordinates from
// (box_u0, box_v0)) that passes all three edges' tests set to 255 in `out`, the others left as
// they are; Inside's expression, the same values, on four pixels at a time with AVX2.
void SmallFace(const Edge (&edges)[3], double sign, int u0, int u1, int v0, int v1, int box_u0,
               int box_v0, cv::Mat& out) {
  for (int v = v0; v <= v1; ++v) {
    auto* row = out.ptr<std::uint8_t>(v - box_v0);
    for (int u = u0; u <= u1; ++u) {
      // No branch on the outcome (a few pixels a row: mispredicted branches cost more than
      // the tests they would skip); the pixels are 0 or 255.
      const int inside = static_cast<int>(Inside(edges[0], sign, u, v)) &
                         static_cast<int>(Inside(edges[1], sign, u, v)) &
                         static_cast<int>(Inside(edges[2], sign, u, v));
      row[u - box_u0] |= inside != 0 ? 255 : 0;
    }
  }
}

#if defined(REVOLVE_X86_AVX2)
[[gnu::target("avx2")]] void SmallFaceAvx2(const Edge (&edges)[3], double sign, int u0, int u1,
                                           int v0, int v1, int box_u0, int box_v0, cv::Mat& out) {
  const __m256d s = _mm256_set1_pd(sign);
  const __m256d zero = _mm256_setzero_pd();
  const __m256d lanes = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
  __m256d ey[3], px[3];
  for (int e = 0; e < 3; ++e) {
    ey[e] = _mm256_set1_pd(edges[e].ey);
    px[e] = _mm256_set1_pd(edges[e].px);
  }
  for (int v = v0; v <= v1; ++v) {
    auto* row = out.ptr<std::uint8_t>(v - box_v0) - box_u0;
    // ex (v - py), each edge's part of the test that the row fixes.
    __m256d c[3];
    for (int e = 0; e < 3; ++e) {
      c[e] = _mm256_set1_pd(edges[e].ex * (static_cast<double>(v) - edges[e].py));
    }
    for (int u = u0; u <= u1; u += 4) {
      const __m256d pixel_u = _mm256_add_pd(_mm256_set1_pd(static_cast<double>(u)), lanes);
      __m256d pass = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
      for (int e = 0; e < 3; ++e) {
        const __m256d test = _mm256_mul_pd(
            s, _mm256_sub_pd(c[e], _mm256_mul_pd(ey[e], _mm256_sub_pd(pixel_u, px[e]))));
        pass = _mm256_and_pd(pass, _mm256_cmp_pd(test, zero, _CMP_GE_OQ));
      }
      const int bits = _mm256_movemask_pd(pass);
      const int count = std::min(4, u1 - u + 1);
      for (int k = 0; k < count; ++k) row[u + k] |= ((bits >> k) & 1) != 0 ? 255 : 0;
    }
  }
}
#endif

}  // namespace

BoxedSilhouette RenderSilhouetteInBox(const Mesh& mesh, const View& view, bool closed) {
  BoxedSilhouette result;
  std::vector<Eigen::Vector2d> projected(mesh.vertices.size());
  std::vector<std::uint8_t> visible(mesh.vertices.size(), 0);
  bool all_visible = true;
  // The rectangle of the visible vertices' finite projections: every face drawn lies within it
  // (a face with a coordinate not finite has no finite area and is not drawn).
  double x_min = std::numeric_limits<double>::infinity(), y_min = x_min;
  double x_max = -x_min, y_max = -x_min;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    Eigen::Vector2d pixel;
    if (view.Project(mesh.vertices[i].cast<double>(), &pixel)) {
      projected[i] = pixel;
      visible[i] = 1;
      if (std::isfinite(pixel.x()) && std::isfinite(pixel.y())) {
        x_min = std::min(x_min, pixel.x());
        x_max = std::max(x_max, pixel.x());
        y_min = std::min(y_min, pixel.y());
        y_max = std::max(y_max, pixel.y());
      }
    } else {
      all_visible = false;
    }
  }
  // The pixel centres within it, in the image (clamped before the conversion to int).
  const double u_first = std::max(0.0, std::ceil(x_min));
  const double u_last = std::min(view.width_px - 1.0, std::floor(x_max));
  const double v_first = std::max(0.0, std::ceil(y_min));
  const double v_last = std::min(view.height_px - 1.0, std::floor(y_max));
  if (!(u_first <= u_last && v_first <= v_last)) return result;
  const int box_u0 = static_cast<int>(u_first);
  const int box_v0 = static_cast<int>(v_first);
  const int box_u1 = static_cast<int>(u_last);
  const int box_v1 = static_cast<int>(v_last);
  result.box = cv::Rect(box_u0, box_v0, box_u1 - box_u0 + 1, box_v1 - box_v0 + 1);
  result.pixels = cv::Mat(result.box.size(), CV_8UC1, cv::Scalar(0));
  cv::Mat& out = result.pixels;
  const bool one_winding = closed && all_visible;
#if defined(REVOLVE_X86_AVX2)
  static const bool avx2 = __builtin_cpu_supports("avx2");
#endif
  // Per face and row of its bounding rectangle, the pixel centres inside all three edges (edges
  // inclusive). Each edge's test, sign * (e_x (v - p_y) - e_y (u - p_x)) >= 0, is monotone in u
  // even as rounded (each operation is), so the pixels that pass it are a prefix or a suffix of
  // the row: its end is found from the line's crossing, then checked with the test itself, and
  // the row's run set at once. The same pixels as testing each one.
  for (const Eigen::Vector3i& face : mesh.faces) {
    if (!visible[face[0]] || !visible[face[1]] || !visible[face[2]]) continue;
    const double x0 = projected[face[0]].x(), y0 = projected[face[0]].y();
    const double x1 = projected[face[1]].x(), y1 = projected[face[1]].y();
    const double x2 = projected[face[2]].x(), y2 = projected[face[2]].y();
    const double area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0);
    if (area == 0.0 || !std::isfinite(area) || (one_winding && area < 0.0)) continue;
    const int u0 = std::max(box_u0, static_cast<int>(std::ceil(std::min(std::min(x0, x1), x2))));
    const int u1 = std::min(box_u1, static_cast<int>(std::floor(std::max(std::max(x0, x1), x2))));
    const int v0 = std::max(box_v0, static_cast<int>(std::ceil(std::min(std::min(y0, y1), y2))));
    const int v1 = std::min(box_v1, static_cast<int>(std::floor(std::max(std::max(y0, y1), y2))));
    if (u0 > u1 || v0 > v1) continue;
    const double sign = area > 0.0 ? 1.0 : -1.0;
    // Edges p1 - p0 from p0, p2 - p1 from p1, p0 - p2 from p2.
    const Edge edges[3] = {
        {x1 - x0, y1 - y0, x0, y0}, {x2 - x1, y2 - y1, x1, y1}, {x0 - x2, y0 - y2, x2, y2}};
    if (u1 - u0 < kRunMinWidthPx) {
#if defined(REVOLVE_X86_AVX2)
      if (avx2) {
        SmallFaceAvx2(edges, sign, u0, u1, v0, v1, box_u0, box_v0, out);
        continue;
      }
#endif
      SmallFace(edges, sign, u0, u1, v0, v1, box_u0, box_v0, out);
      continue;
    }
    for (int v = v0; v <= v1; ++v) {
      int lo = u0, hi = u1;
      for (int e = 0; e < 3 && lo <= hi; ++e) ClipRun(edges[e], sign, v, &lo, &hi);
      if (lo <= hi)
        std::memset(out.ptr<std::uint8_t>(v - box_v0) + (lo - box_u0), 255, hi - lo + 1);
    }
  }
  return result;
}

cv::Mat RenderSilhouette(const Mesh& mesh, const View& view, bool closed) {
  const BoxedSilhouette boxed = RenderSilhouetteInBox(mesh, view, closed);
  cv::Mat out(view.height_px, view.width_px, CV_8UC1, cv::Scalar(0));
  if (!boxed.box.empty()) boxed.pixels.copyTo(out(boxed.box));
  return out;
}

namespace {

// The pixels non-zero in both of two CV_8UC1 images of one size, and in either: counted in one
// pass row by row (whole numbers; the loop runs on vectors, built for AVX2 too where the
// processor has it), with no image made.
struct MaskCounts {
  std::int64_t both = 0;
  std::int64_t either = 0;
};
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
MaskCounts
CountMasks(const cv::Mat& a, const cv::Mat& b) {
  MaskCounts counts;
  for (int y = 0; y < a.rows; ++y) {
    const auto* pa = a.ptr<std::uint8_t>(y);
    const auto* pb = b.ptr<std::uint8_t>(y);
    std::int32_t row_both = 0;
    std::int32_t row_either = 0;
    for (int x = 0; x < a.cols; ++x) {
      const int in_a = pa[x] != 0 ? 1 : 0;
      const int in_b = pb[x] != 0 ? 1 : 0;
      row_both += in_a & in_b;
      row_either += in_a | in_b;
    }
    counts.both += row_both;
    counts.either += row_either;
  }
  return counts;
}

}  // namespace

double MaskIoU(const cv::Mat& a, const cv::Mat& b) {
  const MaskCounts counts = CountMasks(a, b);
  return counts.either == 0 ? 1.0
                            : static_cast<double>(counts.both) / static_cast<double>(counts.either);
}

namespace outline_internal {

ReprojectionStats SilhouetteReprojectionBy(const Mesh& mesh, const std::vector<View>& views,
                                           const std::vector<cv::Mat>& masks,
                                           const std::vector<cv::Point>& mask_origins,
                                           OutlineSearch search) {
  ReprojectionStats stats;
  // The views on all cores, each IoU in its slot; the sum and the worst in view order.
  stats.iou.resize(views.size());
  const bool every_edge = search == OutlineSearch::kEveryEdge;
  std::optional<OutlineIndex> index;
  std::vector<SharedEdge> edges;  // every_edge
  if (every_edge) {
    edges = SharedEdges(mesh);
  } else {
    index.emplace(mesh);
  }
  const bool closed = every_edge ? !edges.empty() : index->closed();  // else face by face
  stats.closed_and_oriented = closed;
  // View i's IoU from its silhouette (nullopt: drawn face by face).
  const auto measure = [&](std::size_t i, const std::optional<BoxedSilhouette>& outline) {
    const cv::Point origin = mask_origins.empty() ? cv::Point() : mask_origins[i];
    if (!outline) {
      const cv::Mat rendered = RenderSilhouette(mesh, views[i], closed);
      stats.iou[i] = MaskIoU(rendered, mask_origins.empty()
                                           ? masks[i]
                                           : WholeFromWindow(masks[i], origin, rendered.size()));
      return;
    }
    // MaskIoU's counts: none of the silhouette lies outside its box, none of the mask outside
    // its window.
    std::int64_t both = 0;
    std::int64_t silhouette = 0;
    if (!outline->box.empty()) {
      const cv::Rect overlap_box = outline->box & cv::Rect(origin, masks[i].size());
      if (!overlap_box.empty()) {
        both = CountMasks(outline->pixels(overlap_box - outline->box.tl()),
                          masks[i](overlap_box - origin))
                   .both;
      }
      silhouette = cv::countNonZero(outline->pixels);
    }
    const std::int64_t either = silhouette + cv::countNonZero(masks[i]) - both;
    stats.iou[i] = either == 0 ? 1.0 : static_cast<double>(both) / static_cast<double>(either);
  };
  if (closed && search == OutlineSearch::kBatched) {
    SilhouettesFromOutline(mesh, *index, views, measure);
  } else {
    tbb::enumerable_thread_specific<OutlineScratch> scratch;  // each thread's, view to view
    ParallelFor(0, views.size(), [&](std::size_t i) {
      std::optional<BoxedSilhouette> outline;
      if (closed) {
        outline = every_edge
                      ? SilhouetteFromEveryEdge(mesh, edges, views[i])
                      : SilhouetteFromOutline(mesh, *index, views[i], nullptr, &scratch.local());
      }
      measure(i, outline);
    });
  }
  double sum = 0.0;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const double iou = stats.iou[i];
    sum += iou;
    if (stats.worst_view < 0 || iou < stats.min) {
      stats.min = iou;
      stats.worst_view = static_cast<int>(i);
    }
  }
  if (!views.empty()) stats.mean = sum / static_cast<double>(views.size());
  return stats;
}

}  // namespace outline_internal

ReprojectionStats SilhouetteReprojection(const Mesh& mesh, const std::vector<View>& views,
                                         const std::vector<cv::Mat>& masks,
                                         const std::vector<cv::Point>& mask_origins) {
  return outline_internal::SilhouetteReprojectionBy(mesh, views, masks, mask_origins,
                                                    outline_internal::OutlineSearch::kBatched);
}

InsideTest MeshInsideTest(const Mesh& mesh) {
  auto index = std::make_shared<ColumnIndex>();
  if (mesh.faces.empty()) return [](const Eigen::Vector3d&) { return false; };
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::max());
  Eigen::Vector2d hi = -lo;
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2d p = mesh.vertices[f[k]].head<2>().cast<double>();
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  }
  const int bins_per_side =
      std::clamp(static_cast<int>(std::sqrt(mesh.faces.size() / 4.0)), 1, 512);
  index->origin = lo;
  index->bin = std::max((hi - lo).maxCoeff() / bins_per_side, 1e-12);
  index->nx = std::max(1, static_cast<int>(std::ceil((hi.x() - lo.x()) / index->bin)) + 1);
  index->ny = std::max(1, static_cast<int>(std::ceil((hi.y() - lo.y()) / index->bin)) + 1);
  index->bins.resize(static_cast<std::size_t>(index->nx) * index->ny);
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3d a = mesh.vertices[f[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[f[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[f[2]].cast<double>();
    const double nz = Cross2((b - a).head<2>(), (c - a).head<2>());
    if (nz == 0.0) continue;  // vertical: never crossed by a vertical ray's interior
    const int t = static_cast<int>(index->a.size());
    index->a.push_back(a);
    index->b.push_back(b);
    index->c.push_back(c);
    index->normal_z.push_back(nz);
    const Eigen::Vector2d tlo = a.head<2>().cwiseMin(b.head<2>()).cwiseMin(c.head<2>());
    const Eigen::Vector2d thi = a.head<2>().cwiseMax(b.head<2>()).cwiseMax(c.head<2>());
    const int i0 = static_cast<int>((tlo.x() - lo.x()) / index->bin);
    const int i1 = std::min(index->nx - 1, static_cast<int>((thi.x() - lo.x()) / index->bin));
    const int j0 = static_cast<int>((tlo.y() - lo.y()) / index->bin);
    const int j1 = std::min(index->ny - 1, static_cast<int>((thi.y() - lo.y()) / index->bin));
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i)
        index->bins[static_cast<std::size_t>(j) * index->nx + i].push_back(t);
    }
  }
  // A query is nudged off the exact position by an irrational fraction of the bin so that rays
  // through shared edges and vertices (grid-aligned meshes) count each crossing once.
  const Eigen::Vector2d nudge = index->bin * 1e-7 * Eigen::Vector2d(0.5772156649, 0.3183098862);
  return [index, nudge](const Eigen::Vector3d& point) {
    const Eigen::Vector2d p = point.head<2>() + nudge;
    const int i = static_cast<int>(std::floor((p.x() - index->origin.x()) / index->bin));
    const int j = static_cast<int>(std::floor((p.y() - index->origin.y()) / index->bin));
    if (i < 0 || j < 0 || i >= index->nx || j >= index->ny) return false;
    int winding = 0;
    for (const int t : index->bins[static_cast<std::size_t>(j) * index->nx + i]) {
      const Eigen::Vector2d a = index->a[t].head<2>();
      const Eigen::Vector2d b = index->b[t].head<2>();
      const Eigen::Vector2d c = index->c[t].head<2>();
      const double area = index->normal_z[t];
      const double wa = Cross2(b - p, c - p) / area;
      const double wb = Cross2(c - p, a - p) / area;
      const double wc = 1.0 - wa - wb;
      if (wa < 0.0 || wb < 0.0 || wc < 0.0) continue;
      const double z = wa * index->a[t].z() + wb * index->b[t].z() + wc * index->c[t].z();
      if (z < point.z()) winding += area < 0.0 ? 1 : -1;
    }
    return winding > 0;
  };
}

double VolumeIoU(const InsideTest& a, const InsideTest& b, const Eigen::Vector3d& box_min,
                 const Eigen::Vector3d& box_max, int resolution) {
  const Eigen::Vector3d size = box_max - box_min;
  const double cell = size.maxCoeff() / std::max(1, resolution);
  Eigen::Vector3i dims;
  for (int k = 0; k < 3; ++k) dims[k] = std::max(1, static_cast<int>(std::ceil(size[k] / cell)));
  std::int64_t both = 0;
  std::int64_t either = 0;
  for (int k = 0; k < dims.z(); ++k) {
    for (int j = 0; j < dims.y(); ++j) {
      for (int i = 0; i < dims.x(); ++i) {
        const Eigen::Vector3d x = box_min + cell * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5);
        const bool in_a = a(x);
        const bool in_b = b(x);
        both += in_a && in_b;
        either += in_a || in_b;
      }
    }
  }
  return either == 0 ? 1.0 : static_cast<double>(both) / static_cast<double>(either);
}

}  // namespace revolve::reconstruct
