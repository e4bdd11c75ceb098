// SilhouettesFromSlices: the silhouettes of views that share their rows (the thesis's) from the
// mesh's slices along those rows.
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>

#include <tbb/enumerable_thread_specific.h>

#include "reconstruct/metrics/outline_internal.h"
#include "reconstruct/parallel.h"

namespace revolve::reconstruct::outline_internal {
namespace {

// A vertex's row coordinate (as Projected computes it) and its ceiling (at == ceil: on a row).
struct VertexRow {
  double at, ceil;
};

// rows[i] for the vertices [begin, end) in `view` (Homogeneous's second row, written out); built
// for AVX2 too where the processor has it (ceil is an instruction there, a call without it).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
void VertexRows(const View& view, const std::vector<Eigen::Vector3f>& vertices, std::size_t begin,
                std::size_t end, VertexRow* __restrict rows) {
  const Matrix34d& p = view.pixel_from_object;
  const double p0 = p(1, 0), p1 = p(1, 1), p2 = p(1, 2), p3 = p(1, 3);
  for (std::size_t i = begin; i < end; ++i) {
    const Eigen::Vector3f& x = vertices[i];
    const double v = ((p0 * static_cast<double>(x.x()) + p1 * static_cast<double>(x.y())) +
                      p2 * static_cast<double>(x.z())) +
                     p3;
    rows[i] = {v, std::ceil(v)};
  }
}

// The least and greatest u = ((p0 x + p1 y) + p2 z) + p3 (Homogeneous's first row) of the
// points [0, count) (count > 0), into *lo and *hi: four running extremes of the sum before p3,
// so that the loop runs on vectors (built for AVX2 too where the processor has it), and p3 added
// to the two extremes (the same values: adding p3 and rounding never reverses an order). The
// points are finite, and which of two equal values (or zeros) is kept does not matter.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
void ExtentOfPoints(const double* row0, const double* __restrict x, const double* __restrict y,
                    const double* __restrict z, std::size_t count, double* lo, double* hi) {
  const double p0 = row0[0], p1 = row0[1], p2 = row0[2], p3 = row0[3];
  constexpr int kLanes = 4;
  double least[kLanes], most[kLanes];
  for (int k = 0; k < kLanes; ++k) {
    least[k] = std::numeric_limits<double>::infinity();
    most[k] = -std::numeric_limits<double>::infinity();
  }
  std::size_t i = 0;
  for (; i + kLanes <= count; i += kLanes) {
    for (int k = 0; k < kLanes; ++k) {
      const double u = (p0 * x[i + k] + p1 * y[i + k]) + p2 * z[i + k];
      least[k] = u < least[k] ? u : least[k];
      most[k] = u > most[k] ? u : most[k];
    }
  }
  for (; i < count; ++i) {
    const double u = (p0 * x[i] + p1 * y[i]) + p2 * z[i];
    least[0] = u < least[0] ? u : least[0];
    most[0] = u > most[0] ? u : most[0];
  }
  *lo = std::min({least[0], least[1], least[2], least[3]}) + p3;
  *hi = std::max({most[0], most[1], most[2], most[3]}) + p3;
}

// Whether a row coordinate p..q edge (either order) is crossed by row r: the fill's rule, rows
// min <= r < max.
bool Crosses(double p, double q, double r) { return std::min(p, q) <= r && r < std::max(p, q); }

// One row's slices: the points where the mesh's edges cross it, cycle after cycle (each cycle
// a closed loop of the faces that cross the row, its points in cycle_end's ranges).
struct RowSlices {
  std::vector<double> x, y, z;
  std::vector<std::uint32_t> cycle_end;
};

// A vertex (a = b) or an edge a - b on row `row` with nothing of the mesh just below it.
struct Bottom {
  int row, a, b;
};

class Slicer {
 public:
  Slicer(const Mesh& mesh, const std::vector<Eigen::Vector3i>& neighbours, const View& view,
         int rows)
      : mesh_(mesh), neighbours_(neighbours), rows_(rows) {
    row_.resize(mesh.vertices.size());
    ParallelChunks(0, row_.size(), 16384, [&](std::size_t lo, std::size_t hi) {
      VertexRows(view, mesh.vertices, lo, hi, row_.data());
    });
  }

