#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <utility>

#include <tbb/enumerable_thread_specific.h>

#include "reconstruct/metrics/outline_internal.h"
#include "reconstruct/parallel.h"

namespace revolve::reconstruct::outline_internal {
namespace {

// A face's orientation is taken from its plane only when the plane is at least this far (rad)
// from every ray of the camera to the mesh: its projected area then is at least ~1e-3 of its
// size, far from its rounding (below), and the float plane's own rounding (~1e-7) is well inside.
constexpr double kGrazingMarginRad = 1e-3;
// ... when the face's smallest altitude is at least this fraction of the view's coordinate scale
// (camera distance, mesh size and offsets: what the projection's rounding grows with). The
// projected area's rounding bounds the altitude whose sign it can flip to ~1e-10 of that scale
// for projections within ~100 focal lengths of the image (below): 1000 times to spare.
constexpr double kMinHeightOfScale = 1e-7;
// ... and, for a pinhole view, when every point of the mesh's sphere lies at a depth of at least
// this fraction of its distance from the camera (its projections within ~100 focal lengths).
constexpr double kMinDepthOfDistance = 1e-2;

// Whether the face p0 p1 p2 has a positive (and finite) projected area.
[[gnu::always_inline]] inline bool Positive(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1,
                                            const Eigen::Vector2d& p2) {
  const double area = (p1.x() - p0.x()) * (p2.y() - p0.y()) - (p1.y() - p0.y()) * (p2.x() - p0.x());
  return area > 0.0 && std::isfinite(area);
}

using Segment = OutlineSegment;

// Where MeasureCorners writes (OutlineIndex's arrays).
struct FaceMeasures {
  float* normal_x;
  float* normal_y;
  float* normal_z;
  float* offset;
  float* height;
  std::uint8_t* shared_axes;
};

// Faces first..first + count's planes, smallest altitudes and shared axes (OutlineIndex's) from
// their corners: corners[(3 k + axis) * count + j] is coordinate `axis` of corner k of face
// first + j. In double as Eigen computes them (a = corner 0 ..., n = (b - a) x (c - a), |n| =
// sqrt((n_x^2 + n_y^2) + n_z^2), the unit normal n / |n|, its offset (u_x a_x + u_y a_y) + u_z
// a_z, the altitude |n| / the longest edge), each operation rounded as there: one loop with no
// branch, on vectors (built for AVX2 too where the processor has it; no fused multiply-add).
// A degenerate face (no normal, or no edge) gets a zero plane and altitude.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
void MeasureCorners(const float* __restrict corners, std::size_t count, std::size_t first,
                    const FaceMeasures& out) {
  const float* __restrict ax = corners;
  const float* __restrict ay = corners + count;
  const float* __restrict az = corners + 2 * count;
  const float* __restrict bx = corners + 3 * count;
  const float* __restrict by = corners + 4 * count;
  const float* __restrict bz = corners + 5 * count;
  const float* __restrict cx = corners + 6 * count;
  const float* __restrict cy = corners + 7 * count;
  const float* __restrict cz = corners + 8 * count;
  float* __restrict normal_x = out.normal_x + first;
  float* __restrict normal_y = out.normal_y + first;
  float* __restrict normal_z = out.normal_z + first;
  float* __restrict offset = out.offset + first;
  float* __restrict height = out.height + first;
  std::uint8_t* __restrict shared_axes = out.shared_axes + first;
  const auto same = [](float p, float q, float r) {
    return static_cast<unsigned>(q == p) & static_cast<unsigned>(r == p);
  };
  for (std::size_t j = 0; j < count; ++j) {
    shared_axes[j] =
        static_cast<std::uint8_t>(same(ax[j], bx[j], cx[j]) | (same(ay[j], by[j], cy[j]) << 1) |
                                  (same(az[j], bz[j], cz[j]) << 2));
  }
  for (std::size_t j = 0; j < count; ++j) {
    const double a_x = ax[j], a_y = ay[j], a_z = az[j];
    const double ab_x = static_cast<double>(bx[j]) - a_x;
    const double ab_y = static_cast<double>(by[j]) - a_y;
    const double ab_z = static_cast<double>(bz[j]) - a_z;
    const double ac_x = static_cast<double>(cx[j]) - a_x;
    const double ac_y = static_cast<double>(cy[j]) - a_y;
    const double ac_z = static_cast<double>(cz[j]) - a_z;
    const double bc_x = static_cast<double>(cx[j]) - static_cast<double>(bx[j]);
    const double bc_y = static_cast<double>(cy[j]) - static_cast<double>(by[j]);
    const double bc_z = static_cast<double>(cz[j]) - static_cast<double>(bz[j]);
    const double ca_x = a_x - static_cast<double>(cx[j]);
    const double ca_y = a_y - static_cast<double>(cy[j]);
    const double ca_z = a_z - static_cast<double>(cz[j]);
    const double n_x = ab_y * ac_z - ab_z * ac_y;
    const double n_y = ab_z * ac_x - ab_x * ac_z;
    const double n_z = ab_x * ac_y - ab_y * ac_x;
    const double n_norm = std::sqrt((n_x * n_x + n_y * n_y) + n_z * n_z);
    const double ab2 = (ab_x * ab_x + ab_y * ab_y) + ab_z * ab_z;
    const double bc2 = (bc_x * bc_x + bc_y * bc_y) + bc_z * bc_z;
    const double ca2 = (ca_x * ca_x + ca_y * ca_y) + ca_z * ca_z;
    // std::max's choice: the later of equal values is not taken.
    const double ab_bc = bc2 > ab2 ? bc2 : ab2;
    const double longest = std::sqrt(ca2 > ab_bc ? ca2 : ab_bc);
    const double u_x = n_x / n_norm, u_y = n_y / n_norm, u_z = n_z / n_norm;
    const bool usable = static_cast<int>(n_norm > 0.0) & static_cast<int>(longest > 0.0);
    normal_x[j] = usable ? static_cast<float>(u_x) : 0.0f;
    normal_y[j] = usable ? static_cast<float>(u_y) : 0.0f;
    normal_z[j] = usable ? static_cast<float>(u_z) : 0.0f;
    offset[j] = usable ? static_cast<float>((u_x * a_x + u_y * a_y) + u_z * a_z) : 0.0f;
    height[j] = usable ? static_cast<float>(n_norm / longest) : 0.0f;
  }
}

// A vertex as `view` sees it: h / h.z, h = Homogeneous(view, vertex). An affine view's h.z is
// exactly 1 (the thesis's), and the division by it, exact, is left out.
[[gnu::always_inline]] inline Eigen::Vector2d Projected(const View& view,
                                                        const Eigen::Vector3f& vertex) {
  const Eigen::Vector3d h = Homogeneous(view, vertex);
  if (h.z() == 1.0) return h.head<2>();
  return h.head<2>() / h.z();
}

// The pixels `segments` wind around or run through, within the rectangle [lo, hi] (clipped to
// the view). Each segment adds its direction to the pixels of each row it crosses (rows v with
// min(y) <= v < max(y)) from its crossing rightwards; a running sum along the row is the winding
// number. Built for AVX2 too where the processor has it: there ceil and floor are an instruction
// each (SSE2's take a dozen), the same values; no fused multiply-add. `winding_store` and
// `on_outline_store`: working memory kept by the caller (any content on entry).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
BoxedSilhouette
Fill(const std::vector<Segment>& segments, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
     const View& view, std::vector<std::int32_t>* winding_store,
     std::vector<cv::Point>* on_outline_store) {
  BoxedSilhouette result;
  const double u_first = std::max(0.0, std::ceil(lo.x()));
  const double v_first = std::max(0.0, std::ceil(lo.y()));
  const double u_last = std::min(view.width_px - 1.0, std::floor(hi.x()));
  const double v_last = std::min(view.height_px - 1.0, std::floor(hi.y()));
  if (u_first > u_last || v_first > v_last) return result;
  const int x0 = static_cast<int>(u_first);
  const int y0 = static_cast<int>(v_first);
  result.box =
      cv::Rect(x0, y0, static_cast<int>(u_last) - x0 + 1, static_cast<int>(v_last) - y0 + 1);
  const int width = result.box.width;
  const int height = result.box.height;
  const auto stride = static_cast<std::size_t>(width) + 1;
  winding_store->assign(stride * static_cast<std::size_t>(height), 0);
  std::int32_t* winding = winding_store->data();
  std::vector<cv::Point>& on_outline = *on_outline_store;  // in the box's coordinates
  on_outline.clear();
  const auto on = [&](double x, int v) __attribute__((always_inline)) {
    if (x == std::floor(x) && x >= x0 && x < x0 + width) {
      on_outline.emplace_back(static_cast<int>(x) - x0, v);
    }
  };
  for (const Segment& s : segments) {
    const Eigen::Vector2d& p = s.p;
    const Eigen::Vector2d& q = s.q;
    const double top = std::min(p.y(), q.y());
    const double bottom = std::max(p.y(), q.y());
    if (top == bottom) {
      if (top == std::floor(top) && top >= y0 && top < y0 + height) {
        const double left = std::max<double>(x0, std::ceil(std::min(p.x(), q.x())));
        const double right = std::min<double>(x0 + width - 1, std::floor(std::max(p.x(), q.x())));
        for (double x = left; x <= right; ++x) on(x, static_cast<int>(top) - y0);
      }
      continue;
    }
    // The box's rows it reaches (clamped before the conversion to int); most outline edges of a
    // fine mesh reach none, and are done before the division.
    const double row_top = std::max<double>(y0, std::ceil(top));
    const double row_bottom = std::min<double>(y0 + height - 1, std::floor(bottom));
    if (!(row_top <= row_bottom)) continue;
    const auto v_top = static_cast<int>(row_top);
    const auto v_bottom = static_cast<int>(row_bottom);
    const int direction = q.y() > p.y() ? 1 : -1;
    const double slope = (q.x() - p.x()) / (q.y() - p.y());
    for (int v = v_top; v <= v_bottom; ++v) {
      const double x = p.x() + (static_cast<double>(v) - p.y()) * slope;
      on(x, v - y0);
      if (static_cast<double>(v) == bottom) continue;  // rows top <= v < bottom cross
      const double u =
          std::clamp(std::ceil(x), static_cast<double>(x0), static_cast<double>(x0 + width));
      winding[static_cast<std::size_t>(v - y0) * stride +
              static_cast<std::size_t>(static_cast<int>(u) - x0)] += direction;
    }
  }
  result.pixels = cv::Mat(height, width, CV_8UC1);
  for (int v = 0; v < height; ++v) {
    const std::int32_t* w = winding + static_cast<std::size_t>(v) * stride;
    auto* row = result.pixels.ptr<std::uint8_t>(v);
    int sum = 0;
    int u = 0;
    // Most of a row adds nothing to the sum (the winding changes only where the outline
    // crosses it): eight such pixels are set at once.
    for (; u + 8 <= width; u += 8) {
      std::int32_t any = 0;
      for (int k = 0; k < 8; ++k) any |= w[u + k];
      if (any == 0) {
        std::memset(row + u, sum != 0 ? 255 : 0, 8);
        continue;
      }
      for (int k = u; k < u + 8; ++k) {
        sum += w[k];
        row[k] = sum != 0 ? 255 : 0;
      }
    }
    for (; u < width; ++u) {
      sum += w[u];
      row[u] = sum != 0 ? 255 : 0;
    }
  }
  for (const cv::Point& pixel : on_outline) result.pixels.at<std::uint8_t>(pixel) = 255;
  return result;
}

// How one view decides a face from its plane (unit normal n, offset d = n . x): s = n . p - d k
// with (p, k) = (camera centre, 1) for a pinhole view, where the projected area is
// det(M) ((x - c) . n) / (z0 z1 z2) as h_i = M (x_i - c), or (r1 x r2, 0) for an orthographic
// one, where it is (r1 x r2) . n / s^2. Decided when |s| > threshold and the face's altitude is
// above min_height: positive iff (s > 0) != flip.
struct PlaneTest {
  bool usable = false;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double k = 0.0;
  double threshold = 0.0;
  double min_height = 0.0;
  bool flip = false;
  // Orthographic views: bit a set when a row of the projection reads only coordinate a (the
  // others' factors exactly 0). A face whose corners share that coordinate (bit for bit) then
  // projects to three equal values in that row: its computed area is exactly 0, not positive.
  std::uint8_t flat_axes = 0;
};

// A PlaneTest's point, k, threshold and minimum altitude in floats, as the loops over the faces
// compare them (their rounding is within the threshold's allowance).
struct PlaneTestFloats {
  float px, py, pz, k, threshold, min_height;
};
PlaneTestFloats InFloats(const PlaneTest& test) {
  return {static_cast<float>(test.point.x()), static_cast<float>(test.point.y()),
          static_cast<float>(test.point.z()), static_cast<float>(test.k),
          static_cast<float>(test.threshold), static_cast<float>(test.min_height)};
}

PlaneTest PlaneTestOf(const OutlineIndex& index, const View& view) {
  PlaneTest test;
  const Eigen::Matrix3d m = view.pixel_from_object.leftCols<3>();
  const Eigen::Vector3d t = view.pixel_from_object.col(3);
  const Eigen::Vector3d& o = index.mesh_centre();
  const double r = index.mesh_radius();
  const double margin = std::sin(kGrazingMarginRad);
  if (view.IsAffine()) {
    const Eigen::Vector3d direction = m.row(0).cross(m.row(1)).transpose();
    const double norm = direction.norm();
    if (!(norm > 0.0) || !std::isfinite(norm)) return test;
    test.point = direction;
    test.threshold = (margin + 1e-5) * norm;
    test.min_height = kMinHeightOfScale * (o.norm() + r + t.head<2>().norm() / std::sqrt(norm));
    for (int row = 0; row < 2; ++row) {
      for (int a = 0; a < 3; ++a) {
        if (m(row, (a + 1) % 3) == 0.0 && m(row, (a + 2) % 3) == 0.0) {
          test.flat_axes |= static_cast<std::uint8_t>(1u << a);
        }
      }
    }
    test.usable = true;
    return test;
  }
  const double det = m.determinant();
  const double size = m.cwiseAbs().maxCoeff();
  if (!(std::abs(det) > 1e-9 * size * size * size) || !std::isfinite(det)) return test;
  const Eigen::Vector3d centre = -m.inverse() * t;
  if (!centre.allFinite()) return test;
  const Eigen::Vector3d w = m.row(2).transpose();
  const double distance = (o - centre).norm();
  if (!(w.dot(o - centre) - w.norm() * r > kMinDepthOfDistance * w.norm() * (distance + r))) {
    return test;
  }
  test.point = centre;
  test.k = 1.0;
  test.threshold = margin * (distance + r) + 1e-5 * (distance + r + o.norm() + centre.norm());
  test.min_height = kMinHeightOfScale * (distance + r + o.norm() + centre.norm());
  test.flip = det > 0.0;
  test.usable = true;
  return test;
}

// Whether every vertex within the mesh's sphere has a computed depth above 0 in `view`.
bool EveryVertexInFront(const OutlineIndex& index, const View& view) {
  if (!index.finite()) return false;
  const Eigen::Vector3d w = view.pixel_from_object.block<1, 3>(2, 0).transpose();
  const double m = view.pixel_from_object(2, 3);
  const Eigen::Vector3d& o = index.mesh_centre();
  const double r = index.mesh_radius();
  const double lowest = w.dot(o) + m - w.norm() * r;
  return lowest > 1e-9 * (w.norm() * (o.norm() + r) + std::abs(m));
}

}  // namespace

std::vector<SharedEdge> SharedEdges(const Mesh& mesh) {
  const std::size_t n = mesh.vertices.size();
  // Each vertex's outgoing edges (target, face), grouped by vertex.
  std::vector<std::size_t> first(n + 1, 0);
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int e = 0; e < 3; ++e) ++first[static_cast<std::size_t>(f[e]) + 1];
  }
  for (std::size_t v = 0; v < n; ++v) first[v + 1] += first[v];
  std::vector<std::pair<int, int>> out(first[n]);
  std::vector<std::size_t> next(first.begin(), first.end() - 1);
  for (std::size_t face = 0; face < mesh.faces.size(); ++face) {
    const Eigen::Vector3i& f = mesh.faces[face];
    for (int e = 0; e < 3; ++e) {
      out[next[static_cast<std::size_t>(f[e])]++] = {f[(e + 1) % 3], static_cast<int>(face)};
    }
  }
  const auto face_of = [&](int from, int to) {
    int found = -1;
    for (std::size_t k = first[static_cast<std::size_t>(from)];
         k < first[static_cast<std::size_t>(from) + 1]; ++k) {
      if (out[k].first != to) continue;
      if (found >= 0) return -2;  // used twice
      found = out[k].second;
    }
    return found;
  };
  std::vector<SharedEdge> edges;
  edges.reserve(mesh.faces.size() * 3 / 2);
  for (std::size_t face = 0; face < mesh.faces.size(); ++face) {
    const Eigen::Vector3i& f = mesh.faces[face];
    for (int e = 0; e < 3; ++e) {
      const int a = f[e];
      const int b = f[(e + 1) % 3];
      if (a == b) return {};
      const int right = face_of(b, a);
      if (right < 0 || face_of(a, b) != static_cast<int>(face)) return {};
      if (a < b) edges.push_back({a, b, static_cast<int>(face), right});
    }
  }
  return edges;
}

