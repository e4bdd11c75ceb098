#include "reconstruct/metrics/reprojection.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <opencv2/core.hpp>

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

}  // namespace

cv::Mat RenderSilhouette(const Mesh& mesh, const View& view) {
  cv::Mat out(view.height_px, view.width_px, CV_8UC1, cv::Scalar(0));
  std::vector<Eigen::Vector2d> projected(mesh.vertices.size());
  std::vector<std::uint8_t> visible(mesh.vertices.size(), 0);
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    Eigen::Vector2d pixel;
    if (view.Project(mesh.vertices[i].cast<double>(), &pixel)) {
      projected[i] = pixel;
      visible[i] = 1;
    }
  }
  for (const Eigen::Vector3i& face : mesh.faces) {
    if (!visible[face[0]] || !visible[face[1]] || !visible[face[2]]) continue;
    const Eigen::Vector2d& p0 = projected[face[0]];
    const Eigen::Vector2d& p1 = projected[face[1]];
    const Eigen::Vector2d& p2 = projected[face[2]];
    const double area = Cross2(p1 - p0, p2 - p0);
    if (area == 0.0 || !std::isfinite(area)) continue;
    const double sign = area > 0.0 ? 1.0 : -1.0;
    const double min_u = std::min({p0.x(), p1.x(), p2.x()});
    const double max_u = std::max({p0.x(), p1.x(), p2.x()});
    const double min_v = std::min({p0.y(), p1.y(), p2.y()});
    const double max_v = std::max({p0.y(), p1.y(), p2.y()});
    const int u0 = std::max(0, static_cast<int>(std::ceil(min_u)));
    const int u1 = std::min(view.width_px - 1, static_cast<int>(std::floor(max_u)));
    const int v0 = std::max(0, static_cast<int>(std::ceil(min_v)));
    const int v1 = std::min(view.height_px - 1, static_cast<int>(std::floor(max_v)));
    for (int v = v0; v <= v1; ++v) {
      auto* row = out.ptr<std::uint8_t>(v);
      for (int u = u0; u <= u1; ++u) {
        if (row[u]) continue;
        const Eigen::Vector2d p(u, v);
        if (sign * Cross2(p1 - p0, p - p0) >= 0.0 && sign * Cross2(p2 - p1, p - p1) >= 0.0 &&
            sign * Cross2(p0 - p2, p - p2) >= 0.0) {
          row[u] = 255;
        }
      }
    }
  }
  return out;
}

double MaskIoU(const cv::Mat& a, const cv::Mat& b) {
  std::int64_t both = 0;
  std::int64_t either = 0;
  for (int v = 0; v < a.rows; ++v) {
    const auto* ra = a.ptr<std::uint8_t>(v);
    const auto* rb = b.ptr<std::uint8_t>(v);
    for (int u = 0; u < a.cols; ++u) {
      const bool x = ra[u] != 0;
      const bool y = rb[u] != 0;
      both += x && y;
      either += x || y;
    }
  }
  return either == 0 ? 1.0 : static_cast<double>(both) / static_cast<double>(either);
}

ReprojectionStats SilhouetteReprojection(const Mesh& mesh, const std::vector<View>& views,
                                         const std::vector<cv::Mat>& masks) {
  ReprojectionStats stats;
  double sum = 0.0;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const double iou = MaskIoU(RenderSilhouette(mesh, views[i]), masks[i]);
    stats.iou.push_back(iou);
    sum += iou;
    if (stats.worst_view < 0 || iou < stats.min) {
      stats.min = iou;
      stats.worst_view = static_cast<int>(i);
    }
  }
  if (!views.empty()) stats.mean = sum / static_cast<double>(views.size());
  return stats;
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
