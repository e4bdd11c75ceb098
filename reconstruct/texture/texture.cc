#include "reconstruct/texture/texture.h"

#include <atomic>
#include <limits>

#include <fmt/format.h>

#include "reconstruct/parallel.h"
#include "reconstruct/texture/texture_internal.h"

namespace revolve::reconstruct {
namespace {

using texture_internal::AssignUvs;
using texture_internal::Candidates;
using texture_internal::Charts;
using texture_internal::ChartUvs;
using texture_internal::ClusterVertices;
using texture_internal::DrawAtlas;
using texture_internal::Float4;
using texture_internal::GroupCharts;
using texture_internal::kUnseenColor;
using texture_internal::LabelFaces;
using texture_internal::MeasureNeighbourhoods;
using texture_internal::MeasureSurface;
using texture_internal::PackCharts;
using texture_internal::Packing;
using texture_internal::PerView;
using texture_internal::ProjectCharts;
using texture_internal::Rect;
using texture_internal::Sightings;
using texture_internal::Surface;
using texture_internal::SweepInputs;
using texture_internal::SweepViews;
using texture_internal::VertexClusters;
using texture_internal::ViewGeometry;
using texture_internal::ViewRanking;

// Errors (bad_input) for inputs TextureMesh refuses.
Expected<void> CheckInputs(const std::vector<View>& views, const std::vector<cv::Mat>& images,
                           const TextureOptions& options, const std::vector<cv::Point>& origins) {
  if (views.size() != images.size() || (!origins.empty() && origins.size() != views.size())) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{} views but {} images", views.size(), images.size()));
  }
  if (options.texture_size_px < 64 || options.texture_size_px > 16384) {
    return MakeError(ErrorCode::kBadInput, fmt::format("texture size {} px is out of range "
                                                       "[64, 16384]",
                                                       options.texture_size_px));
  }
  for (std::size_t k = 0; k < views.size(); ++k) {
    const cv::Point origin = origins.empty() ? cv::Point() : origins[k];
    const cv::Rect frame(0, 0, views[k].width_px, views[k].height_px);
    const cv::Rect window(origin, images[k].size());
    if (!images[k].empty() && (images[k].type() != CV_8UC3 || (window & frame) != window ||
                               (origins.empty() && window != frame))) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("image {} must be CV_8UC3 {}x{} (its view's size)", k,
                                   views[k].width_px, views[k].height_px));
    }
  }
  return {};
}

// Sets mesh->colors from the sums of the samples (mid-grey where there are none); returns the
// number of vertices without any.
std::int64_t ColorVertices(const std::vector<Float4>& color_sum, Mesh* mesh) {
  const std::size_t nv = mesh->vertices.size();
  mesh->colors.resize(nv);
  // On all cores: each chunk of vertices counts its unseen ones (an exact sum in any order).
  std::atomic<std::int64_t> unseen = 0;
  ParallelChunks(0, nv, 16384, [&](std::size_t lo, std::size_t hi) {
    std::int64_t chunk_unseen = 0;
    for (std::size_t vi = lo; vi < hi; ++vi) {
      const float weight = color_sum[vi][3];
      if (weight <= 0.0f) {
        ++chunk_unseen;
        mesh->colors[vi] = kUnseenColor;
        continue;
      }
      const Float4 bgr = color_sum[vi] / weight;
      auto byte = [](float x) {
        return static_cast<std::uint8_t>(std::clamp(std::lround(x), 0L, 255L));
      };
      mesh->colors[vi] = Color(byte(bgr[2]), byte(bgr[1]), byte(bgr[0]));
    }
    unseen += chunk_unseen;
  });
  return unseen;
}

}  // namespace

