#include <numeric>

#include "reconstruct/parallel.h"
#include "reconstruct/texture/texture_internal.h"

namespace revolve::reconstruct::texture_internal {
namespace {

constexpr std::size_t kFacesPerTask = 8192;

VertexFaces FacesOfVertices(const Mesh& mesh) {
  const int nf = static_cast<int>(mesh.faces.size());
  VertexFaces out;
  std::vector<int>& start = out.start;
  start.assign(mesh.vertices.size() + 1, 0);
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int c = 0; c < 3; ++c) ++start[f[c] + 1];
  }
  std::partial_sum(start.begin(), start.end(), start.begin());
  out.faces.resize(start.back());
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (int i = 0; i < nf; ++i) {
    for (int c = 0; c < 3; ++c) out.faces[fill[mesh.faces[i][c]]++] = i;
  }
  return out;
}

// The (up to 3) faces sharing an edge with each face; -1 for a border edge.
std::vector<std::array<int, 3>> FaceNeighbours(const Mesh& mesh, const VertexFaces& around) {
  const int nf = static_cast<int>(mesh.faces.size());
  std::vector<std::array<int, 3>> neighbours(nf);
  ParallelChunks(0, nf, kFacesPerTask, [&](std::size_t lo, std::size_t hi) {
    for (int i = static_cast<int>(lo); i < static_cast<int>(hi); ++i) {
      const Eigen::Vector3i& f = mesh.faces[i];
      neighbours[i] = {-1, -1, -1};
      for (int c = 0; c < 3; ++c) {
        const int a = f[c];
        const int b = f[(c + 1) % 3];
        for (int k = around.start[a]; k < around.start[a + 1]; ++k) {
          const int g = around.faces[k];
          if (g == i) continue;
          const Eigen::Vector3i& h = mesh.faces[g];
          if (h[0] == b || h[1] == b || h[2] == b) {
            neighbours[i][c] = g;
            break;
          }
        }
      }
    }
  });
  return neighbours;
}

// Smoothed face normals choose the views: the voxel staircase of the silhouettes tilts single
// facets, and views chosen per raw facet would shatter the charts. Starts from the mean of the
// corners' (area-weighted) normals, already two rings wide, then averages over the
// edge-neighbours kNormalSmoothingPasses times (each pass reads only the one before: the faces
// on all cores).
void SmoothFaceNormals(const Mesh& mesh, Surface* s) {
  const std::size_t nf = mesh.faces.size();
  s->snx.resize(nf);
  s->sny.resize(nf);
  s->snz.resize(nf);
  ParallelChunks(0, nf, kFacesPerTask, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) {
      const Eigen::Vector3i& f = mesh.faces[i];
      const Eigen::Vector3f n =
          (s->vertex_normal[f[0]] + s->vertex_normal[f[1]] + s->vertex_normal[f[2]]).normalized();
      s->snx[i] = n.x();
      s->sny[i] = n.y();
      s->snz[i] = n.z();
    }
  });
  std::vector<float> tx(nf), ty(nf), tz(nf);
  for (int pass = 0; pass < kNormalSmoothingPasses; ++pass) {
    ParallelChunks(0, nf, kFacesPerTask, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) {
        float x = s->snx[i], y = s->sny[i], z = s->snz[i];
        for (int nb : s->neighbours[i]) {
          if (nb < 0) continue;
          x += s->snx[nb];
          y += s->sny[nb];
          z += s->snz[nb];
        }
        const float length = std::sqrt(x * x + y * y + z * z);
        const float inv = length > 0.0f ? 1.0f / length : 0.0f;
        tx[i] = x * inv;
        ty[i] = y * inv;
        tz[i] = z * inv;
      }
    });
    s->snx.swap(tx);
    s->sny.swap(ty);
    s->snz.swap(tz);
  }
}