std::optional<BoxedSilhouette> SilhouetteFromEveryEdge(const Mesh& mesh,
                                                       const std::vector<SharedEdge>& edges,
                                                       const View& view) {
  std::vector<Eigen::Vector2d> projected(mesh.vertices.size());
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3d h = Homogeneous(view, mesh.vertices[i]);
    if (h.z() <= 0.0) return std::nullopt;
    projected[i] = h.head<2>() / h.z();
    lo = lo.cwiseMin(projected[i]);
    hi = hi.cwiseMax(projected[i]);
  }
  if (!lo.allFinite() || !hi.allFinite()) return std::nullopt;
  std::vector<std::uint8_t> positive(mesh.faces.size());
  for (std::size_t i = 0; i < mesh.faces.size(); ++i) {
    const Eigen::Vector3i& f = mesh.faces[i];
    positive[i] = Positive(projected[f[0]], projected[f[1]], projected[f[2]]);
  }
  std::vector<Segment> segments;
  for (const SharedEdge& e : edges) {
    if (positive[e.left] == positive[e.right]) continue;
    segments.push_back(
        {projected[positive[e.left] ? e.a : e.b], projected[positive[e.left] ? e.b : e.a]});
  }
  std::vector<std::int32_t> winding;
  std::vector<cv::Point> on_outline;
  return Fill(segments, lo, hi, view, &winding, &on_outline);
}

