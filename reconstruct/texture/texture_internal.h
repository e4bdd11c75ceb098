// Internal to reconstruct/texture: the steps of TextureMesh (texture.cc) and what they share.
//   surface_geometry.cc  normals, neighbours, the mesh's scale, vertex clusters
//   view_ranking.cc      the few best views of each face and vertex, and the lists per view
//   visibility.cc        per view: depth cells, the visibility of the candidates, the samples
//   atlas.cc             labels, charts, packing, the atlas image and its uvs
// All are built with -fvect-cost-model=dynamic -fno-math-errno (reconstruct/CMakeLists.txt): the
// per-view loops over every vertex are written to be vectorised.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "reconstruct/mesh.h"
#include "reconstruct/texture/texture.h"

namespace revolve::reconstruct::texture_internal {

constexpr int kChartMarginPx = 2;  // image pixels around a chart's rectangle
constexpr int kSmoothingPasses = 3;
constexpr float kNeighbourBonus = 0.1f;
constexpr int kNormalSmoothingPasses = 6;
constexpr int kCandidates = 3;   // views ranked per face and vertex
constexpr int kUnseenPatch = 4;  // side of the atlas's mid-grey patch (texels)
inline const Color kUnseenColor(128, 128, 128);

// One view's projection, in float for speed.
struct ViewGeometry {
  Eigen::Matrix<float, 3, 4> p;
  bool affine = false;
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();     // pinhole centre
  Eigen::Vector3f direction = Eigen::Vector3f::Zero();  // affine: toward the camera
  Eigen::Vector4f depth_row = Eigen::Vector4f::Zero();  // depth (mm) = depth_row . [X; 1]
  int width = 0;
  int height = 0;

  explicit ViewGeometry(const View& view) : width(view.width_px), height(view.height_px) {
    p = view.pixel_from_object.cast<float>();
    affine = view.IsAffine();
    const Eigen::Matrix3d m = view.pixel_from_object.leftCols<3>();
    if (affine) {
      direction = view.DirectionToCamera(Eigen::Vector3d::Zero()).cast<float>();
      depth_row << -direction, 0.0f;
    } else {
      centre = (-m.inverse() * view.pixel_from_object.col(3)).cast<float>();
      const double scale = m.row(2).norm();
      depth_row = (view.pixel_from_object.row(2) / scale).transpose().cast<float>();
    }
  }