  // What lies on a row with nothing of the mesh just below it: vertices with no edge down from
  // them (a = b), and edges both of whose faces lie on or above the row (a != b). On such a row
  // the fill also sets the pixels the outline runs through, which the slices below the row need
  // not hold (SilhouetteOfSlices checks them in each view).
  std::vector<Bottom> BottomsOnRows() const {
    const std::size_t n = mesh_.vertices.size();
    const std::size_t face_count = mesh_.faces.size();
    std::vector<std::uint8_t> down(n, 0);
    const auto below = [&](std::size_t face, int c, double r) {
      return row_[static_cast<std::size_t>(mesh_.faces[face][(c + 2) % 3])].at > r;
    };
    // In chunks of faces on all cores: the corners on a row with a corner of the face below them
    // marked, and the edges on a row neither of whose faces goes below it (found from the face
    // of the lower index), each chunk's in face order.
    constexpr std::size_t kChunk = 16384;
    std::vector<std::vector<Bottom>> edges((face_count + kChunk - 1) / kChunk);
    ParallelFor(0, edges.size(), [&](std::size_t chunk) {
      const std::size_t end = std::min(face_count, (chunk + 1) * kChunk);
      for (std::size_t i = chunk * kChunk; i < end; ++i) {
        const Eigen::Vector3i& f = mesh_.faces[i];
        for (int c = 0; c < 3; ++c) {
          const VertexRow& r = row_[static_cast<std::size_t>(f[c])];
          if (r.at != r.ceil || !OnImageRow(r.at)) continue;
          const double next = row_[static_cast<std::size_t>(f[(c + 1) % 3])].at;
          if (next > r.at || below(i, c, r.at)) {
            std::atomic_ref<std::uint8_t>(down[static_cast<std::size_t>(f[c])])
                .store(1, std::memory_order_relaxed);
          }
          if (next != r.at || below(i, c, r.at)) continue;
          // The face across runs b -> a: whether it goes below.
          const int a = f[c];
          const int b = f[(c + 1) % 3];
          const auto g = static_cast<std::size_t>(neighbours_[i][c]);
          if (g < i) continue;  // seen from there (or from here, once)
          bool g_below = false;
          for (int e = 0; e < 3; ++e) {
            if (mesh_.faces[g][e] == b && mesh_.faces[g][(e + 1) % 3] == a) {
              g_below = below(g, e, r.at);
            }
          }
          if (!g_below) edges[chunk].push_back({static_cast<int>(r.at), a, b});
        }
      }
    });
    std::vector<Bottom> bottoms;
    for (std::size_t i = 0; i < n; ++i) {
      if (row_[i].at == row_[i].ceil && OnImageRow(row_[i].at) && down[i] == 0) {
        bottoms.push_back({static_cast<int>(row_[i].at), static_cast<int>(i), static_cast<int>(i)});
      }
    }
    for (const std::vector<Bottom>& chunk : edges) {
      bottoms.insert(bottoms.end(), chunk.begin(), chunk.end());
    }
    return bottoms;
  }

