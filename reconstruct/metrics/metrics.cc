#include "reconstruct/metrics/metrics.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Dense>

#include "reconstruct/parallel.h"

namespace revolve::reconstruct {
namespace {

DistanceStats Summarize(std::vector<double> distances) {
  DistanceStats stats;
  stats.samples = static_cast<std::int64_t>(distances.size());
  if (distances.empty()) {
    return stats;
  }
  double sum = 0.0;
  double sum_sq = 0.0;
  for (double d : distances) {
    sum += d;
    sum_sq += d * d;
    stats.max_mm = std::max(stats.max_mm, d);
  }
  stats.mean_mm = sum / distances.size();
  stats.rms_mm = std::sqrt(sum_sq / distances.size());
  const std::size_t k = std::min(distances.size() - 1,
                                 static_cast<std::size_t>(std::ceil(0.9 * distances.size())) - 1);
  std::nth_element(distances.begin(), distances.begin() + k, distances.end());
  stats.p90_mm = distances[k];
  return stats;
}

Eigen::Vector3d Vertex(const Mesh& mesh, int index) { return mesh.vertices[index].cast<double>(); }

}  // namespace

MeshStats ComputeMeasures(const Mesh& mesh) {
  MeshStats stats;
  stats.vertex_count = static_cast<std::int64_t>(mesh.vertices.size());
  stats.triangle_count = static_cast<std::int64_t>(mesh.faces.size());
  if (mesh.faces.empty()) {
    return stats;
  }
  // Each face's area and volume terms on all cores, in chunks that also take their corners'
  // box and count their degenerate faces; the terms are summed in face order on one thread
  // (the same sums, to the bit, as one loop adding them face after face).
  const std::size_t face_count = mesh.faces.size();
  constexpr std::size_t kChunk = 16384;
  struct Chunk {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
    std::int64_t degenerate = 0;
  };
  std::vector<Chunk> chunks((face_count + kChunk - 1) / kChunk);
  std::vector<double> area(face_count);
  std::vector<double> volume6(face_count);
  ParallelFor(0, chunks.size(), [&](std::size_t c) {
    Chunk& chunk = chunks[c];
    const std::size_t end = std::min(face_count, (c + 1) * kChunk);
    for (std::size_t i = c * kChunk; i < end; ++i) {
      const Eigen::Vector3i& f = mesh.faces[i];
      const Eigen::Vector3d a = Vertex(mesh, f[0]);
      const Eigen::Vector3d b = Vertex(mesh, f[1]);
      const Eigen::Vector3d d = Vertex(mesh, f[2]);
      chunk.lo = chunk.lo.cwiseMin(a).cwiseMin(b).cwiseMin(d);
      chunk.hi = chunk.hi.cwiseMax(a).cwiseMax(b).cwiseMax(d);
      area[i] = 0.5 * (b - a).cross(d - a).norm();
      volume6[i] = a.dot(b.cross(d));
      if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) {
        ++chunk.degenerate;
      }
    }
  });
  stats.bbox_min_mm = chunks[0].lo;
  stats.bbox_max_mm = chunks[0].hi;
  for (const Chunk& chunk : chunks) {
    stats.bbox_min_mm = stats.bbox_min_mm.cwiseMin(chunk.lo);
    stats.bbox_max_mm = stats.bbox_max_mm.cwiseMax(chunk.hi);
    stats.degenerate_triangles += chunk.degenerate;
  }
  double volume_sum = 0.0;
  for (std::size_t i = 0; i < face_count; ++i) {
    stats.area_mm2 += area[i];
    volume_sum += volume6[i];
  }
  stats.volume_mm3 = volume_sum / 6.0;
  return stats;
}

void CheckEdges(const Mesh& mesh, MeshStats* stats) {
  stats->closed = false;
  stats->oriented = false;
  if (mesh.faces.empty()) return;
  // Each vertex's outgoing directed edges (their targets), grouped by vertex (a counting sort).
  const std::size_t n = mesh.vertices.size();
  std::vector<std::size_t> first(n + 1, 0);
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int e = 0; e < 3; ++e) ++first[static_cast<std::size_t>(f[e]) + 1];
  }
  for (std::size_t v = 0; v < n; ++v) first[v + 1] += first[v];
  std::vector<int> targets(first[n]);
  {
    std::vector<std::size_t> next(first.begin(), first.end() - 1);
    for (const Eigen::Vector3i& f : mesh.faces) {
      for (int e = 0; e < 3; ++e) targets[next[static_cast<std::size_t>(f[e])]++] = f[(e + 1) % 3];
    }
  }
  const auto uses = [&](int from, int to) {
    const auto begin = targets.begin() + static_cast<std::ptrdiff_t>(first[from]);
    const auto end = targets.begin() + static_cast<std::ptrdiff_t>(first[from + 1]);
    return static_cast<int>(std::count(begin, end, to));
  };
  // Oriented: every directed edge used once; closed: every undirected edge {a, b} used twice
  // (its uses plus its reverse's), none from a vertex to itself. Each vertex's edges are
  // checked on its own, on all cores; a flag only ever goes from true to false.
  std::atomic<bool> oriented = true;
  std::atomic<bool> closed = true;
  ParallelChunks(0, n, 4096, [&](std::size_t lo, std::size_t hi) {
    bool chunk_oriented = true;
    bool chunk_closed = true;
    for (std::size_t v = lo; v < hi; ++v) {
      const int a = static_cast<int>(v);
      for (std::size_t k = first[v]; k < first[v + 1]; ++k) {
        const int b = targets[k];
        const int forward = uses(a, b);
        if (forward != 1) chunk_oriented = false;
        if (a == b || forward + uses(b, a) != 2) chunk_closed = false;
      }
    }
    if (!chunk_oriented) oriented.store(false, std::memory_order_relaxed);
    if (!chunk_closed) closed.store(false, std::memory_order_relaxed);
  });
  stats->oriented = oriented.load();
  stats->closed = closed.load();
}

