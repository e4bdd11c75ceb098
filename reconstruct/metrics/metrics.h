// Measurements of a mesh: size, topology checks, distance to a known truth, sphere fit.
#pragma once

#include <cstdint>
#include <functional>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

struct MeshStats {
  std::int64_t vertex_count = 0;
  std::int64_t triangle_count = 0;
  double area_mm2 = 0.0;
  // Signed volume by the divergence theorem: positive for a closed, outward-oriented mesh.
  double volume_mm3 = 0.0;
  Eigen::Vector3d bbox_min_mm = Eigen::Vector3d::Zero();  // of the vertices used by faces
  Eigen::Vector3d bbox_max_mm = Eigen::Vector3d::Zero();
  // Every undirected edge is shared by exactly two triangles (watertight, no non-manifold edge).
  bool closed = false;
  // Every directed edge appears at most once (consistent orientation; with `closed`, each
  // edge is used once in each direction).
  bool oriented = false;
  std::int64_t degenerate_triangles = 0;  // triangles that repeat a vertex index
};

// Stats of `mesh`; an empty mesh is neither closed nor oriented. Precondition: face indices
// are valid vertex indices. ComputeMeasures then CheckEdges.
MeshStats ComputeStats(const Mesh& mesh);

// ComputeStats's counts, sizes, area and volume; `closed` and `oriented` false (not checked).
MeshStats ComputeMeasures(const Mesh& mesh);

// ComputeStats's `closed` and `oriented` into *stats (its other fields untouched). A caller that
// knows them already (ReprojectionStats::closed_and_oriented) sets them instead.
void CheckEdges(const Mesh& mesh, MeshStats* stats);

// Unsigned distance (mm) from a point to the true surface.
using DistanceToTruth = std::function<double(const Eigen::Vector3d&)>;

struct DistanceStats {
  std::int64_t samples = 0;
  double mean_mm = 0.0;
  double rms_mm = 0.0;
  double p90_mm = 0.0;  // 90th percentile ("accuracy" of the Middlebury benchmark)
  double max_mm = 0.0;
};

// Distance of every vertex of the mesh to the truth.
DistanceStats VertexDistance(const Mesh& mesh, const DistanceToTruth& truth);

// Distance of `count` points sampled uniformly by area on the mesh's triangles (deterministic
// for a given seed) to the truth.
DistanceStats SurfaceDistance(const Mesh& mesh, const DistanceToTruth& truth, int count,
                              std::uint32_t seed = 1);

struct SphereFit {
  Eigen::Vector3d centre_mm = Eigen::Vector3d::Zero();
  double radius_mm = 0.0;
  double rms_residual_mm = 0.0;  // rms of |p - centre| - radius over the vertices
  bool ok = false;               // false with fewer than 4 vertices or a degenerate set
};

// Linear least-squares sphere through the mesh's vertices (|p|^2 = 2 c.p + d).
SphereFit FitSphere(const Mesh& mesh);

// Peak signal-to-noise ratio (dB, peak 255) between two images of the same size and type
// (8-bit, any channel count) over the pixels where `mask` (CV_8UC1) is non-zero:
// 10 log10(255^2 / MSE), the MSE taken over every channel. Infinity when they are equal there,
// NaN when the mask is empty or the images do not match.
double Psnr(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask);

}  // namespace revolve::reconstruct