Expected<TextureStats> TextureMesh(Mesh* mesh, const std::vector<View>& views,
                                   const std::vector<cv::Mat>& images,
                                   const TextureOptions& options,
                                   const std::vector<cv::Point>& image_origins) {
  if (Expected<void> valid = CheckInputs(views, images, options, image_origins); !valid) {
    return std::unexpected(valid.error());
  }
  TextureStats stats;
  if (mesh->faces.empty()) {
    return stats;
  }
  Surface surface = MeasureSurface(mesh, options.atlas);
  const float cos_min = static_cast<float>(std::cos(options.max_angle_deg * M_PI / 180.0));
  const float max_tan =
      std::sqrt(std::max(0.0f, 1.0f - cos_min * cos_min)) / std::max(cos_min, 0.05f);
  std::vector<ViewGeometry> geometry;
  geometry.reserve(views.size());
  for (const View& view : views) geometry.emplace_back(view);

  // The few best views of each face and vertex, and per view the faces and vertices it may see.
  const ViewRanking ranking(geometry, images, surface, cos_min);
  // The faces' side (their neighbourhoods and views) and the vertices' side at once, each on all
  // cores where it can be.
  std::vector<Candidates> face_candidates;
  PerView<std::int64_t> faces_per_view;
  VertexClusters clusters;
  PerView<int> vertices_per_view;
  ParallelInvoke(
      [&] {
        if (options.atlas) {
          MeasureNeighbourhoods(*mesh, &surface);
          face_candidates = ranking.Rank(static_cast<int>(mesh->faces.size()), surface.snx.data(),
                                         surface.sny.data(), surface.snz.data());
        }
        faces_per_view = ranking.FacesPerView(face_candidates);
      },
      [&] {
        vertices_per_view = ranking.VerticesPerView(surface.vertex_normal, options.vertex_colors);
      },
      [&] { clusters = ClusterVertices(mesh->vertices, surface); });

  const std::vector<cv::Point> origins =
      image_origins.empty() ? std::vector<cv::Point>(views.size()) : image_origins;
  const Sightings seen = SweepViews(
      SweepInputs{*mesh, surface, geometry, images, origins, ranking, clusters, faces_per_view,
                  vertices_per_view, cos_min, max_tan, options.atlas, options.vertex_colors});
  stats.views_used = seen.views_used;
  if (options.vertex_colors) {
    stats.unseen_vertices = ColorVertices(seen.color_sum, mesh);
  }
  if (options.on_stage) options.on_stage(MeshStage::kColors);
  if (!options.atlas) {
    return stats;
  }

  const Charts charts = GroupCharts(LabelFaces(seen.face_cos, face_candidates, surface.neighbours),
                                    surface.neighbours);
  stats.unseen_faces = charts.unseen_faces;
  stats.charts = charts.count;
  ChartUvs projected = ProjectCharts(*mesh, charts, geometry);
  const std::vector<Rect> source = projected.source;
  Expected<Packing> packing = PackCharts(source, options.texture_size_px);
  if (!packing) {
    return std::unexpected(packing.error());
  }
  stats.atlas_scale = packing->scale;
  // The uvs first, for the writers waiting for them (they do not depend on the atlas's pixels).
  AssignUvs(charts, std::move(projected), *packing, mesh);
  if (options.on_stage) options.on_stage(MeshStage::kUvs);
  mesh->texture = DrawAtlas(charts, source, *packing, images, origins);
  return stats;
}