  // Pixel of x; false behind the camera.
  bool Project(const Eigen::Vector3f& x, float* u, float* v) const {
    // Written out: Eigen's expression is not inlined here and this runs per vertex and view.
    const float hw = p(2, 0) * x.x() + p(2, 1) * x.y() + p(2, 2) * x.z() + p(2, 3);
    if (!(hw > 0.0f)) {
      return false;
    }
    *u = (p(0, 0) * x.x() + p(0, 1) * x.y() + p(0, 2) * x.z() + p(0, 3)) / hw;
    *v = (p(1, 0) * x.x() + p(1, 1) * x.y() + p(1, 2) * x.z() + p(1, 3)) / hw;
    return true;
  }
  float Depth(const Eigen::Vector3f& x) const { return depth_row.head<3>().dot(x) + depth_row[3]; }
  Eigen::Vector3f ToCamera(const Eigen::Vector3f& x) const {
    if (affine) return direction;
    const float dx = centre.x() - x.x(), dy = centre.y() - x.y(), dz = centre.z() - x.z();
    const float squared = dx * dx + dy * dy + dz * dz;
    const float inv = squared > 0.0f ? 1.0f / std::sqrt(squared) : 0.0f;
    return Eigen::Vector3f(dx * inv, dy * inv, dz * inv);
  }
  bool InImage(float u, float v) const {
    return u >= -0.5f && v >= -0.5f && u < width - 0.5f && v < height - 0.5f;
  }
};

// Four floats as one value (GCC's vector extension: one register where the processor has them).
using Float4 = float __attribute__((vector_size(16)));

// SampleBilinear(bgr, u, v) as (b, g, r, 1): each lane does the same operations in the same
// order (float(b) - float(a) is the integer difference exactly), so it gives the same values.
[[gnu::always_inline]] inline Float4 SampleBilinearWithOne(const cv::Mat& bgr, float u, float v) {
  const float x = std::clamp(u, 0.0f, static_cast<float>(bgr.cols - 1));
  const float y = std::clamp(v, 0.0f, static_cast<float>(bgr.rows - 1));
  const int x0 = std::min(static_cast<int>(x), bgr.cols - 2 < 0 ? 0 : bgr.cols - 2);
  const int y0 = std::min(static_cast<int>(y), bgr.rows - 2 < 0 ? 0 : bgr.rows - 2);
  const int x1 = std::min(x0 + 1, bgr.cols - 1);
  const int y1 = std::min(y0 + 1, bgr.rows - 1);
  const float fx = x - x0;
  const float fy = y - y0;
  const cv::Vec3b* r0 = bgr.ptr<cv::Vec3b>(y0);
  const cv::Vec3b* r1 = bgr.ptr<cv::Vec3b>(y1);
  auto pixel = [](const cv::Vec3b& p, float last) {
    return Float4{static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]),
                  last};
  };
  // The fourth lane: 1 + fx * (1 - 1) = 1, and the same down the column.
  const Float4 top = pixel(r0[x0], 1.0f) + fx * (pixel(r0[x1], 1.0f) - pixel(r0[x0], 1.0f));
  const Float4 bottom = pixel(r1[x0], 1.0f) + fx * (pixel(r1[x1], 1.0f) - pixel(r1[x0], 1.0f));
  return top + fy * (bottom - top);
}

// The image's colour (b, g, r) at pixel (u, v), bilinear, clamped to the image.
inline Eigen::Vector3f SampleBilinear(const cv::Mat& bgr, float u, float v) {
  const Float4 sample = SampleBilinearWithOne(bgr, u, v);
  return {sample[0], sample[1], sample[2]};
}

// ---- surface_geometry.cc

// Per vertex, the faces around it in increasing order (a face twice when it holds the vertex
// twice): faces [start[v], start[v + 1]) of `faces`.
struct VertexFaces {
  std::vector<int> start;
  std::vector<int> faces;
};

// What the steps need of the mesh's shape.
struct Surface {
  // Per face, for the atlas only (else empty): unit normals (zero for a face without area),
  // centroids, and (MeasureNeighbourhoods) normals smoothed over kNormalSmoothingPasses rings
  // (unit, or zero) and the (up to 3) faces sharing an edge with each (-1: a border edge).
  // Normals are structures of arrays.
  std::vector<float> fnx, fny, fnz;
  std::vector<Eigen::Vector3f> centroid;
  std::vector<float> snx, sny, snz;
  std::vector<std::array<int, 3>> neighbours;
  // The same per face in one place (MeasureNeighbourhoods): what a view's sweep reads of each
  // candidate face, from one cache line rather than seven arrays.
  struct FacePoint {
    float x, y, z;     // centroid
    float sx, sy, sz;  // smoothed normal
    float fx, fy, fz;  // own normal
  };
  std::vector<FacePoint> face_point;
  // Per vertex: the unit area-weighted normal, zero where it vanishes; the faces around it.
  std::vector<Eigen::Vector3f> vertex_normal;
  VertexFaces around;
  Eigen::Vector3f box_lo, box_hi;  // every vertex's box
  float mean_edge_mm = 0.0f;       // the mean length of the faces' first edges
  // The centre and radius of the box of the faces' first corners.
  Eigen::Vector3f centre;
  float radius = 0.0f;
};

// The Surface of a mesh with at least one face, but its neighbourhoods; also sets mesh->normals
// (Mesh::normals: the vertex normals, +z where they vanish). `atlas`: whether the per-face parts
// are wanted.
Surface MeasureSurface(Mesh* mesh, bool atlas);
// Adds the faces' neighbours, smoothed normals and face_point to a Surface MeasureSurface made
// with `atlas` (it writes only those).
void MeasureNeighbourhoods(const Mesh& mesh, Surface* surface);

