#include "reconstruct/meridian/meridian.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/log.h"
#include "reconstruct/cameras/views.h"
#include "reconstruct/texture/view_atlas.h"

namespace revolve::reconstruct {
namespace {

// A view must see a strip at more than ~25 deg from grazing to texture it.
constexpr double kMinTextureCosine = 0.42;

// The point of the ray closest to the object's z axis; nullopt when the ray runs along the axis.
std::optional<Eigen::Vector3d> ClosestToAxis(const Ray& ray) {
  const Eigen::Vector2d d = ray.direction.head<2>();
  const double dd = d.squaredNorm();
  if (!(dd > 1e-12)) return std::nullopt;
  const double s = -ray.origin.head<2>().dot(d) / dd;
  return Eigen::Vector3d(ray.origin + s * ray.direction);
}

std::optional<Eigen::Vector3d> FeaturePoint(const View& view, double u, double v) {
  const std::optional<Ray> ray = BackProject(view, Eigen::Vector2d(u, v));
  if (!ray) return std::nullopt;
  return ClosestToAxis(*ray);
}

double AngularDistance(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 2.0 * std::numbers::pi);
  return std::min(d, 2.0 * std::numbers::pi - d);
}

}  // namespace

MeridianReconstructor::MeridianReconstructor(const MeridianOptions& options) : options_(options) {}

Expected<void> MeridianReconstructor::Integrate(const cv::Mat& mask, const cv::Mat& image,
                                                const View& view) {
  if (mask.type() != CV_8UC1 || mask.cols != view.width_px || mask.rows != view.height_px) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("meridian: view {}: the mask must be CV_8UC1 of the view's size "
                                 "{}x{} (got {}x{}, type {})",
                                 views_.size(), view.width_px, view.height_px, mask.cols, mask.rows,
                                 mask.type()));
  }
  if (!views_.empty() && (view.width_px != width_px_ || view.height_px != height_px_)) {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("meridian: view {} is {}x{} but the first was {}x{}", views_.size(),
                    view.width_px, view.height_px, width_px_, height_px_));
  }
  if (!view.pixel_from_object.allFinite()) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("meridian: view {}: non-finite projection", views_.size()));
  }
  ViewData data;
  data.view = view;
  if (!image.empty()) {
    if (image.size() != mask.size() || image.depth() != CV_8U ||
        (image.channels() != 3 && image.channels() != 1)) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("meridian: view {}: the image must be 8-bit BGR or grey of "
                                   "the mask's size",
                                   views_.size()));
    }
    if (image.channels() == 1) {
      cv::cvtColor(image, data.image, cv::COLOR_GRAY2BGR);
    } else {
      data.image = image;
    }
  }

  // The imaged axis: the line through the images of the axis's origin and of its direction.
  const Eigen::Vector3d origin_image = view.pixel_from_object.col(3);
  const Eigen::Vector3d direction_image = view.pixel_from_object.col(2);
  const Eigen::Vector3d axis_line = origin_image.cross(direction_image);
  if (!(std::abs(axis_line.x()) > 1e-9 * axis_line.norm())) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("meridian: view {}: the rotation axis does not cross the image "
                                 "rows (the camera looks along it)",
                                 views_.size()));
  }
  const auto axis_u = [&](double v) {
    return -(axis_line.z() + axis_line.y() * v) / axis_line.x();
  };

  // Every row's edge points are kept; FinishModel picks the rows (every k-th from the object's
  // top, and its bottom row).
  const int width = mask.cols;
  const int rows = mask.rows;
  Meridian left;
  Meridian right;
  left.view = right.view = static_cast<int>(views_.size());
  right.left = false;
  left.points.resize(static_cast<std::size_t>(rows));
  right.points.resize(static_cast<std::size_t>(rows));
  left.axis_points.resize(static_cast<std::size_t>(rows));
  for (int v = 0; v < rows; ++v) {
    const double u_axis = axis_u(v);
    const std::optional<Eigen::Vector3d> on_axis = FeaturePoint(view, u_axis, v);
    if (!on_axis) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("meridian: view {}: row {} cannot be back-projected to the axis",
                                   views_.size(), v));
    }
    left.axis_points[static_cast<std::size_t>(v)] = *on_axis;
    const auto* row = mask.ptr<std::uint8_t>(v);
    int first = -1;
    int last = -1;
    for (int u = 0; u < width; ++u) {
      if (row[u] == 0) continue;
      if (first < 0) first = u;
      last = u;
    }
    if (first < 0) continue;
    // Leftmost pixel left of the axis (its outer edge); none: the row's point is on the axis.
    left.points[static_cast<std::size_t>(v)] =
        first <= u_axis ? FeaturePoint(view, first - 0.5, v) : on_axis;
    right.points[static_cast<std::size_t>(v)] =
        last >= u_axis ? FeaturePoint(view, last + 0.5, v) : on_axis;
  }
  right.axis_points = left.axis_points;
  // Azimuths of the two half-planes: a pixel an eighth of the width off the axis, mid-height.
  const double v_mid = 0.5 * (mask.rows - 1);
  const double offset = std::max(1.0, 0.125 * width);
  for (Meridian* m : {&left, &right}) {
    const double u = axis_u(v_mid) + (m->left ? -offset : offset);
    const std::optional<Eigen::Vector3d> p = FeaturePoint(view, u, v_mid);
    if (!p || p->head<2>().norm() == 0.0) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("meridian: view {}: cannot tell the meridian's azimuth", views_.size()));
    }
    m->azimuth_rad = std::atan2(p->y(), p->x());
  }
  if (views_.empty()) {
    width_px_ = view.width_px;
    height_px_ = view.height_px;
  }
  views_.push_back(std::move(data));
  meridians_.push_back(std::move(left));
  if (options_.both_sides) meridians_.push_back(std::move(right));
  return {};
}