std::vector<Eigen::Vector3i> FaceNeighbours(const Mesh& mesh) {
  const std::size_t face_count = mesh.faces.size();
  const std::size_t n = mesh.vertices.size();
  // Both runs of each edge a - b (a < b) in the bucket of a, in face order: the higher end and
  // whether the run goes down from it (b -> a), as key = b * 2 + down; the face and the corner it
  // starts from, as by = face * 4 + corner (corner 3: a down run already paired).
  struct Run {
    std::uint32_t key, by;
  };
  // The faces in `parts` ranges, one task each: each range's runs counted per bucket, then
  // placed after those of the ranges before it.
  const std::size_t parts = std::clamp<std::size_t>(static_cast<std::size_t>(ThreadCount()), 1,
                                                    std::max<std::size_t>(face_count / 65536, 1));
  const auto range_of = [&](std::size_t part) {
    return std::pair(part * face_count / parts, (part + 1) * face_count / parts);
  };
  // next[part][v]: where the part's next run in bucket v goes (at first, how many it has there).
  std::vector<std::vector<std::uint32_t>> next(parts);
  ParallelFor(0, parts, [&](std::size_t part) {
    std::vector<std::uint32_t>& count = next[part];
    count.assign(n, 0);
    const auto [begin, end] = range_of(part);
    for (std::size_t face = begin; face < end; ++face) {
      const Eigen::Vector3i& f = mesh.faces[face];
      for (int e = 0; e < 3; ++e) ++count[static_cast<std::size_t>(std::min(f[e], f[(e + 1) % 3]))];
    }
  });
  std::vector<std::uint32_t> first(n + 1, 0);
  for (std::size_t v = 0; v < n; ++v) {
    std::uint32_t at = first[v];
    for (std::vector<std::uint32_t>& part : next) at += std::exchange(part[v], at);
    first[v + 1] = at;
  }
  const std::uint32_t total = first[n];
  const std::unique_ptr<Run[]> runs(new Run[total]);  // every slot written below: no zeros first
  ParallelFor(0, parts, [&](std::size_t part) {
    std::uint32_t* at = next[part].data();
    const auto [begin, end] = range_of(part);
    for (std::size_t face = begin; face < end; ++face) {
      const Eigen::Vector3i& f = mesh.faces[face];
      for (int e = 0; e < 3; ++e) {
        const int a = f[e];
        const int b = f[(e + 1) % 3];
        runs[at[std::min(a, b)]++] = {
            static_cast<std::uint32_t>(std::max(a, b)) * 2 + static_cast<std::uint32_t>(a > b),
            static_cast<std::uint32_t>(face * 4 + static_cast<std::size_t>(e))};
      }
    }
  });
  next = {};
  std::vector<Eigen::Vector3i> neighbours(face_count);
  std::atomic<bool> closed = true;
  std::atomic<std::int64_t> pairs = 0;
  // In each bucket, each up run a -> b is paired with the first down run b -> a there, which is
  // then marked paired. So the mesh is closed and consistently oriented iff every up run finds
  // one not paired yet (a second a -> b finds the same one, paired; a run from a vertex to itself
  // finds none) and the pairs are half the runs (no down run is left over, as a second b -> a
  // would be). Each bucket is one thread's; each (face, corner) is written by its pair alone.
  ParallelChunks(0, n, 4096, [&](std::size_t lo, std::size_t hi) {
    std::int64_t found = 0;
    for (std::size_t a = lo; a < hi; ++a) {
      const std::uint32_t begin = first[a];
      const std::uint32_t end = first[a + 1];
      for (std::uint32_t k = begin; k < end; ++k) {
        const std::uint32_t key = runs[k].key;
        if ((key & 1u) != 0) continue;  // a down run: paired from its up run
        std::uint32_t m = begin;
        while (m < end && runs[m].key != (key | 1u)) ++m;
        if (m == end || runs[m].by % 4 == 3) {
          closed.store(false, std::memory_order_relaxed);
          return;
        }
        const std::uint32_t left = runs[k].by;
        const std::uint32_t right = runs[m].by;
        runs[m].by = right | 3u;
        neighbours[left / 4][static_cast<int>(left % 4)] = static_cast<int>(right / 4);
        neighbours[right / 4][static_cast<int>(right % 4)] = static_cast<int>(left / 4);
        ++found;
      }
    }
    pairs.fetch_add(found, std::memory_order_relaxed);
  });
  if (!closed.load() || 2 * pairs.load() != static_cast<std::int64_t>(total)) return {};
  return neighbours;
}

