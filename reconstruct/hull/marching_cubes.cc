#include "reconstruct/hull/marching_cubes.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cstring>
#include <limits>
#include <numeric>

#include <tbb/enumerable_thread_specific.h>
#include <Eigen/Geometry>

#include "reconstruct/parallel.h"
#include "reconstruct/union_find.h"

namespace revolve::reconstruct {

BitVolume::BitVolume(const Eigen::Vector3i& dims) : dims_(dims.cwiseMax(0)) {
  words_per_row_ = (dims_.x() + 63) / 64;
  words_.assign(static_cast<std::size_t>(words_per_row_) * dims_.y() * dims_.z(), 0);
}

std::int64_t BitVolume::Count() const {
  std::int64_t count = 0;
  for (std::uint64_t w : words_) {
    count += std::popcount(w);
  }
  return count;
}

bool BitVolume::Any() const {
  return std::any_of(words_.begin(), words_.end(), [](std::uint64_t w) { return w != 0; });
}

namespace {

// ---------------------------------------------------------------------------------------------
// The case table, generated at first use from the rule in the header. Corner c of a cell is at
// (c & 1, (c >> 1) & 1, (c >> 2) & 1). Edge e runs along axis e / 4 from kEdges[e].lower_corner
// to kEdges[e].upper_corner; the lower corner's other two coordinates are (e & 1, (e >> 1) & 1)
// in increasing axis order.

struct CubeEdge {
  int axis;
  int lower_corner;
  int upper_corner;
};

constexpr std::array<CubeEdge, 12> MakeEdges() {
  std::array<CubeEdge, 12> edges{};
  for (int e = 0; e < 12; ++e) {
    const int axis = e / 4;
    const int b0 = e & 1;
    const int b1 = (e >> 1) & 1;
    int c = 0;
    if (axis == 0) {
      c = (b0 << 1) | (b1 << 2);
    }
    if (axis == 1) {
      c = b0 | (b1 << 2);
    }
    if (axis == 2) {
      c = b0 | (b1 << 1);
    }
    edges[e] = CubeEdge{axis, c, c | (1 << axis)};
  }
  return edges;
}
constexpr std::array<CubeEdge, 12> kEdges = MakeEdges();

int EdgeBetween(int c0, int c1) {
  for (int e = 0; e < 12; ++e) {
    if ((kEdges[e].lower_corner == c0 && kEdges[e].upper_corner == c1) ||
        (kEdges[e].lower_corner == c1 && kEdges[e].upper_corner == c0)) {
      return e;
    }
  }
  return -1;
}

Eigen::Vector3d CornerPosition(int c) { return Eigen::Vector3d(c & 1, (c >> 1) & 1, (c >> 2) & 1); }
Eigen::Vector3d EdgeMidpoint(int e) {
  return 0.5 * (CornerPosition(kEdges[e].lower_corner) + CornerPosition(kEdges[e].upper_corner));
}

// True when edges e and f lie on a common face of the cell.
bool ShareFace(int e, int f) {
  const Eigen::Vector3d a = EdgeMidpoint(e);
  const Eigen::Vector3d b = EdgeMidpoint(f);
  for (int axis = 0; axis < 3; ++axis) {
    if (axis == kEdges[e].axis || axis == kEdges[f].axis) {
      continue;
    }
    if (a[axis] == b[axis]) {
      return true;
    }
  }
  return false;
}

struct CaseTable {
  static constexpr std::uint8_t kEnd = 0xFF;
  // Triangles of each case as local edge triples, terminated by kEnd.
  std::array<std::array<std::uint8_t, 3 * 12 + 1>, 256> triangles;
};

// Minimum-total-chord triangulation of a loop with no chord joining two same-face vertices.
// Appends triangles (same orientation as the loop) to `out`.
void TriangulateLoop(const std::vector<int>& loop, std::vector<int>* out) {
  const int n = static_cast<int>(loop.size());
  constexpr double kInvalid = std::numeric_limits<double>::infinity();
  auto chord = [&](int i, int j) {
    if (j - i == 1 || (i == 0 && j == n - 1)) {
      return 0.0;  // a side of the loop
    }
    if (ShareFace(loop[i], loop[j])) {
      return kInvalid;
    }
    return (EdgeMidpoint(loop[i]) - EdgeMidpoint(loop[j])).norm();
  };
  std::vector<std::vector<double>> cost(n, std::vector<double>(n, 0.0));
  std::vector<std::vector<int>> split(n, std::vector<int>(n, -1));
  for (int len = 2; len < n; ++len) {
    for (int i = 0; i + len < n; ++i) {
      const int j = i + len;
      cost[i][j] = kInvalid;
      const double own = chord(i, j);
      if (own == kInvalid) {
        continue;
      }
      for (int k = i + 1; k < j; ++k) {
        const double c = cost[i][k] + cost[k][j] + own;
        if (c < cost[i][j]) {
          cost[i][j] = c;
          split[i][j] = k;
        }
      }
    }
  }
  if (n < 3 || cost[0][n - 1] == kInvalid) {
    // The rule always admits one; marching_cubes_test builds and checks all 256 cases.
    std::abort();
  }
  std::vector<std::pair<int, int>> stack = {{0, n - 1}};
  while (!stack.empty()) {
    auto [i, j] = stack.back();
    stack.pop_back();
    if (j - i < 2) {
      continue;
    }
    const int k = split[i][j];
    out->insert(out->end(), {loop[i], loop[k], loop[j]});
    stack.push_back({i, k});
    stack.push_back({k, j});
  }
}

CaseTable BuildCaseTable() {
  CaseTable table{};
  for (int config = 0; config < 256; ++config) {
    auto inside = [&](int c) { return ((config >> c) & 1) != 0; };
    std::array<int, 12> next;
    next.fill(-1);
    for (int axis = 0; axis < 3; ++axis) {
      const int a1 = (axis + 1) % 3;
      const int a2 = (axis + 2) % 3;
      for (int side = 0; side < 2; ++side) {
        // Corners of this face in cyclic order.
        std::array<int, 4> ring;
        const int steps[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
        for (int r = 0; r < 4; ++r) {
          ring[r] = (side << axis) | (steps[r][0] << a1) | (steps[r][1] << a2);
        }
        Eigen::Vector3d normal = Eigen::Vector3d::Zero();
        normal[axis] = side ? 1.0 : -1.0;
        for (int r = 0; r < 4; ++r) {
          const int prev = (r + 3) % 4;
          if (!inside(ring[r]) || inside(ring[prev])) {
            continue;  // not the start of a run
          }
          int end = r;
          while (inside(ring[(end + 1) % 4])) {
            end = (end + 1) % 4;
          }
          int a = EdgeBetween(ring[prev], ring[r]);
          int b = EdgeBetween(ring[end], ring[(end + 1) % 4]);
          const Eigen::Vector3d pa = EdgeMidpoint(a);
          const Eigen::Vector3d pb = EdgeMidpoint(b);
          const Eigen::Vector3d pc = CornerPosition(ring[r]);
          if ((pb - pa).cross(pc - pa).dot(normal) > 0.0) {
            std::swap(a, b);
          }
          if (next[a] != -1) {
            std::abort();
          }
          next[a] = b;
        }
      }
    }
    std::vector<int> triangles;
    std::array<bool, 12> used{};
    for (int start = 0; start < 12; ++start) {
      if (next[start] == -1 || used[start]) {
        continue;
      }
      std::vector<int> loop;
      for (int e = start; !used[e]; e = next[e]) {
        used[e] = true;
        loop.push_back(e);
        if (next[e] == -1) {
          std::abort();
        }
      }
      TriangulateLoop(loop, &triangles);
    }
    auto& row = table.triangles[config];
    std::fill(row.begin(), row.end(), CaseTable::kEnd);
    for (std::size_t i = 0; i < triangles.size(); ++i) {
      row[i] = static_cast<std::uint8_t>(triangles[i]);
    }
  }
  return table;
}

const CaseTable& Table() {
  static const CaseTable table = BuildCaseTable();
  return table;
}

// ---------------------------------------------------------------------------------------------

}  // namespace

namespace {

// The connected components (through shared vertices) of `faces` over `vertex_count` vertices:
// the sets, how many there are, and the root of the one with the most triangles (ties: the first
// found); one component needs no more.
struct Components {
  UnionFind sets{0};
  int count = 0;
  int largest_root = -1;
};
Components FindComponents(const std::vector<Eigen::Vector3i>& faces, int vertex_count) {
  Components out;
  if (faces.empty()) return out;
  UnionFind& sets = out.sets;
  sets = UnionFind(vertex_count);
  for (const Eigen::Vector3i& f : faces) {
    sets.Unite(f[0], f[1]);
    sets.Unite(f[1], f[2]);
  }
  // One set (the common case): one component, nothing to drop.
  int roots = 0;
  for (int v = 0; v < vertex_count && roots < 2; ++v) roots += sets.parent[v] == v ? 1 : 0;
  if (roots == 1) {
    out.count = 1;
    return out;
  }
  std::vector<int> triangles_of_root(vertex_count, 0);
  for (const Eigen::Vector3i& f : faces) {
    ++triangles_of_root[sets.Find(f[0])];
  }
  for (int v = 0; v < vertex_count; ++v) {
    if (triangles_of_root[v] == 0) {
      continue;
    }
    ++out.count;
    if (out.largest_root < 0 || triangles_of_root[v] > triangles_of_root[out.largest_root]) {
      out.largest_root = v;
    }
  }
  return out;
}

// KeepLargestComponent with the mesh's components found.
int KeepComponent(Components& found, Mesh* mesh) {
  if (found.count <= 1) {
    return found.count;
  }
  const int vertex_count = static_cast<int>(mesh->vertices.size());
  const int best_root = found.largest_root;
  UnionFind& sets = found.sets;
  std::vector<int> new_index(vertex_count, -1);
  Mesh kept;
  const bool colors = mesh->HasColors();
  const bool normals = mesh->HasNormals();
  const bool uv_faces = mesh->uv_faces.size() == mesh->faces.size();
  kept.uvs = mesh->uvs;
  kept.texture = mesh->texture;
  for (std::size_t i = 0; i < mesh->faces.size(); ++i) {
    const Eigen::Vector3i& f = mesh->faces[i];
    if (sets.Find(f[0]) != best_root) {
      continue;
    }
    if (uv_faces) {
      kept.uv_faces.push_back(mesh->uv_faces[i]);
    }
    Eigen::Vector3i g;
    for (int c = 0; c < 3; ++c) {
      int& idx = new_index[f[c]];
      if (idx < 0) {
        idx = static_cast<int>(kept.vertices.size());
        kept.vertices.push_back(mesh->vertices[f[c]]);
        if (colors) {
          kept.colors.push_back(mesh->colors[f[c]]);
        }
        if (normals) {
          kept.normals.push_back(mesh->normals[f[c]]);
        }
      }
      g[c] = idx;
    }
    kept.faces.push_back(g);
  }
  *mesh = std::move(kept);
  return found.count;
}

}  // namespace

int KeepLargestComponent(Mesh* mesh) {
  Components found = FindComponents(mesh->faces, static_cast<int>(mesh->vertices.size()));
  return KeepComponent(found, mesh);
}

namespace {

// A copy of `field` padded by one empty sample on every side: padded sample p is field sample
// p - 1.
BitVolume Padded(const BitVolume& field) {
  const Eigen::Vector3i& dims = field.dims();
  BitVolume padded(dims + Eigen::Vector3i::Constant(2));
  const int src_words = field.words_per_row();
  for (int k = 0; k < dims.z(); ++k) {
    for (int j = 0; j < dims.y(); ++j) {
      const std::uint64_t* src = field.Row(j, k);
      std::uint64_t* dst = padded.Row(j + 1, k + 1);
      std::uint64_t carry = 0;
      for (int w = 0; w < src_words; ++w) {
        dst[w] = (src[w] << 1) | carry;
        carry = src[w] >> 63;
      }
      if (src_words < padded.words_per_row()) {
        dst[src_words] = carry;
      }
    }
  }
  return padded;
}

// mesh->vertices: one per cut edge, at origin + spacing * (inside + t (outside - inside)) with
// t from `crossings` (clamped to [0, 1]; the midpoint without them, or when they do not give
// one per edge).
void PlaceVertices(const std::vector<GridEdge>& cut_edges, const Eigen::Vector3d& origin,
                   double spacing, const EdgeCrossings& crossings, Mesh* mesh) {
  std::vector<double> t;
  if (crossings) {
    t = crossings(cut_edges);
  }
  if (t.size() != cut_edges.size()) {
    t.assign(cut_edges.size(), 0.5);
  }
  mesh->vertices.resize(cut_edges.size());
  ParallelChunks(0, cut_edges.size(), 16384, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t v = lo; v < hi; ++v) {
      const GridEdge& edge = cut_edges[v];
      const double tv = std::clamp(t[v], 0.0, 1.0);
      const Eigen::Vector3d position =
          origin +
          spacing * (edge.inside.cast<double>() + tv * (edge.outside - edge.inside).cast<double>());
      mesh->vertices[v] = position.cast<float>();
    }
  });
}

}  // namespace