  // Each image row's slices; false when a face's loop does not close as a closed, consistently
  // oriented mesh's must.
  bool Slice(std::vector<RowSlices>* out) {
    const std::size_t face_count = mesh_.faces.size();
    // The rows each face crosses, [first_row, first_row + row_count), numbered face by face.
    std::vector<int> first_row(face_count);
    std::vector<std::uint32_t> row_count(face_count);
    ParallelChunks(0, face_count, 16384, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) {
        const Eigen::Vector3i& f = mesh_.faces[i];
        const double a = row_[static_cast<std::size_t>(f[0])].ceil;
        const double b = row_[static_cast<std::size_t>(f[1])].ceil;
        const double c = row_[static_cast<std::size_t>(f[2])].ceil;
        // Rows min <= r < max, within the image: from ceil(min) = min(ceil), the corners' (the
        // ceiling never decreases), and the same for max.
        const double first = std::max(std::min({a, b, c}), 0.0);
        const double last = std::min(std::max({a, b, c}) - 1.0, rows_ - 1.0);
        first_row[i] = first <= last ? static_cast<int>(first) : 0;
        row_count[i] = first <= last ? static_cast<std::uint32_t>(last - first) + 1 : 0;
      }
    });
    // Face i's pairs are numbered from `pairs` on, row first_row[i] first.
    pair_base_.resize(face_count);
    std::int64_t pairs = 0;
    for (std::size_t i = 0; i < face_count; ++i) {
      pair_base_[i] = pairs - first_row[i];
      pairs += row_count[i];
    }
    // The faces of each row, in face order.
    std::vector<std::uint32_t> row_start(static_cast<std::size_t>(rows_) + 1, 0);
    for (std::size_t i = 0; i < face_count; ++i) {
      for (std::uint32_t k = 0; k < row_count[i]; ++k) {
        ++row_start[static_cast<std::size_t>(first_row[i]) + k + 1];
      }
    }
    for (int r = 0; r < rows_; ++r) row_start[r + 1] += row_start[r];
    std::vector<std::uint32_t> row_faces(row_start.back());
    {
      std::vector<std::uint32_t> next(row_start.begin(), row_start.end() - 1);
      for (std::size_t i = 0; i < face_count; ++i) {
        for (std::uint32_t k = 0; k < row_count[i]; ++k) {
          row_faces[next[static_cast<std::size_t>(first_row[i]) + k]++] =
              static_cast<std::uint32_t>(i);
        }
      }
    }
    visited_.assign(static_cast<std::size_t>(pairs), 0);
    out->assign(static_cast<std::size_t>(rows_), RowSlices());
    std::atomic<bool> closed = true;
    ParallelFor(0, static_cast<std::size_t>(rows_), [&](std::size_t r) {
      RowSlices& slices = (*out)[r];
      // A point per face crossing the row (each face of a loop leaves it by one edge).
      const std::uint32_t faces = row_start[r + 1] - row_start[r];
      for (std::vector<double>* v : {&slices.x, &slices.y, &slices.z}) v->reserve(faces);
      for (std::uint32_t k = row_start[r]; k < row_start[r + 1] && closed.load(); ++k) {
        const std::uint32_t face = row_faces[k];
        if (visited_[Pair(face, static_cast<int>(r))] != 0) continue;
        if (!Loop(face, static_cast<int>(r), row_start[r + 1] - row_start[r], &slices)) {
          closed.store(false);
        }
      }
    });
    return closed.load();
  }

 private:
  bool OnImageRow(double v) const { return v >= 0.0 && v <= rows_ - 1.0; }

  std::size_t Pair(std::uint32_t face, int r) const {
    return static_cast<std::size_t>(pair_base_[face] + r);
  }

  // The corners c of `face` whose edge c -> c + 1 row r crosses, into corner[0] < corner[1];
  // false unless there are two.
  bool CrossingEdges(std::uint32_t face, double r, int* corner) const {
    const Eigen::Vector3i& f = mesh_.faces[face];
    int found = 0;
    for (int c = 0; c < 3; ++c) {
      if (!Crosses(row_[static_cast<std::size_t>(f[c])].at,
                   row_[static_cast<std::size_t>(f[(c + 1) % 3])].at, r)) {
        continue;
      }
      if (found == 2) return false;
      corner[found++] = c;
    }
    return found == 2;
  }

  // The loop through `start` of the faces crossing row r, its points appended to *slices as one
  // cycle (each edge's crossing once, from its lower vertex index so that it is the same point
  // from either face); false when it does not close within `limit` faces. A face entered across
  // edge b -> a (as it runs it) with third corner t leaves across a -> t or t -> b, whichever
  // row r crosses: the fill's rule makes exactly one of them cross it when b -> a does.
  bool Loop(std::uint32_t start, int r, std::uint32_t limit, RowSlices* slices) {
    const auto row = static_cast<double>(r);
    int corner[2];
    if (!CrossingEdges(start, row, corner)) return false;
    visited_[Pair(start, r)] = 1;
    std::uint32_t face = start;
    const int start_exit = corner[0];
    int exit = start_exit;
    for (std::uint32_t steps = 0; steps < limit; ++steps) {
      const Eigen::Vector3i& f = mesh_.faces[face];
      const int a = f[exit];
      const int b = f[(exit + 1) % 3];
      AddCrossing(std::min(a, b), std::max(a, b), row, slices);
      const int next = neighbours_[face][exit];
      if (next < 0) return false;
      const auto g = static_cast<std::uint32_t>(next);
      // g runs the edge b -> a from its corner c: where b is (once: a face of a closed mesh
      // repeats no vertex).
      const Eigen::Vector3i& h = mesh_.faces[g];
      const int c = h[0] == b ? 0 : (h[1] == b ? 1 : 2);
      if (h[c] != b || h[(c + 1) % 3] != a) return false;
      if (g == start) {
        // Back at the start, through its other crossing edge.
        if (c != corner[1]) return false;
        slices->cycle_end.push_back(static_cast<std::uint32_t>(slices->x.size()));
        return true;
      }
      const double va = row_[static_cast<std::size_t>(a)].at;
      const double vb = row_[static_cast<std::size_t>(b)].at;
      const double vt = row_[static_cast<std::size_t>(h[(c + 2) % 3])].at;
      const bool to_t = Crosses(va, vt, row);
      if (to_t == Crosses(vt, vb, row)) return false;
      std::uint8_t& seen = visited_[Pair(g, r)];
      if (seen != 0) return false;
      seen = 1;
      face = g;
      exit = (c + (to_t ? 1 : 2)) % 3;
    }
    return false;
  }