// A group of vertices (a cell of a coarse grid over their box), with its box and normal cone.
struct Cluster {
  int begin = 0, end = 0;  // in VertexClusters' arrays
  Eigen::Vector3f lo, hi;
  Eigen::Vector3f axis = Eigen::Vector3f::Zero();
  float half_angle = static_cast<float>(M_PI);  // pi: no test
};
// The vertices and their normals as arrays, ordered cluster by cluster: a view splats only the
// clusters that can face it and project near its candidates.
struct VertexClusters {
  std::vector<Cluster> clusters;
  std::vector<float> x, y, z, nx, ny, nz;
};
VertexClusters ClusterVertices(const std::vector<Eigen::Vector3f>& vertices,
                               const Surface& surface);

// ---- view_ranking.cc

// A point's kCandidates best views, best first; empty slots: score -2, view -1.
struct Candidates {
  std::array<float, kCandidates> score;
  std::array<std::int16_t, kCandidates> view;
  Candidates() {
    score.fill(-2.0f);
    view.fill(-1);
  }
  // Keeps (s, k) if it is among the kCandidates best so far (ties: the earlier first).
  void Insert(float s, int k) {
    if (s <= score[kCandidates - 1]) return;
    int slot = kCandidates - 1;
    while (slot > 0 && score[slot - 1] < s) {
      score[slot] = score[slot - 1];
      view[slot] = view[slot - 1];
      --slot;
    }
    score[slot] = s;
    view[slot] = static_cast<std::int16_t>(k);
  }
};

// Per view k, its entries [start[k], start[k + 1]) of `entries`.
template <typename Entry>
struct PerView {
  std::vector<int> start;
  std::vector<Entry> entries;
};

// Ranking: each normal's kCandidates best views (those with an image) by the cosine to the
// direction from the mesh's centre to the camera, kept when within the mesh's angular radius of
// cos_min; the exact cosine and visibility are then tested for these only. The ranking is looked
// up: the sphere of directions is binned as a cube map, each bin holds the views ranked for its
// centre, and a normal takes its bin's views, rescored with itself.
class ViewRanking {
 public:
  ViewRanking(const std::vector<ViewGeometry>& geometry, const std::vector<cv::Mat>& images,
              const Surface& surface, float cos_min);
  // The candidates of a normal (x, y, z): its bin's views that may see it, best first (none for
  // a zero normal).
  Candidates Rank(float x, float y, float z) const;
  // Rank of each of `count` normals.
  std::vector<Candidates> Rank(int count, const float* x, const float* y, const float* z) const;
  // Per view, the faces it is a candidate for, as face * kCandidates + slot.
  PerView<std::int64_t> FacesPerView(const std::vector<Candidates>& face_candidates) const;
  // Per view, the vertices it is a candidate for (by `vertex_normal`), in the mesh's order.
  // Without `wanted`, no entries.
  PerView<int> VerticesPerView(const std::vector<Eigen::Vector3f>& vertex_normal,
                               bool wanted) const;
  // The direction from the mesh's centre to view k's camera, and how far below cos_min a
  // point's cosine to it may lie while the point's own may not (2: always ranked).
  const Eigen::Vector3f& Direction(int k) const { return direction_[k]; }
  float Margin(int k) const { return margin_[k]; }

 private:
  static constexpr int kBins = 48;  // per cube face side (under 2 degrees)
  static int BinOf(float x, float y, float z);

  float cos_min_;
  std::vector<Eigen::Vector3f> direction_;
  std::vector<float> margin_;
  std::vector<Candidates> bins_;
};

// ---- visibility.cc