namespace {

// Layers of cells per task of MarchingCubes: a fixed number, so the slabs (and so the mesh) do
// not depend on the threads.
constexpr int kSlabLayers = 16;

// A triangle corner on an x or y edge of a slab's first plane, which the slab below makes:
// kForeign - (cell * 2 + axis), resolved once every slab is done.
constexpr int kForeign = -2;

// Vertex ids of the edges around a layer of cells: x and y edges on the planes z = pz (parity
// pz & 1) and z = pz + 1, z edges between them; -1 = not made yet. The slots set in each, so a
// plane is reset by undoing them rather than by filling it (most cells of a layer are empty).
// One per thread, kept across its slabs.
struct EdgePlanes {
  std::array<std::vector<int>, 2> x, y;
  std::vector<int> z;
  std::array<std::vector<std::int64_t>, 2> x_set, y_set;
  std::vector<std::int64_t> z_set;

  explicit EdgePlanes(std::int64_t plane_size)
      : x{std::vector<int>(plane_size, -1), std::vector<int>(plane_size, -1)},
        y(x),
        z(plane_size, -1) {}
  static void Reset(std::vector<int>* plane, std::vector<std::int64_t>* set) {
    for (std::int64_t cell : *set) (*plane)[cell] = -1;
    set->clear();
  }
};

// What one slab of layers made: its cut edges (its vertices, numbered from 0 in the order made),
// its triangles (kForeign corners for the edges of its first plane), and the (cell, vertex)
// pairs of the x and y edges of the plane above its last layer.
struct Slab {
  std::vector<GridEdge> edges;
  std::vector<Eigen::Vector3i> faces;
  std::array<std::vector<std::pair<std::int64_t, int>>, 2> top;
};

// The cells of layers [z0, z1) of `padded` (the field with an empty border), as MarchingCubes
// makes them one layer after another; `planes` is all -1 before and after.
Slab MarchSlab(const BitVolume& padded, const CaseTable& table, int z0, int z1,
               EdgePlanes* planes) {
  Slab out;
  const Eigen::Vector3i& n = padded.dims();
  // A new vertex on the edge from padded sample (x, y, z) one step along `axis`.
  // `first_inside`: padded sample (x, y, z) is set.
  auto make_vertex = [&](int x, int y, int z, int axis, bool first_inside) {
    // In field coordinates (padded - 1) the edge runs from (x, y, z) - 1 one step along `axis`
    // (u); `in` is 1 when its second end, not its first, is the inside sample.
    const int ux = axis == 0 ? 1 : 0, uy = axis == 1 ? 1 : 0, uz = axis == 2 ? 1 : 0;
    const int in = first_inside ? 0 : 1;
    const int out_end = 1 - in;
    GridEdge& edge = out.edges.emplace_back();
    edge.inside = Eigen::Vector3i(x - 1 + in * ux, y - 1 + in * uy, z - 1 + in * uz);
    edge.outside =
        Eigen::Vector3i(x - 1 + out_end * ux, y - 1 + out_end * uy, z - 1 + out_end * uz);
    return static_cast<int>(out.edges.size() - 1);
  };
  const int words = padded.words_per_row();
  const int last_cell = n.x() - 2;  // cells px in [0, n.x() - 1)
  for (int pz = z0; pz < z1; ++pz) {
    std::vector<int>& x_lo = planes->x[pz & 1];
    std::vector<int>& y_lo = planes->y[pz & 1];
    std::vector<int>& x_hi = planes->x[(pz + 1) & 1];
    std::vector<int>& y_hi = planes->y[(pz + 1) & 1];
    EdgePlanes::Reset(&x_hi, &planes->x_set[(pz + 1) & 1]);
    EdgePlanes::Reset(&y_hi, &planes->y_set[(pz + 1) & 1]);
    EdgePlanes::Reset(&planes->z, &planes->z_set);
    // The edges of plane z0 are the slab below's (but the field's first plane's).
    const bool lo_foreign = pz == z0 && z0 > 0;
    for (int py = 0; py + 1 < n.y(); ++py) {
      const std::uint64_t* rows[4] = {padded.Row(py, pz), padded.Row(py + 1, pz),
                                      padded.Row(py, pz + 1), padded.Row(py + 1, pz + 1)};
      for (int w = 0; w < words; ++w) {
        auto word_of = [&](int r, int ww) { return ww < words ? rows[r][ww] : std::uint64_t{0}; };
        const std::uint64_t here[4] = {word_of(0, w), word_of(1, w), word_of(2, w), word_of(3, w)};
        const std::uint64_t next[4] = {word_of(0, w + 1), word_of(1, w + 1), word_of(2, w + 1),
                                       word_of(3, w + 1)};
        const std::uint64_t any = here[0] | here[1] | here[2] | here[3];
        const std::uint64_t all = here[0] & here[1] & here[2] & here[3];
        const std::uint64_t any_next = next[0] | next[1] | next[2] | next[3];
        const std::uint64_t all_next = next[0] & next[1] & next[2] & next[3];
        const std::uint64_t any_cell = any | (any >> 1) | (any_next << 63);
        const std::uint64_t all_cell = all & ((all >> 1) | (all_next << 63));
        std::uint64_t active = any_cell & ~all_cell;
        while (active != 0) {
          const int bit = std::countr_zero(active);
          active &= active - 1;
          const int px = w * 64 + bit;
          if (px > last_cell) {
            break;
          }
          // Corner c = x + 2 y + 4 z is bit px + (c & 1) of row c >> 1: each row gives two
          // corners, its bits `bit` and `bit + 1` (the next word's first when bit is 63).
          int config = 0;
          for (int r = 0; r < 4; ++r) {
            const std::uint64_t pair = (here[r] >> bit) | ((next[r] << 1) << (63 - bit));
            config |= static_cast<int>(pair & 3u) << (2 * r);
          }
          const auto& tris = table.triangles[config];
          int local[12];
          std::fill(std::begin(local), std::end(local), -1);
          // The vertex of the cell's edge e (made on first use).
          auto vertex = [&](int e) {
            if (local[e] != -1) return local[e];
            const CubeEdge& edge = kEdges[e];
            const int c = edge.lower_corner;
            const int x = px + (c & 1);
            const int y = py + ((c >> 1) & 1);
            const int z = pz + ((c >> 2) & 1);
            const std::int64_t cell = std::int64_t{y} * n.x() + x;
            int* slot = nullptr;
            std::vector<std::int64_t>* set = nullptr;
            const bool hi = (c >> 2) & 1;
            if (edge.axis == 2) {
              slot = &planes->z[cell];
              set = &planes->z_set;
            } else {
              const int parity = (pz + (hi ? 1 : 0)) & 1;
              slot = edge.axis == 0 ? &(hi ? x_hi : x_lo)[cell] : &(hi ? y_hi : y_lo)[cell];
              set = edge.axis == 0 ? &planes->x_set[parity] : &planes->y_set[parity];
            }
            if (*slot == -1) {
              *slot = lo_foreign && !hi && edge.axis != 2
                          ? kForeign - static_cast<int>(cell * 2 + edge.axis)
                          : make_vertex(x, y, z, edge.axis, ((config >> c) & 1) != 0);
              set->push_back(cell);
            }
            local[e] = *slot;
            return *slot;
          };
          for (int t = 0; tris[t] != CaseTable::kEnd; t += 3) {
            // In order: the vertices are numbered as they are made.
            const int a = vertex(tris[t]);
            const int b = vertex(tris[t + 1]);
            const int c = vertex(tris[t + 2]);
            out.faces.emplace_back(a, b, c);
          }
        }
      }
    }
  }
  // The plane above the last layer, for the slab above; then every plane back to -1.
  for (int axis = 0; axis < 2; ++axis) {
    const std::vector<int>& plane = axis == 0 ? planes->x[z1 & 1] : planes->y[z1 & 1];
    const std::vector<std::int64_t>& set =
        axis == 0 ? planes->x_set[z1 & 1] : planes->y_set[z1 & 1];
    for (std::int64_t cell : set) out.top[axis].emplace_back(cell, plane[cell]);
  }
  for (int parity = 0; parity < 2; ++parity) {
    EdgePlanes::Reset(&planes->x[parity], &planes->x_set[parity]);
    EdgePlanes::Reset(&planes->y[parity], &planes->y_set[parity]);
  }
  EdgePlanes::Reset(&planes->z, &planes->z_set);
  return out;
}

// Slab s's triangles with their vertices numbered in the whole mesh (slab s's first vertex is
// vertex_base[s]) at `faces`; false when a corner of its first plane is not a vertex the slab
// below made (never, if every cell around a cut edge uses it).
bool JoinSlab(const std::vector<Slab>& slabs, const std::vector<int>& vertex_base, std::size_t s,
              EdgePlanes* planes, Eigen::Vector3i* faces) {
  const Slab& slab = slabs[s];
  // The slab below's top plane, as lookups (planes->x[0] and y[0], all -1 before and after).
  if (s > 0) {
    for (int axis = 0; axis < 2; ++axis) {
      std::vector<int>& plane = axis == 0 ? planes->x[0] : planes->y[0];
      for (const auto& [cell, id] : slabs[s - 1].top[axis]) plane[cell] = id;
    }
  }
  bool ok = true;
  for (std::size_t j = 0; j < slab.faces.size(); ++j) {
    for (int c = 0; c < 3; ++c) {
      const int id = slab.faces[j][c];
      if (id >= 0) {
        faces[j][c] = vertex_base[s] + id;
        continue;
      }
      const int code = kForeign - id;
      const int below = s > 0 ? (code & 1 ? planes->y[0] : planes->x[0])[code >> 1] : -1;
      ok = ok && below >= 0;
      faces[j][c] = s > 0 ? vertex_base[s - 1] + below : 0;
    }
  }
  if (s > 0) {
    for (int axis = 0; axis < 2; ++axis) {
      std::vector<int>& plane = axis == 0 ? planes->x[0] : planes->y[0];
      for (const auto& entry : slabs[s - 1].top[axis]) plane[entry.first] = -1;
    }
  }
  return ok;
}

}  // namespace