// Per face: its normal (twice its area times the unit normal) and the length of its first edge;
// for the atlas also the unit normal and centroid.
void MeasureFaces(const Mesh& mesh, bool atlas, std::vector<Eigen::Vector3f>* normal,
                  std::vector<float>* first_edge, Surface* s) {
  const int nf = static_cast<int>(mesh.faces.size());
  const std::vector<Eigen::Vector3f>& vertices = mesh.vertices;
  normal->resize(nf);
  first_edge->resize(nf);
  if (atlas) {
    for (std::vector<float>* a : {&s->fnx, &s->fny, &s->fnz}) a->resize(nf);
    s->centroid.resize(nf);
  }
  ParallelChunks(0, nf, kFacesPerTask, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) {
      const Eigen::Vector3i& f = mesh.faces[i];
      const Eigen::Vector3f& a = vertices[f[0]];
      const Eigen::Vector3f& b = vertices[f[1]];
      const Eigen::Vector3f& c = vertices[f[2]];
      const Eigen::Vector3f n = (b - a).cross(c - a);
      (*normal)[i] = n;
      (*first_edge)[i] = (b - a).norm();
      if (atlas) {
        const float length = n.norm();
        const Eigen::Vector3f unit =
            length > 0.0f ? Eigen::Vector3f(n / length) : Eigen::Vector3f::Zero();
        s->fnx[i] = unit.x();
        s->fny[i] = unit.y();
        s->fnz[i] = unit.z();
        s->centroid[i] = (a + b + c) / 3.0f;
      }
    }
  });
}

}  // namespace

Surface MeasureSurface(Mesh* mesh, bool atlas) {
  Surface s;
  const int nv = static_cast<int>(mesh->vertices.size());
  const int nf = static_cast<int>(mesh->faces.size());
  const std::vector<Eigen::Vector3f>& vertices = mesh->vertices;
  std::vector<Eigen::Vector3f> face_normal;
  std::vector<float> first_edge;
  VertexFaces& around = s.around;
  ParallelInvoke([&] { MeasureFaces(*mesh, atlas, &face_normal, &first_edge, &s); },
                 [&] { around = FacesOfVertices(*mesh); });
  // The mesh's scale: the mean first edge, summed in face order (one thread: the same sum on
  // any number of cores), and the box of the faces' first corners.
  double edge_sum = 0.0;
  for (const float length : first_edge) edge_sum += length;
  Eigen::Vector3f lo = vertices[mesh->faces[0][0]];
  Eigen::Vector3f hi = lo;
  for (const Eigen::Vector3i& f : mesh->faces) {
    lo = lo.cwiseMin(vertices[f[0]]);
    hi = hi.cwiseMax(vertices[f[0]]);
  }
  // Vertex normals: each vertex sums its faces' normals in face order (as adding each face's to
  // its corners face after face would), on all cores. The mesh keeps them too (Mesh::normals:
  // +z where they vanish), for the writers.
  std::vector<Eigen::Vector3f>& vertex_normal = s.vertex_normal;
  vertex_normal.resize(nv);
  mesh->normals.resize(nv);
  ParallelChunks(0, nv, kFacesPerTask, [&](std::size_t vlo, std::size_t vhi) {
    for (std::size_t v = vlo; v < vhi; ++v) {
      Eigen::Vector3f n = Eigen::Vector3f::Zero();
      for (int k = around.start[v]; k < around.start[v + 1]; ++k) n += face_normal[around.faces[k]];
      const float length = n.norm();
      mesh->normals[v] = length > 0.0f && std::isfinite(length) ? Eigen::Vector3f(n / length)
                                                                : Eigen::Vector3f::UnitZ();
      vertex_normal[v] = length > 0.0f ? Eigen::Vector3f(n / length) : Eigen::Vector3f::Zero();
    }
  });
  // Every vertex's box (lo and hi above take the faces' first corners only).
  s.box_lo = vertices[0];
  s.box_hi = s.box_lo;
  for (const Eigen::Vector3f& x : vertices) {
    s.box_lo = s.box_lo.cwiseMin(x);
    s.box_hi = s.box_hi.cwiseMax(x);
  }
  s.mean_edge_mm = static_cast<float>(edge_sum / nf);
  s.centre = 0.5f * (lo + hi);
  s.radius = 0.5f * (hi - lo).norm();
  return s;
}