MeshStats ComputeStats(const Mesh& mesh) {
  MeshStats stats = ComputeMeasures(mesh);
  CheckEdges(mesh, &stats);
  return stats;
}

DistanceStats VertexDistance(const Mesh& mesh, const DistanceToTruth& truth) {
  std::vector<double> distances;
  distances.reserve(mesh.vertices.size());
  for (const Eigen::Vector3f& v : mesh.vertices) {
    distances.push_back(truth(v.cast<double>()));
  }
  return Summarize(std::move(distances));
}

DistanceStats SurfaceDistance(const Mesh& mesh, const DistanceToTruth& truth, int count,
                              std::uint32_t seed) {
  if (mesh.faces.empty() || count <= 0) {
    return {};
  }
  std::vector<double> cumulative_area;
  cumulative_area.reserve(mesh.faces.size());
  double total = 0.0;
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3d a = Vertex(mesh, f[0]);
    total += 0.5 * (Vertex(mesh, f[1]) - a).cross(Vertex(mesh, f[2]) - a).norm();
    cumulative_area.push_back(total);
  }
  if (!(total > 0.0)) {
    return {};
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> distances;
  distances.reserve(count);
  for (int i = 0; i < count; ++i) {
    const double pick = unit(rng) * total;
    const std::size_t t = std::min<std::size_t>(
        std::upper_bound(cumulative_area.begin(), cumulative_area.end(), pick) -
            cumulative_area.begin(),
        mesh.faces.size() - 1);
    const Eigen::Vector3i& f = mesh.faces[t];
    double r1 = unit(rng);
    double r2 = unit(rng);
    if (r1 + r2 > 1.0) {
      r1 = 1.0 - r1;
      r2 = 1.0 - r2;
    }
    const Eigen::Vector3d a = Vertex(mesh, f[0]);
    const Eigen::Vector3d p = a + r1 * (Vertex(mesh, f[1]) - a) + r2 * (Vertex(mesh, f[2]) - a);
    distances.push_back(truth(p));
  }
  return Summarize(std::move(distances));
}

SphereFit FitSphere(const Mesh& mesh) {
  SphereFit fit;
  const int n = static_cast<int>(mesh.vertices.size());
  if (n < 4) {
    return fit;
  }
  // Centre and scale the points (unit rms distance) so the rank test below is meaningful.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3f& v : mesh.vertices) {
    mean += v.cast<double>();
  }
  mean /= n;
  double spread = 0.0;
  for (const Eigen::Vector3f& v : mesh.vertices) {
    spread += (v.cast<double>() - mean).squaredNorm();
  }
  spread = std::sqrt(spread / n);
  if (!(spread > 0.0)) {
    return fit;
  }
  Eigen::Matrix4d normal = Eigen::Matrix4d::Zero();
  Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
  for (const Eigen::Vector3f& v : mesh.vertices) {
    const Eigen::Vector3d p = (v.cast<double>() - mean) / spread;
    const Eigen::Vector4d row(2.0 * p.x(), 2.0 * p.y(), 2.0 * p.z(), 1.0);
    normal += row * row.transpose();
    rhs += row * p.squaredNorm();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eigen(normal);
  if (eigen.info() != Eigen::Success || eigen.eigenvalues()[0] <= 1e-9 * eigen.eigenvalues()[3]) {
    return fit;  // coplanar or otherwise degenerate points
  }
  const Eigen::Vector4d x = normal.ldlt().solve(rhs);
  const double r2 = x[3] + x.head<3>().squaredNorm();
  if (!(r2 > 0.0) || !x.allFinite()) {
    return fit;
  }
  fit.centre_mm = mean + spread * x.head<3>();
  fit.radius_mm = spread * std::sqrt(r2);
  double sum_sq = 0.0;
  for (const Eigen::Vector3f& v : mesh.vertices) {
    const double r = (v.cast<double>() - fit.centre_mm).norm() - fit.radius_mm;
    sum_sq += r * r;
  }
  fit.rms_residual_mm = std::sqrt(sum_sq / n);
  fit.ok = true;
  return fit;
}

double Psnr(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  if (a.size() != b.size() || a.type() != b.type() || a.depth() != CV_8U ||
      mask.size() != a.size() || mask.type() != CV_8UC1) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  const int pixels = cv::countNonZero(mask);
  if (pixels == 0) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  const double sse = std::pow(cv::norm(a, b, cv::NORM_L2, mask), 2.0);
  if (sse == 0.0) {
    return std::numeric_limits<double>::infinity();
  }
  const double mse = sse / (static_cast<double>(pixels) * a.channels());
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

}  // namespace revolve::reconstruct