Mesh MarchingCubes(const BitVolume& field, const Eigen::Vector3d& origin, double spacing,
                   const EdgeCrossings& crossings, const MarchingCubesOptions& options) {
  const CaseTable& table = Table();
  Mesh mesh;
  const Eigen::Vector3i& dims = field.dims();
  if (dims.minCoeff() <= 0 || !field.Any()) {
    return mesh;
  }
  const BitVolume padded = Padded(field);
  const Eigen::Vector3i& n = padded.dims();
  const std::int64_t plane_size = std::int64_t{n.x()} * n.y();
  tbb::enumerable_thread_specific<EdgePlanes> planes(
      [plane_size] { return EdgePlanes(plane_size); });
  // The layers in slabs on all cores, each numbering its own vertices; then the slabs joined in
  // order, which numbers the vertices and lists the triangles exactly as one sweep over every
  // layer would (a slab's edges are those the sweep makes in its layers, in the same order).
  const int layers = n.z() - 1;
  const int slab_layers = options.slab_layers > 0 ? options.slab_layers : kSlabLayers;
  std::vector<Slab> slabs(static_cast<std::size_t>((layers + slab_layers - 1) / slab_layers));
  ParallelFor(0, slabs.size(), [&](std::size_t s) {
    const int z0 = static_cast<int>(s) * slab_layers;
    slabs[s] = MarchSlab(padded, table, z0, std::min(layers, z0 + slab_layers), &planes.local());
  });
  std::vector<int> vertex_base(slabs.size() + 1, 0);
  std::vector<std::size_t> face_base(slabs.size() + 1, 0);
  for (std::size_t s = 0; s < slabs.size(); ++s) {
    vertex_base[s + 1] = vertex_base[s] + static_cast<int>(slabs[s].edges.size());
    face_base[s + 1] = face_base[s] + slabs[s].faces.size();
  }
  mesh.faces.resize(face_base.back());
  std::vector<GridEdge> cut_edges(static_cast<std::size_t>(vertex_base.back()));
  std::atomic<bool> joined = true;
  ParallelFor(0, slabs.size(), [&](std::size_t s) {
    std::copy(slabs[s].edges.begin(), slabs[s].edges.end(), cut_edges.begin() + vertex_base[s]);
    if (!JoinSlab(slabs, vertex_base, s, &planes.local(), mesh.faces.data() + face_base[s])) {
      joined = false;
    }
  });
  if (!joined && slabs.size() > 1) {
    // Not expected (every cell around a cut edge uses it); one slab is the sweep itself.
    MarchingCubesOptions one = options;
    one.slab_layers = layers;
    return MarchingCubes(field, origin, spacing, crossings, one);
  }
  slabs.clear();
  // The components (from the faces alone) are found while the vertices are placed.
  Components components;
  ParallelInvoke([&] { PlaceVertices(cut_edges, origin, spacing, crossings, &mesh); },
                 [&] {
                   if (options.keep_largest_component) {
                     components = FindComponents(mesh.faces, static_cast<int>(cut_edges.size()));
                   }
                 });
  if (options.keep_largest_component) {
    KeepComponent(components, &mesh);
  }
  return mesh;
}

}  // namespace revolve::reconstruct