  // The point where edge a - b (a < b) crosses row coordinate r.
  void AddCrossing(int a, int b, double r, RowSlices* slices) const {
    const Eigen::Vector3f& pa = mesh_.vertices[static_cast<std::size_t>(a)];
    const Eigen::Vector3f& pb = mesh_.vertices[static_cast<std::size_t>(b)];
    const double va = row_[static_cast<std::size_t>(a)].at;
    const double vb = row_[static_cast<std::size_t>(b)].at;
    const double t = (r - va) / (vb - va);
    const auto along = [t](float p, float q) {
      return static_cast<double>(p) + t * (static_cast<double>(q) - static_cast<double>(p));
    };
    slices->x.push_back(along(pa.x(), pb.x()));
    slices->y.push_back(along(pa.y(), pb.y()));
    slices->z.push_back(along(pa.z(), pb.z()));
  }

  const Mesh& mesh_;
  const std::vector<Eigen::Vector3i>& neighbours_;
  int rows_;
  std::vector<VertexRow> row_;
  // Face f's (face, row) pair for row r, an index of visited_: pair_base_[f] + r.
  std::vector<std::int64_t> pair_base_;
  std::vector<std::uint8_t> visited_;
};

// View `view`'s silhouette from the slices (its extents at `slot` of `view_count`): on each row,
// the pixels between the least and the greatest u of each cycle (ends included). nullopt when a
// bottom's pixel (a pixel centre within 1e-6 px of where the bottom's vertex or edge projects) is
// not one of them: the fill may set it. Each row's loops' least and greatest u in each view:
// [r][(loop * views + k) * 2] and [.. + 1] for views[which[k]]. Row by row on all cores, each
// loop's points read once for all the views (they stay in the core's cache; the views' passes over
// all the points would each read them from memory).
std::vector<std::vector<double>> Extents(const std::vector<RowSlices>& rows,
                                         const std::vector<View>& views,
                                         const std::vector<std::size_t>& which) {
  std::vector<std::array<double, 4>> row0(which.size());
  for (std::size_t k = 0; k < which.size(); ++k) {
    const Matrix34d& p = views[which[k]].pixel_from_object;
    row0[k] = {p(0, 0), p(0, 1), p(0, 2), p(0, 3)};
  }
  std::vector<std::vector<double>> extents(rows.size());
  ParallelFor(0, rows.size(), [&](std::size_t r) {
    const RowSlices& slices = rows[r];
    std::vector<double>& out = extents[r];
    out.resize(slices.cycle_end.size() * which.size() * 2);
    std::uint32_t begin = 0;
    std::size_t at = 0;
    for (const std::uint32_t end : slices.cycle_end) {
      for (std::size_t k = 0; k < which.size(); ++k, at += 2) {
        ExtentOfPoints(row0[k].data(), slices.x.data() + begin, slices.y.data() + begin,
                       slices.z.data() + begin, end - begin, &out[at], &out[at + 1]);
      }
      begin = end;
    }
  });
  return extents;
}