MeshRendering RenderMesh(const Mesh& mesh, const View& view) {
  MeshRendering out;
  out.image = cv::Mat(view.height_px, view.width_px, CV_8UC3, cv::Scalar(0, 0, 0));
  out.coverage = cv::Mat(view.height_px, view.width_px, CV_8UC1, cv::Scalar(0));
  const ViewGeometry g(view);
  const bool textured = mesh.HasTexture();
  const bool colors = mesh.HasColors();
  // Nearest first: q = 1 / w (pinhole) or -depth (affine), linear in the image.
  cv::Mat nearest(view.height_px, view.width_px, CV_32F,
                  cv::Scalar(-std::numeric_limits<float>::infinity()));
  const Eigen::Matrix<double, 3, 4> p = view.pixel_from_object;
  for (std::size_t fi = 0; fi < mesh.faces.size(); ++fi) {
    const Eigen::Vector3i& f = mesh.faces[fi];
    Eigen::Vector3d x[3], h[3];
    double q[3];
    bool in_front = true;
    for (int c = 0; c < 3; ++c) {
      x[c] = mesh.vertices[f[c]].cast<double>();
      h[c] = p.leftCols<3>() * x[c] + p.col(3);
      in_front = in_front && h[c].z() > 0.0;
    }
    if (!in_front) continue;
    const Eigen::Vector3d n = (x[1] - x[0]).cross(x[2] - x[0]);
    const Eigen::Vector3d centre = (x[0] + x[1] + x[2]) / 3.0;
    if (!(n.dot(view.DirectionToCamera(centre)) > 0.0)) continue;
    double u[3], v[3];
    for (int c = 0; c < 3; ++c) {
      u[c] = h[c].x() / h[c].z();
      v[c] = h[c].y() / h[c].z();
      q[c] = g.affine ? -static_cast<double>(g.Depth(mesh.vertices[f[c]])) : 1.0 / h[c].z();
    }
    const double area = (u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0]);
    if (area == 0.0) continue;
    const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({u[0], u[1], u[2]}))));
    const int x1 =
        std::min(view.width_px - 1, static_cast<int>(std::floor(std::max({u[0], u[1], u[2]}))));
    const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({v[0], v[1], v[2]}))));
    const int y1 =
        std::min(view.height_px - 1, static_cast<int>(std::floor(std::max({v[0], v[1], v[2]}))));
    for (int py = y0; py <= y1; ++py) {
      float* near_row = nearest.ptr<float>(py);
      for (int px = x0; px <= x1; ++px) {
        double l[3];
        for (int c = 0; c < 3; ++c) {
          const int a = (c + 1) % 3;
          const int b = (c + 2) % 3;
          l[c] = ((u[b] - u[a]) * (py - v[a]) - (px - u[a]) * (v[b] - v[a])) / area;
        }
        if (l[0] < 0.0 || l[1] < 0.0 || l[2] < 0.0) continue;
        const double depth_q = l[0] * q[0] + l[1] * q[1] + l[2] * q[2];
        if (!(depth_q > near_row[px])) continue;
        near_row[px] = static_cast<float>(depth_q);
        // Perspective-correct weights.
        double w[3];
        for (int c = 0; c < 3; ++c) w[c] = g.affine ? l[c] : l[c] * q[c];
        const double sum = w[0] + w[1] + w[2];
        for (double& wc : w) wc /= sum;
        Eigen::Vector3f bgr(160.0f, 160.0f, 160.0f);
        if (textured) {
          Eigen::Vector2d uv = Eigen::Vector2d::Zero();
          for (int c = 0; c < 3; ++c) uv += w[c] * mesh.uvs[mesh.uv_faces[fi][c]].cast<double>();
          bgr = texture_internal::SampleBilinear(
              mesh.texture, static_cast<float>(uv.x() * mesh.texture.cols - 0.5),
              static_cast<float>(uv.y() * mesh.texture.rows - 0.5));
        } else if (colors) {
          Eigen::Vector3f rgb = Eigen::Vector3f::Zero();
          for (int c = 0; c < 3; ++c)
            rgb += static_cast<float>(w[c]) * mesh.colors[f[c]].cast<float>();
          bgr = Eigen::Vector3f(rgb[2], rgb[1], rgb[0]);
        }
        cv::Vec3b& pixel = out.image.at<cv::Vec3b>(py, px);
        for (int k = 0; k < 3; ++k) {
          pixel[k] = static_cast<std::uint8_t>(std::clamp(std::lround(bgr[k]), 0L, 255L));
        }
        out.coverage.at<std::uint8_t>(py, px) = 255;
      }
    }
  }
  return out;
}

}  // namespace revolve::reconstruct