OutlineIndex::OutlineIndex(const Mesh& mesh) : mesh_(&mesh) {
  // The neighbours (on all cores) beside the sphere.
  ParallelInvoke([&] { neighbours_ = FaceNeighbours(mesh); }, [&] { MeasureSphere(mesh); });
}

void OutlineIndex::MeasureSphere(const Mesh& mesh) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const Eigen::Vector3f& v : mesh.vertices) {
    const Eigen::Vector3d p = v.cast<double>();
    if (!p.allFinite()) return;  // finite_ false: every view projects every vertex
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  finite_ = true;
  mesh_centre_ = 0.5 * (lo + hi);
  double r2 = 0.0;
  for (const Eigen::Vector3f& v : mesh.vertices) {
    r2 = std::max(r2, (v.cast<double>() - mesh_centre_).squaredNorm());
  }
  mesh_radius_ = std::sqrt(r2) * (1.0 + 1e-9);
}

void OutlineIndex::MeasureFaces() const {
  if (!finite_) return;  // no planes: no view reads them
  const Mesh& mesh = *mesh_;
  const std::size_t face_count = mesh.faces.size();
  for (std::vector<float>* v : {&normal_x_, &normal_y_, &normal_z_, &offset_, &height_}) {
    v->resize(face_count);
  }
  shared_axes_.resize(face_count);
  // In chunks on all cores: each chunk's corners gathered into rows, then measured on vectors.
  const FaceMeasures out{normal_x_.data(), normal_y_.data(), normal_z_.data(),
                         offset_.data(),   height_.data(),   shared_axes_.data()};
  ParallelChunks(0, face_count, 4096, [&](std::size_t begin, std::size_t end) {
    const std::size_t count = end - begin;
    std::vector<float> corners(9 * count);
    for (std::size_t j = 0; j < count; ++j) {
      const Eigen::Vector3i& f = mesh.faces[begin + j];
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3f& v = mesh.vertices[f[k]];
        for (int axis = 0; axis < 3; ++axis) corners[(3 * k + axis) * count + j] = v[axis];
      }
    }
    MeasureCorners(corners.data(), count, begin, out);
  });
}