// What the views saw of the candidates.
struct Sightings {
  int views_used = 0;
  // Per face and candidate slot (atlas only): the cosine of the smoothed normal to the camera
  // where the view sees the face, -2 where not.
  std::vector<float> face_cos;
  // Per vertex (vertex colours only): the weighted sum of its samples (b, g, r) and of their
  // weights.
  std::vector<Float4> color_sum;
};
// What the sweep reads (all borrowed).
struct SweepInputs {
  const Mesh& mesh;
  const Surface& surface;
  const std::vector<ViewGeometry>& geometry;
  const std::vector<cv::Mat>& images;
  const std::vector<cv::Point>& origins;  // per view: the frame pixel of images[k]'s (0, 0)
  const ViewRanking& ranking;
  const VertexClusters& clusters;
  const PerView<std::int64_t>& faces;
  const PerView<int>& vertices;
  float cos_min;
  float max_tan;  // the tangent of the largest angle a tolerance allows for
  bool atlas;
  bool vertex_colors;
};
// Per view with an image: the depth of the surface facing the camera, splatted from the vertices
// into cells about 1.5 mean edges wide, then the visibility of the view's candidates: a face seen
// records its cosine, a vertex seen adds its sample weighted by cos^8.
Sightings SweepViews(const SweepInputs& in);

// ---- atlas.cc

// Each face's view (-1: unseen): its best visible candidate, then kSmoothingPasses of iterated
// conditional modes.
std::vector<int> LabelFaces(const std::vector<float>& face_cos,
                            const std::vector<Candidates>& face_candidates,
                            const std::vector<std::array<int, 3>>& neighbours);

// The charts: connected faces with the same view.
struct Charts {
  int count = 0;
  std::vector<int> view;   // per chart
  std::vector<int> start;  // count + 2: chart c's faces [start[c], start[c + 1]); the
  std::vector<int> faces;  // unseen faces last, as chart `count`
  std::int64_t unseen_faces = 0;
};
Charts GroupCharts(const std::vector<int>& label,
                   const std::vector<std::array<int, 3>>& neighbours);

struct Rect {
  int x = 0, y = 0, w = 0, h = 0;
};
// The charts in their views: each chart's vertices (one uv per (chart, vertex), chart after
// chart, each chart's in the order its faces first reach them) projected once.
struct ChartUvs {
  std::vector<Rect> source;  // per chart: its rectangle (pixels, margin included, clamped)
  std::vector<int> start;    // count + 1: chart c's uvs [start[c], start[c + 1])
  std::vector<float> u, v;   // per uv: its vertex's pixel in the chart's view
  std::vector<std::uint8_t> in_front;     // per uv: whether it projects (else u, v unused)
  std::vector<Eigen::Vector3i> uv_faces;  // per face (of the charts): its corners' uvs
};
ChartUvs ProjectCharts(const Mesh& mesh, const Charts& charts,
                       const std::vector<ViewGeometry>& geometry);

// The charts' rectangles placed in the atlas: placed[c] for chart c, placed[charts] for the
// unseen patch; `scale` texels per image pixel.
struct Packing {
  std::vector<Rect> placed;
  double scale = 1.0;
  int width = 0;
  int height = 0;
};
// Shelf-packs the rectangles at the largest scale (1, shrinking by 0.85) that fits an atlas of a
// power-of-two width of at most max_side. Error (internal) when none does.
Expected<Packing> PackCharts(const std::vector<Rect>& source, int max_side);

// The atlas image: each chart's pixels (resized when scaled), the mid-grey patch, black between.
// `origins`: per view, the frame pixel of images[k]'s (0, 0).
cv::Mat DrawAtlas(const Charts& charts, const std::vector<Rect>& source, const Packing& packing,
                  const std::vector<cv::Mat>& images, const std::vector<cv::Point>& origins);

// Sets mesh->uvs and uv_faces: one uv per (chart, vertex), the projection into the chart's view
// mapped into its placed rectangle, and the unseen patch's centre for the unseen faces.
void AssignUvs(const Charts& charts, ChartUvs&& projected, const Packing& packing, Mesh* mesh);

}  // namespace revolve::reconstruct::texture_internal