Expected<Mesh> MeridianReconstructor::Finish() {
  Expected<MeridianModel> model = FinishModel();
  if (!model) return std::unexpected(model.error());
  return std::move(model->mesh);
}

Expected<std::vector<const MeridianReconstructor::Meridian*>>
MeridianReconstructor::ChooseMeridians() const {
  // Meridians in azimuth order: left ones (duplicates of one azimuth dropped), then right ones not
  // within a quarter step of a left one.
  std::vector<const Meridian*> chosen;
  for (const Meridian& m : meridians_) {
    if (!m.left) continue;
    const bool duplicate = std::any_of(chosen.begin(), chosen.end(), [&](const Meridian* c) {
      return AngularDistance(c->azimuth_rad, m.azimuth_rad) < 1e-6;
    });
    if (!duplicate) chosen.push_back(&m);
  }
  const std::size_t left_count = chosen.size();
  if (left_count > 0) {
    const double quarter_step = 0.25 * 2.0 * std::numbers::pi / static_cast<double>(left_count);
    for (const Meridian& m : meridians_) {
      if (m.left) continue;
      const bool near = std::any_of(chosen.begin(), chosen.end(), [&](const Meridian* c) {
        return AngularDistance(c->azimuth_rad, m.azimuth_rad) < quarter_step;
      });
      if (!near) chosen.push_back(&m);
    }
  }
  if (chosen.size() < 3) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("meridian: {} distinct meridian(s) from {} view(s); at least 3 "
                                 "are needed",
                                 chosen.size(), views_.size()));
  }
  std::sort(chosen.begin(), chosen.end(),
            [](const Meridian* a, const Meridian* b) { return a->azimuth_rad < b->azimuth_rad; });
  return chosen;
}

Expected<std::vector<int>> MeridianReconstructor::SampledRows(
    const std::vector<const Meridian*>& chosen) const {
  const int all_rows = static_cast<int>(chosen.front()->points.size());
  int first_row = all_rows;
  int last_row = -1;
  for (const Meridian* m : chosen) {
    for (int v = 0; v < all_rows; ++v) {
      if (m->points[static_cast<std::size_t>(v)]) {
        first_row = std::min(first_row, v);
        last_row = std::max(last_row, v);
      }
    }
  }
  if (last_row < 0) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("meridian: no image row holds an object pixel in {} view(s): the "
                                 "silhouettes are empty",
                                 views_.size()));
  }
  if (last_row == first_row) {
    return MakeError(ErrorCode::kBadInput,
                     "meridian: the object spans a single image row: no surface to form");
  }
  // Rows: every k-th from the object's top row, and its bottom row.
  std::vector<int> rows;
  for (int v = first_row; v < last_row; v += options_.row_step_px) rows.push_back(v);
  rows.push_back(last_row);

  return rows;
}