void MeasureNeighbourhoods(const Mesh& mesh, Surface* surface) {
  surface->neighbours = FaceNeighbours(mesh, surface->around);
  SmoothFaceNormals(mesh, surface);
  Surface& s = *surface;
  s.face_point.resize(mesh.faces.size());
  ParallelChunks(0, mesh.faces.size(), kFacesPerTask, [&s](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) {
      s.face_point[i] = Surface::FacePoint{s.centroid[i].x(), s.centroid[i].y(), s.centroid[i].z(),
                                           s.snx[i],          s.sny[i],          s.snz[i],
                                           s.fnx[i],          s.fny[i],          s.fnz[i]};
    }
  });
}

VertexClusters ClusterVertices(const std::vector<Eigen::Vector3f>& vertices,
                               const Surface& surface) {
  constexpr int kClusterSide = 8;
  const int nv = static_cast<int>(vertices.size());
  const std::vector<Eigen::Vector3f>& vertex_normal = surface.vertex_normal;
  VertexClusters out;
  std::vector<Cluster>& clusters = out.clusters;
  clusters.resize(std::size_t{kClusterSide} * kClusterSide * kClusterSide);
  std::vector<float>&vx = out.x, &vy = out.y, &vz = out.z;
  std::vector<float>&vnx = out.nx, &vny = out.ny, &vnz = out.nz;
  for (std::vector<float>* a : {&vx, &vy, &vz, &vnx, &vny, &vnz}) a->resize(nv);
  const Eigen::Vector3f scale =
      kClusterSide * (surface.box_hi - surface.box_lo).cwiseMax(1e-6f).cwiseInverse();
  std::vector<int> cluster_of(nv);
  std::vector<int> start(clusters.size() + 1, 0);
  for (int i = 0; i < nv; ++i) {
    int cell[3];
    for (int a = 0; a < 3; ++a) {
      const float x = (vertices[i][a] - surface.box_lo[a]) * scale[a];
      cell[a] = std::clamp(static_cast<int>(x >= 0.0f ? x : 0.0f), 0, kClusterSide - 1);
    }
    cluster_of[i] = (cell[2] * kClusterSide + cell[1]) * kClusterSide + cell[0];
    ++start[cluster_of[i] + 1];
  }
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (int i = 0; i < nv; ++i) {
    const int at = fill[cluster_of[i]]++;
    vx[at] = vertices[i].x();
    vy[at] = vertices[i].y();
    vz[at] = vertices[i].z();
    vnx[at] = vertex_normal[i].x();
    vny[at] = vertex_normal[i].y();
    vnz[at] = vertex_normal[i].z();
  }
  for (std::size_t c = 0; c < clusters.size(); ++c) {
    Cluster& cluster = clusters[c];
    cluster.begin = start[c];
    cluster.end = start[c + 1];
    if (cluster.begin == cluster.end) continue;
    cluster.lo = cluster.hi =
        Eigen::Vector3f(vx[cluster.begin], vy[cluster.begin], vz[cluster.begin]);
    bool unit_normals = true;
    for (int i = cluster.begin; i < cluster.end; ++i) {
      const Eigen::Vector3f x(vx[i], vy[i], vz[i]);
      cluster.lo = cluster.lo.cwiseMin(x);
      cluster.hi = cluster.hi.cwiseMax(x);
      const Eigen::Vector3f n(vnx[i], vny[i], vnz[i]);
      unit_normals = unit_normals && n.squaredNorm() > 0.5f;
      cluster.axis += n;
    }
    if (!unit_normals || !(cluster.axis.norm() > 1e-3f)) continue;  // no cone
    cluster.axis.normalize();
    float min_cos = 1.0f;
    for (int i = cluster.begin; i < cluster.end; ++i) {
      min_cos = std::min(min_cos, cluster.axis.dot(Eigen::Vector3f(vnx[i], vny[i], vnz[i])));
    }
    cluster.half_angle = std::acos(std::clamp(min_cos, -1.0f, 1.0f));
  }
  return out;
}

}  // namespace revolve::reconstruct::texture_internal