namespace {

// Each face's orientation in `view` (1 positive, 0 not) as far as its plane decides it, 2 where
// it does not (into `positive`); the faces it does not decide, in order, into `undecided`.
// Returns their count.
std::size_t OrientationsFromPlanes(const OutlineIndex& index, const PlaneTest& test,
                                   std::uint8_t* positive, std::uint32_t* undecided) {
  const std::size_t face_count = index.normal_x().size();
  const float* nx = index.normal_x().data();
  const float* ny = index.normal_y().data();
  const float* nz = index.normal_z().data();
  const float* offset = index.offset().data();
  const float* height = index.height().data();
  const auto [px, py, pz, k, threshold, min_height] = InFloats(test);
  const std::uint8_t flip = test.flip ? 1 : 0;
  const std::uint8_t* shared_axes = index.shared_axes().data();
  const std::uint8_t flat_axes = test.flat_axes;
  // In floats: the rounding (~1e-7 of |p| + |x|) is within the threshold's allowance. No branch
  // on the outcome (decided ? sign : 2), so that the loop runs on vectors.
  for (std::size_t i = 0; i < face_count; ++i) {
    const float s = nx[i] * px + ny[i] * py + nz[i] * pz - offset[i] * k;
    const auto flat = static_cast<std::uint8_t>((shared_axes[i] & flat_axes) != 0);
    const auto decided =
        static_cast<std::uint8_t>(((std::abs(s) > threshold) & (height[i] > min_height)) | flat);
    const auto sign =
        static_cast<std::uint8_t>((static_cast<std::uint8_t>(s > 0.0f) ^ flip) & (flat ^ 1u));
    positive[i] = static_cast<std::uint8_t>((sign & decided) | ((decided ^ 1u) << 1));
  }
  // The undecided listed (always written, the count advanced when undecided), eight faces at a
  // time skipped when none is.
  std::size_t count = 0;
  const auto list = [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      undecided[count] = static_cast<std::uint32_t>(i);
      count += positive[i] >> 1;
    }
  };
  std::size_t i = 0;
  for (; i + 8 <= face_count; i += 8) {
    std::uint64_t eight;
    std::memcpy(&eight, positive + i, sizeof eight);
    if (eight & 0x0202020202020202ull) list(i, i + 8);
  }
  list(i, face_count);
  return count;
}

}  // namespace