std::vector<int> MeridianReconstructor::BuildMesh(const std::vector<const Meridian*>& chosen,
                                                  const std::vector<int>& rows,
                                                  MeridianModel* model) {
  Mesh& mesh = model->mesh;
  const int meridian_count = model->meridian_count;
  const int row_count = model->row_count;
  const int first_row = rows.front();
  const int last_row = rows.back();
  Eigen::Vector3d top = Eigen::Vector3d::Zero();
  Eigen::Vector3d bottom = Eigen::Vector3d::Zero();
  for (const Meridian* m : chosen) {
    for (const int v : rows) {
      const auto& p = m->points[static_cast<std::size_t>(v)];
      mesh.vertices.push_back((p ? *p : m->axis_points[static_cast<std::size_t>(v)]).cast<float>());
    }
    top += m->axis_points[static_cast<std::size_t>(first_row)];
    bottom += m->axis_points[static_cast<std::size_t>(last_row)];
  }
  const int top_index = static_cast<int>(mesh.vertices.size());
  mesh.vertices.push_back((top / meridian_count).cast<float>());
  const int bottom_index = top_index + 1;
  mesh.vertices.push_back((bottom / meridian_count).cast<float>());
  const auto vertex = [&](int m, int j) { return (m % meridian_count) * row_count + j; };

  // Faces per strip (the quads between meridians m and m + 1), then the caps. Image rows run
  // down and azimuths counter-clockwise from above, which makes these outward for an upright
  // camera; the whole mesh is flipped below when the signed volume says otherwise.
  std::vector<int> face_strip;  // strip of each face; meridian_count = top cap, + 1 = bottom cap
  for (int m = 0; m < meridian_count; ++m) {
    for (int j = 0; j + 1 < row_count; ++j) {
      const int a = vertex(m, j);
      const int b = vertex(m + 1, j);
      const int c = vertex(m, j + 1);
      const int d = vertex(m + 1, j + 1);
      mesh.faces.emplace_back(a, c, b);
      mesh.faces.emplace_back(b, c, d);
      face_strip.push_back(m);
      face_strip.push_back(m);
    }
  }
  for (int m = 0; m < meridian_count; ++m) {
    mesh.faces.emplace_back(top_index, vertex(m, 0), vertex(m + 1, 0));
    face_strip.push_back(meridian_count);
  }
  for (int m = 0; m < meridian_count; ++m) {
    mesh.faces.emplace_back(bottom_index, vertex(m + 1, row_count - 1), vertex(m, row_count - 1));
    face_strip.push_back(meridian_count + 1);
  }
  double volume = 0.0;
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3d a = mesh.vertices[f[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[f[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[f[2]].cast<double>();
    volume += a.dot(b.cross(c)) / 6.0;
  }
  if (volume < 0.0) {
    for (Eigen::Vector3i& f : mesh.faces) std::swap(f[1], f[2]);
  }

  return face_strip;
}

Expected<void> MeridianReconstructor::TextureStrips(const std::vector<int>& face_strip,
                                                    MeridianModel* model) const {
  // Texture: per strip (and cap) the view facing it most squarely.
  const bool any_image =
      std::any_of(views_.begin(), views_.end(), [](const ViewData& v) { return !v.image.empty(); });
  if (!any_image) return {};
  Mesh& mesh = model->mesh;
  const int meridian_count = model->meridian_count;
  const int row_count = model->row_count;
  const int groups = meridian_count + 2;
  std::vector<Eigen::Vector3d> normal(static_cast<std::size_t>(groups), Eigen::Vector3d::Zero());
  std::vector<Eigen::Vector3d> centre(static_cast<std::size_t>(groups), Eigen::Vector3d::Zero());
  std::vector<double> area(static_cast<std::size_t>(groups), 0.0);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Eigen::Vector3d a = mesh.vertices[mesh.faces[f][0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[mesh.faces[f][1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[mesh.faces[f][2]].cast<double>();
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const auto g = static_cast<std::size_t>(face_strip[f]);
    normal[g] += n;
    centre[g] += 0.5 * n.norm() * (a + b + c) / 3.0;
    area[g] += 0.5 * n.norm();
  }
  std::vector<int> group_view(static_cast<std::size_t>(groups), -1);
  std::map<int, int> texture_of_view;
  for (int g = 0; g < groups; ++g) {
    const std::size_t gi = static_cast<std::size_t>(g);
    if (!(area[gi] > 0.0) || normal[gi].norm() == 0.0) continue;
    const Eigen::Vector3d n = normal[gi].normalized();
    const Eigen::Vector3d c = centre[gi] / area[gi];
    double best = kMinTextureCosine;
    for (std::size_t v = 0; v < views_.size(); ++v) {
      if (views_[v].image.empty()) continue;
      const double score = n.dot(views_[v].view.DirectionToCamera(c));
      if (score > best) {
        best = score;
        group_view[gi] = static_cast<int>(v);
      }
    }
    if (group_view[gi] >= 0 && texture_of_view.count(group_view[gi]) == 0) {
      const int t = static_cast<int>(mesh.view_texture.images.size());
      texture_of_view[group_view[gi]] = t;
      mesh.view_texture.images.push_back(views_[static_cast<std::size_t>(group_view[gi])].image);
    }
  }
  // Texture coordinates: one per (group, vertex), the vertex projected into the group's view.
  std::map<std::pair<int, int>, int> uv_index;
  const auto uv_of = [&](int g, int vertex_index) {
    const auto key = std::make_pair(g, vertex_index);
    if (const auto it = uv_index.find(key); it != uv_index.end()) return it->second;
    const View& view =
        views_[static_cast<std::size_t>(group_view[static_cast<std::size_t>(g)])].view;
    Eigen::Vector2d pixel(0.0, 0.0);
    (void)view.Project(mesh.vertices[vertex_index].cast<double>(), &pixel);
    const double s = std::clamp((pixel.x() + 0.5) / view.width_px, 0.0, 1.0);
    const double t = std::clamp(1.0 - (pixel.y() + 0.5) / view.height_px, 0.0, 1.0);
    const int index = static_cast<int>(mesh.view_texture.uvs.size());
    mesh.view_texture.uvs.emplace_back(static_cast<float>(s), static_cast<float>(t));
    uv_index.emplace(key, index);
    return index;
  };
  mesh.view_texture.uv_faces.resize(mesh.faces.size(), Eigen::Vector3i::Zero());
  mesh.view_texture.face_image.resize(mesh.faces.size(), -1);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const int g = face_strip[f];
    const int view = group_view[static_cast<std::size_t>(g)];
    if (view < 0) continue;
    mesh.view_texture.face_image[f] = texture_of_view[view];
    for (int k = 0; k < 3; ++k) mesh.view_texture.uv_faces[f][k] = uv_of(g, mesh.faces[f][k]);
  }
  // Untextured faces point at it.
  if (mesh.view_texture.uvs.empty()) mesh.view_texture.uvs.emplace_back(0.0f, 0.0f);
  if (options_.atlas_size_px > 0) {
    if (Expected<void> atlas = AtlasFromViewTexture(&mesh, options_.atlas_size_px); !atlas) {
      return std::unexpected(atlas.error());
    }
  }
  Logger("reconstruct")
      ->info(
          "meridian: {} views, {} meridians x {} rows (every {} px), {} triangles, {} "
          "texture image(s), atlas {}x{}",
          views_.size(), meridian_count, row_count, options_.row_step_px, mesh.faces.size(),
          mesh.view_texture.images.size(), mesh.texture.cols, mesh.texture.rows);
  return {};
}

Expected<MeridianModel> MeridianReconstructor::FinishModel() const {
  Expected<std::vector<const Meridian*>> chosen = ChooseMeridians();
  if (!chosen) return std::unexpected(chosen.error());
  Expected<std::vector<int>> rows = SampledRows(*chosen);
  if (!rows) return std::unexpected(rows.error());
  MeridianModel model;
  model.meridian_count = static_cast<int>(chosen->size());
  model.row_count = static_cast<int>(rows->size());
  const std::vector<int> face_strip = BuildMesh(*chosen, *rows, &model);
  if (Expected<void> textured = TextureStrips(face_strip, &model); !textured) {
    return std::unexpected(textured.error());
  }
  return model;
}

}  // namespace revolve::reconstruct