std::optional<BoxedSilhouette> SilhouetteOfSlices(const Mesh& mesh,
                                                  const std::vector<RowSlices>& rows,
                                                  const std::vector<std::vector<double>>& extents,
                                                  std::size_t slot, std::size_t view_count,
                                                  const std::vector<Bottom>& bottoms,
                                                  const View& view) {
  struct Run {
    int row, first, last;
  };
  std::vector<Run> runs;
  std::vector<std::uint32_t> row_runs(rows.size() + 1, 0);  // runs of row r: [row_runs[r], [r + 1])
  const int height = std::min(view.height_px, static_cast<int>(rows.size()));
  for (int r = 0; r < height; ++r) {
    const std::size_t loops = rows[static_cast<std::size_t>(r)].cycle_end.size();
    const std::vector<double>& extent = extents[static_cast<std::size_t>(r)];
    for (std::size_t loop = 0; loop < loops; ++loop) {
      const double lo = extent[(loop * view_count + slot) * 2];
      const double hi = extent[(loop * view_count + slot) * 2 + 1];
      const double first = std::max(std::ceil(lo), 0.0);
      const double last = std::min(std::floor(hi), view.width_px - 1.0);
      if (first <= last) runs.push_back({r, static_cast<int>(first), static_cast<int>(last)});
    }
    row_runs[static_cast<std::size_t>(r) + 1] = static_cast<std::uint32_t>(runs.size());
  }
  for (int r = height; r < static_cast<int>(rows.size()); ++r) {
    row_runs[static_cast<std::size_t>(r) + 1] = static_cast<std::uint32_t>(runs.size());
  }
  for (const Bottom& bottom : bottoms) {
    if (bottom.row >= height) continue;
    const double ua = Homogeneous(view, mesh.vertices[static_cast<std::size_t>(bottom.a)]).x();
    const double ub = Homogeneous(view, mesh.vertices[static_cast<std::size_t>(bottom.b)]).x();
    const double first = std::max(std::ceil(std::min(ua, ub) - 1e-6), 0.0);
    const double last = std::min(std::floor(std::max(ua, ub) + 1e-6), view.width_px - 1.0);
    for (double u = first; u <= last; ++u) {
      bool covered = false;
      for (std::uint32_t k = row_runs[static_cast<std::size_t>(bottom.row)];
           k < row_runs[static_cast<std::size_t>(bottom.row) + 1] && !covered; ++k) {
        covered = runs[k].first <= u && u <= runs[k].last;
      }
      if (!covered) return std::nullopt;
    }
  }
  BoxedSilhouette result;
  if (runs.empty()) return result;
  int left = runs[0].first, right = runs[0].last;
  for (const Run& run : runs) {
    left = std::min(left, run.first);
    right = std::max(right, run.last);
  }
  const int top = runs.front().row;
  const int bottom = runs.back().row;
  result.box = cv::Rect(left, top, right - left + 1, bottom - top + 1);
  result.pixels = cv::Mat(result.box.size(), CV_8UC1, cv::Scalar(0));
  for (const Run& run : runs) {
    std::uint8_t* row = result.pixels.ptr<std::uint8_t>(run.row - top);
    std::fill(row + (run.first - left), row + (run.last - left) + 1, std::uint8_t{255});
  }
  return result;
}

}  // namespace

bool ShareTheirRows(const std::vector<View>& views, const std::vector<std::size_t>& which) {
  if (which.empty()) return false;
  const Eigen::RowVector4d affine(0.0, 0.0, 0.0, 1.0);
  const Eigen::RowVector4d row = views[which[0]].pixel_from_object.row(1);
  return std::all_of(which.begin(), which.end(), [&](std::size_t i) {
    const Matrix34d& p = views[i].pixel_from_object;
    return p.row(2) == affine && p.row(1) == row && p.allFinite();
  });
}

bool SilhouettesFromSlices(const Mesh& mesh, const OutlineIndex& index,
                           const std::vector<View>& views, const std::vector<std::size_t>& which,
                           const SilhouetteSink& use) {
  if (!ShareTheirRows(views, which) || !index.finite() || !index.closed()) return false;
  int rows = 0;
  for (const std::size_t i : which) rows = std::max(rows, views[i].height_px);
  Slicer slicer(mesh, index.neighbours(), views[which[0]], rows);
  std::vector<RowSlices> slices;
  if (!slicer.Slice(&slices)) return false;
  const std::vector<Bottom> bottoms = slicer.BottomsOnRows();
  const std::vector<std::vector<double>> extents = Extents(slices, views, which);
  // A view whose bottoms the slices do not cover is searched for its outline instead.
  tbb::enumerable_thread_specific<OutlineScratch> scratch;
  ParallelFor(0, which.size(), [&](std::size_t k) {
    const View& view = views[which[k]];
    std::optional<BoxedSilhouette> silhouette =
        SilhouetteOfSlices(mesh, slices, extents, k, which.size(), bottoms, view);
    if (!silhouette) {
      silhouette = SilhouetteFromOutline(mesh, index, view, nullptr, &scratch.local());
    }
    use(which[k], std::move(silhouette));
  });
  return true;
}

}  // namespace revolve::reconstruct::outline_internal