std::optional<BoxedSilhouette> SilhouetteFromOutline(const Mesh& mesh, const OutlineIndex& index,
                                                     const View& view, OutlineCounts* counts,
                                                     OutlineScratch* scratch) {
  OutlineCounts local_counts;
  OutlineCounts& count = counts ? *counts : local_counts;
  count = {};
  OutlineScratch local_scratch;
  OutlineScratch& work = scratch ? *scratch : local_scratch;
  const std::size_t face_count = mesh.faces.size();
  count.faces = static_cast<int>(face_count);
  // A vertex projected where it is needed, again where it is needed again: cheaper than
  // keeping it.
  const auto point = [&](int vertex) { return Projected(view, mesh.vertices[vertex]); };
  work.positive.resize(face_count);  // 1 positive, 0 not
  std::uint8_t* positive = work.positive.data();
  // The faces whose planes do not decide them.
  work.undecided.resize(face_count);
  std::uint32_t* undecided = work.undecided.data();
  std::size_t undecided_count = face_count;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  const bool every_face = !EveryVertexInFront(index, view);
  const PlaneTest test = every_face ? PlaneTest{} : PlaneTestOf(index, view);
  if (every_face) {
    // SilhouetteFromEveryEdge's check and box.
    count.every_face = true;
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
      const Eigen::Vector3d h = Homogeneous(view, mesh.vertices[i]);
      if (h.z() <= 0.0) return std::nullopt;
      const Eigen::Vector2d p = h.head<2>() / h.z();
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    if (!lo.allFinite() || !hi.allFinite()) return std::nullopt;
  }
  if (test.usable) {
    undecided_count = OrientationsFromPlanes(index, test, positive, undecided);
  } else {
    for (std::size_t i = 0; i < face_count; ++i) undecided[i] = static_cast<std::uint32_t>(i);
  }
  for (std::size_t k = 0; k < undecided_count; ++k) {
    const Eigen::Vector3i& f = mesh.faces[undecided[k]];
    positive[undecided[k]] = Positive(point(f[0]), point(f[1]), point(f[2]));
  }
  count.decided = static_cast<int>(face_count - undecided_count);
  // The outline: each positive face's edges to a face that is not, as it runs them.
  std::vector<Segment>& segments = work.segments;
  segments.clear();
  const std::vector<Eigen::Vector3i>& neighbours = index.neighbours();
  const std::uint8_t* is_positive = positive;
  for (std::size_t i = 0; i < face_count; ++i) {
    const Eigen::Vector3i& across = neighbours[i];
    // Positive, with a neighbour that is not (no branch on either alone).
    if (!(is_positive[i] &
          ~(is_positive[across[0]] & is_positive[across[1]] & is_positive[across[2]]))) {
      continue;
    }
    const Eigen::Vector3i& f = mesh.faces[i];
    for (int e = 0; e < 3; ++e) {
      if (!is_positive[across[e]]) {
        segments.push_back({point(f[e]), point(f[(e + 1) % 3])});
      }
    }
  }
  if (!every_face) {
    for (const Segment& segment : segments) {
      lo = lo.cwiseMin(segment.p).cwiseMin(segment.q);
      hi = hi.cwiseMax(segment.p).cwiseMax(segment.q);
    }
  }
  count.outline_edges = static_cast<int>(segments.size());
  return Fill(segments, lo, hi, view, &work.winding, &work.on_outline);
}

