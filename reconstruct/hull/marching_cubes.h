// Marching cubes over a binary field.
//
// Samples sit on an integer lattice; sample (i, j, k) is at origin + spacing * (i, j, k). Samples
// outside [0, dims) are empty, so the surface is always closed. Each cell (the cube between 8
// neighbouring samples, including the cells that straddle the grid's border) is polygonised from
// a case table generated once from one consistent rule:
//  - on every cube face, the surface segments cut off each maximal run of inside corners (two
//    diagonal inside corners of a face stay separated: inside is 6-connected, outside 18/26);
//  - the loops these segments form on a cube's boundary are capped by separate discs (no
//    tunnels through a cell), each triangulated without a chord between two vertices on the same
//    cube face.
// Both neighbours of a face see the same segments, and no triangle edge can appear in two cells
// except a face segment, so the mesh is watertight and every edge is shared by exactly two
// triangles, traversed once in each direction (consistent orientation). Triangles are
// counter-clockwise seen from the empty side (outward normals, positive enclosed volume).
// Vertices are welded: one per cut grid edge.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

// A dense binary field, bit-packed in rows along x.
class BitVolume {
 public:
  BitVolume() = default;
  explicit BitVolume(const Eigen::Vector3i& dims);

  const Eigen::Vector3i& dims() const { return dims_; }
  // False outside [0, dims).
  bool Get(int i, int j, int k) const {
    if (i < 0 || j < 0 || k < 0 || i >= dims_.x() || j >= dims_.y() || k >= dims_.z()) {
      return false;
    }
    return (Row(j, k)[i >> 6] >> (i & 63)) & 1u;
  }
  // Precondition: (i, j, k) inside dims.
  void Set(int i, int j, int k, bool value) {
    std::uint64_t& word = Row(j, k)[i >> 6];
    const std::uint64_t bit = std::uint64_t{1} << (i & 63);
    word = value ? (word | bit) : (word & ~bit);
  }
  std::int64_t Count() const;
  // Whether any sample is set (cheaper than Count() > 0).
  bool Any() const;

  int words_per_row() const { return words_per_row_; }
  // The bits of row (j, k): bit i of the row is sample (i, j, k); bits past dims.x() are 0.
  const std::uint64_t* Row(int j, int k) const {
    return words_.data() + (std::int64_t{k} * dims_.y() + j) * words_per_row_;
  }
  std::uint64_t* Row(int j, int k) {
    return words_.data() + (std::int64_t{k} * dims_.y() + j) * words_per_row_;
  }

 private:
  Eigen::Vector3i dims_ = Eigen::Vector3i::Zero();
  int words_per_row_ = 0;
  std::vector<std::uint64_t> words_;
};

// A cut grid edge: from the inside sample `inside` to its 6-neighbour `outside` (either may lie
// one sample outside the grid, where the field is empty).
struct GridEdge {
  Eigen::Vector3i inside;
  Eigen::Vector3i outside;
};

// Where the surface crosses each edge: one parameter t in [0, 1] from `inside` per edge, in the
// same order (values are clamped to [0, 1]). Called once with every cut edge of the mesh (one
// per vertex, in vertex order), so an implementation can batch or parallelise the work. A
// result of the wrong size is a bug; MarchingCubes then falls back to midpoints.
using EdgeCrossings = std::function<std::vector<double>(const std::vector<GridEdge>& edges)>;

struct MarchingCubesOptions {
  // Keep only the connected component with the most triangles (ties: the first found).
  bool keep_largest_component = true;
  // Layers of cells per task (0: the default, 16): the cells are polygonised in slabs of layers
  // on all cores and joined in order, so the mesh is the same for any value (tests compare).
  int slab_layers = 0;
};

// Polygonises `field`; an empty `crossings` puts every vertex at its edge's midpoint. Empty mesh
// when no sample is inside.
Mesh MarchingCubes(const BitVolume& field, const Eigen::Vector3d& origin, double spacing,
                   const EdgeCrossings& crossings = {}, const MarchingCubesOptions& options = {});

// Keeps the connected component (through shared vertices) with the most triangles and drops
// unreferenced vertices (and their colours); `uv_faces` follow their faces (`uvs` are kept as
// they are). Returns the number of components found.
int KeepLargestComponent(Mesh* mesh);

}  // namespace revolve::reconstruct
