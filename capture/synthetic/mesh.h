// Triangle meshes for the simulated camera: a minimal reader for the OBJ and PLY files of the
// shared data (Spot, the Stanford bunny), ray and distance queries, and a tiny PLY writer for
// ground-truth export. capture does not depend on reconstruct, hence its own small reader.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "base/error.h"

namespace revolve::capture {

struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;  // indices into vertices
};

// Reads a Wavefront OBJ (v and f lines; polygons are fanned into triangles; texture and normal
// indices, negative indices and comments are handled) or a PLY (ascii or binary little/big
// endian; vertex x y z of any numeric type, face vertex_indices lists; other elements and
// properties are skipped). Chosen by the extension (.obj, .ply, any case).
// Errors: not_found, bad_input naming the file and what is wrong.
Expected<TriangleMesh> ReadMesh(const std::filesystem::path& path);

// Writes an ASCII PLY (vertices and triangles), atomically. Errors: io.
Expected<void> WritePlyAscii(const TriangleMesh& mesh, const std::filesystem::path& path);

// Signed volume by the divergence theorem (positive for outward-facing counter-clockwise
// triangles; exact for a closed mesh).
double MeshVolume(const TriangleMesh& mesh);

// Distance from a point to a triangle.
double PointTriangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b, const Eigen::Vector3d& c);

// Ray parameter t > eps where o + t d meets triangle (a, b, c) (either side), or nullopt.
std::optional<double> RayTriangle(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                  const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  const Eigen::Vector3d& c);

// A uniform grid of triangle lists over a mesh's bounding box, for distance queries.
class MeshGrid {
 public:
  // Contract: the mesh has at least one triangle.
  explicit MeshGrid(std::shared_ptr<const TriangleMesh> mesh, int cells_per_side = 24);
  // Exact unsigned distance from `p` to the mesh (searches outward shell by shell).
  double Distance(const Eigen::Vector3d& p) const;

 private:
  std::shared_ptr<const TriangleMesh> mesh_;
  Eigen::Vector3d min_, cell_size_;
  int n_;
  std::vector<std::vector<int>> cells_;
};

}  // namespace revolve::capture