namespace {

// The views of a batch, one bit each in a word per face.
using ViewBits = std::uint32_t;
constexpr std::size_t kBatchViews = 32;
// Faces per chunk of a batch: their planes (~22 bytes a face) stay in the core's cache from one
// view to the next.
constexpr std::size_t kBatchFaces = 8192;

// The faces' planes as PlaneBits reads them (OutlineIndex's arrays).
struct FacePlanes {
  const float* nx;
  const float* ny;
  const float* nz;
  const float* offset;
  const float* height;
  const std::uint8_t* shared_axes;
};

// For the faces [begin, end): bit `bit` of positive[i - begin] set when face i's plane decides it
// positive in the view of `test`, of undecided[i - begin] when its plane does not decide it.
// OrientationsFromPlanes's expressions, rounded the same way; one view, every face in a row, on
// vectors (built for AVX2 too where the processor has it: twice as wide, the same values, no
// fused multiply-add).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
void PlaneBits(const FacePlanes& planes, const PlaneTest& test, std::size_t begin,
               std::size_t end, ViewBits bit, ViewBits* __restrict positive,
               ViewBits* __restrict undecided) {
  const float* __restrict nx = planes.nx;
  const float* __restrict ny = planes.ny;
  const float* __restrict nz = planes.nz;
  const float* __restrict offset = planes.offset;
  const float* __restrict height = planes.height;
  const std::uint8_t* __restrict shared_axes = planes.shared_axes;
  const auto [px, py, pz, k, threshold, min_height] = InFloats(test);
  const ViewBits flip = test.flip ? ~ViewBits{0} : 0;
  const std::uint8_t flat_axes = test.flat_axes;
  // All-ones or zero words, no branch: the loop runs on vectors.
  for (std::size_t i = begin; i < end; ++i) {
    const float s = nx[i] * px + ny[i] * py + nz[i] * pz - offset[i] * k;
    const ViewBits flat = (shared_axes[i] & flat_axes) != 0 ? ~ViewBits{0} : 0;
    const ViewBits decided =
        (((std::abs(s) > threshold) & (height[i] > min_height)) ? ~ViewBits{0} : 0) | flat;
    const ViewBits sign = ((s > 0.0f ? ~ViewBits{0} : 0) ^ flip) & ~flat;
    positive[i - begin] |= sign & decided & bit;
    undecided[i - begin] |= ~decided & bit;
  }
}

// SilhouettesFromOutline for the views `batch` (at most kBatchViews; each decided in front by
// the mesh's sphere, its plane test `tests[view]` usable): every face signed in every view of
// the batch chunk by chunk (its plane read once for them all), then the outline edges of every
// view found in one pass over the faces and their neighbours, then each view's outline filled.
// Each view's outline edges in SilhouetteFromOutline's order (faces, then corners).
void SilhouettesOfBatch(const Mesh& mesh, const OutlineIndex& index, const std::vector<View>& views,
                        const std::vector<std::size_t>& batch, const std::vector<PlaneTest>& tests,
                        const SilhouetteSink& use) {
  const std::size_t face_count = mesh.faces.size();
  const std::size_t view_count = batch.size();
  const std::size_t chunk_count = (face_count + kBatchFaces - 1) / kBatchFaces;
  std::vector<ViewBits> positive(face_count, 0);
  const FacePlanes planes{index.normal_x().data(), index.normal_y().data(),
                          index.normal_z().data(), index.offset().data(),
                          index.height().data(),   index.shared_axes().data()};
  tbb::enumerable_thread_specific<std::vector<ViewBits>> undecided_store;
  ParallelFor(0, chunk_count, [&](std::size_t c) {
    const std::size_t begin = c * kBatchFaces;
    const std::size_t end = std::min(face_count, begin + kBatchFaces);
    std::vector<ViewBits>& undecided = undecided_store.local();
    undecided.assign(end - begin, 0);
    ViewBits* chunk = positive.data() + begin;
    for (std::size_t b = 0; b < view_count; ++b) {
      PlaneBits(planes, tests[batch[b]], begin, end, ViewBits{1} << b, chunk, undecided.data());
    }
    // The faces a plane leaves undecided, projected in that view.
    for (std::size_t j = 0; j < end - begin; ++j) {
      for (ViewBits left = undecided[j]; left != 0; left &= left - 1) {
        const int b = std::countr_zero(left);
        const View& view = views[batch[static_cast<std::size_t>(b)]];
        const Eigen::Vector3i& f = mesh.faces[begin + j];
        if (Positive(Projected(view, mesh.vertices[f[0]]), Projected(view, mesh.vertices[f[1]]),
                     Projected(view, mesh.vertices[f[2]]))) {
          chunk[j] |= ViewBits{1} << b;
        }
      }
    }
  });
  // Per chunk and view ([c * view_count + b]): the outline edges, as their positive face runs
  // them (its vertices read here once for every view, in order, not in each view at random).
  std::vector<std::vector<std::array<int, 2>>> outline(chunk_count * view_count);
  const std::vector<Eigen::Vector3i>& neighbours = index.neighbours();
  ParallelFor(0, chunk_count, [&](std::size_t c) {
    const std::size_t begin = c * kBatchFaces;
    const std::size_t end = std::min(face_count, begin + kBatchFaces);
    for (std::size_t i = begin; i < end; ++i) {
      const Eigen::Vector3i& across = neighbours[i];
      const ViewBits a = positive[static_cast<std::size_t>(across[0])];
      const ViewBits b = positive[static_cast<std::size_t>(across[1])];
      const ViewBits d = positive[static_cast<std::size_t>(across[2])];
      // The views where face i is positive with a neighbour that is not.
      ViewBits views_out = positive[i] & ~(a & b & d);
      if (views_out == 0) continue;
      const Eigen::Vector3i& f = mesh.faces[i];
      for (; views_out != 0; views_out &= views_out - 1) {
        const int v = std::countr_zero(views_out);
        std::vector<std::array<int, 2>>& edges =
            outline[c * view_count + static_cast<std::size_t>(v)];
        if (!((a >> v) & 1u)) edges.push_back({f[0], f[1]});
        if (!((b >> v) & 1u)) edges.push_back({f[1], f[2]});
        if (!((d >> v) & 1u)) edges.push_back({f[2], f[0]});
      }
    }
  });
  positive = {};
  tbb::enumerable_thread_specific<OutlineScratch> scratch;
  ParallelFor(0, view_count, [&](std::size_t b) {
    const View& view = views[batch[b]];
    OutlineScratch& work = scratch.local();
    std::vector<Segment>& segments = work.segments;
    segments.clear();
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector2d hi = -lo;
    for (std::size_t c = 0; c < chunk_count; ++c) {
      for (const auto& [from, to] : outline[c * view_count + b]) {
        const Segment segment{Projected(view, mesh.vertices[from]),
                              Projected(view, mesh.vertices[to])};
        lo = lo.cwiseMin(segment.p).cwiseMin(segment.q);
        hi = hi.cwiseMax(segment.p).cwiseMax(segment.q);
        segments.push_back(segment);
      }
    }
    use(batch[b], Fill(segments, lo, hi, view, &work.winding, &work.on_outline));
  });
}

}  // namespace

void SilhouettesFromOutline(const Mesh& mesh, const OutlineIndex& index,
                            const std::vector<View>& views, const SilhouetteSink& use) {
  std::vector<PlaneTest> tests(views.size());
  std::vector<std::size_t> alone;
  std::vector<std::vector<std::size_t>> batches;
  for (std::size_t i = 0; i < views.size(); ++i) {
    if (EveryVertexInFront(index, views[i])) tests[i] = PlaneTestOf(index, views[i]);
    if (!tests[i].usable) {
      alone.push_back(i);
      continue;
    }
    if (batches.empty() || batches.back().size() == kBatchViews) batches.emplace_back();
    batches.back().push_back(i);
  }
  // Views that share their rows (the thesis's) from the mesh's slices, when it can.
  std::vector<std::size_t> batched;
  for (const std::vector<std::size_t>& batch : batches) {
    batched.insert(batched.end(), batch.begin(), batch.end());
  }
  if (SilhouettesFromSlices(mesh, index, views, batched, use)) batches.clear();
  for (const std::vector<std::size_t>& batch : batches) {
    SilhouettesOfBatch(mesh, index, views, batch, tests, use);
  }
  tbb::enumerable_thread_specific<OutlineScratch> scratch;
  ParallelFor(0, alone.size(), [&](std::size_t k) {
    use(alone[k], SilhouetteFromOutline(mesh, index, views[alone[k]], nullptr, &scratch.local()));
  });
}

}  // namespace revolve::reconstruct::outline_internal
