#include "reconstruct/texture/view_atlas.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace revolve::reconstruct {
namespace {

constexpr int kMarginPx = 2;
constexpr int kGreyPatchPx = 4;
constexpr int kMinAtlasPx = 64;
constexpr int kMaxAtlasPx = 16384;
const cv::Scalar kGrey(204, 204, 204);  // 0.8, the VRML material's diffuse colour

// A rectangle of a source image (or the grey patch: image -1) and where it lands in the atlas.
struct Patch {
  int image = -1;
  cv::Rect source;  // in the image's pixels
  cv::Size size;    // in the atlas (the source scaled)
  cv::Point place;
};

// Shelf packing, tallest first, into rows `width` wide: the atlas height, or -1 when a patch is
// wider than the atlas.
int Pack(std::vector<Patch>* patches, int width) {
  std::vector<Patch*> order;
  for (Patch& p : *patches) order.push_back(&p);
  std::stable_sort(order.begin(), order.end(),
                   [](const Patch* a, const Patch* b) { return a->size.height > b->size.height; });
  int x = 0;
  int y = 0;
  int shelf = 0;
  for (Patch* p : order) {
    if (p->size.width > width) return -1;
    if (x + p->size.width > width) {
      y += shelf;
      x = 0;
      shelf = 0;
    }
    p->place = cv::Point(x, y);
    x += p->size.width;
    shelf = std::max(shelf, p->size.height);
  }
  return y + shelf;
}

// Scales the patches and packs them into the narrowest power-of-two width holding them in a
// square or less, else the widest allowed; shrinks while they do not fit. The atlas size.
cv::Size Layout(std::vector<Patch>* patches, int atlas_size_px) {
  for (double scale = 1.0;; scale *= 0.9) {
    int widest = 1;
    for (Patch& p : *patches) {
      const bool grey = p.image < 0;
      p.size = grey ? p.source.size()
                    : cv::Size(std::max(1, static_cast<int>(std::ceil(p.source.width * scale))),
                               std::max(1, static_cast<int>(std::ceil(p.source.height * scale))));
      widest = std::max(widest, p.size.width);
    }
    int width = kMinAtlasPx;
    while (width < widest && width < atlas_size_px) width *= 2;
    for (; width <= atlas_size_px; width *= 2) {
      const int height = Pack(patches, width);
      if (height < 0) continue;
      if (height <= width || (width * 2 > atlas_size_px && height <= atlas_size_px)) {
        return cv::Size(width, height);
      }
    }
  }
}

}  // namespace

Expected<void> AtlasFromViewTexture(Mesh* mesh, int atlas_size_px) {
  const ViewTexture& vt = mesh->view_texture;
  if (!mesh->HasViewTexture()) {
    return MakeError(ErrorCode::kBadInput, "texture atlas: the mesh has no view-dependent texture");
  }
  if (atlas_size_px < kMinAtlasPx || atlas_size_px > kMaxAtlasPx) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("texture atlas: size {} px is out of range [{}, {}]",
                                 atlas_size_px, kMinAtlasPx, kMaxAtlasPx));
  }
  const int image_count = static_cast<int>(vt.images.size());
  for (const cv::Mat& image : vt.images) {
    if (image.type() != CV_8UC3 || image.empty()) {
      return MakeError(ErrorCode::kBadInput, "texture atlas: a view image is not 8-bit BGR");
    }
  }
  // The pixel rectangle (edge coordinates) each image's faces span: min x, min y, max x, max y.
  std::vector<cv::Vec4d> span(static_cast<std::size_t>(image_count),
                              cv::Vec4d(HUGE_VAL, HUGE_VAL, -HUGE_VAL, -HUGE_VAL));
  bool any_grey = false;
  const auto pixel_of = [&](int image, int uv) {
    const cv::Mat& m = vt.images[static_cast<std::size_t>(image)];
    const Eigen::Vector2f& st = vt.uvs[static_cast<std::size_t>(uv)];
    return cv::Point2d(st.x() * m.cols, (1.0 - st.y()) * m.rows);
  };
  for (std::size_t f = 0; f < mesh->faces.size(); ++f) {
    const int image = vt.face_image[f];
    if (image < 0) {
      any_grey = true;
      continue;
    }
    if (image >= image_count) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("texture atlas: face {} names image {} of {}", f, image, image_count));
    }
    for (int c = 0; c < 3; ++c) {
      const int uv = vt.uv_faces[f][c];
      if (uv < 0 || uv >= static_cast<int>(vt.uvs.size())) {
        return MakeError(
            ErrorCode::kBadInput,
            fmt::format("texture atlas: face {} names uv {} of {}", f, uv, vt.uvs.size()));
      }
      const cv::Point2d p = pixel_of(image, uv);
      cv::Vec4d& r = span[static_cast<std::size_t>(image)];
      r = cv::Vec4d(std::min(r[0], p.x), std::min(r[1], p.y), std::max(r[2], p.x),
                    std::max(r[3], p.y));
    }
  }
  std::vector<Patch> patches;
  std::vector<int> patch_of_image(static_cast<std::size_t>(image_count), -1);
  for (int i = 0; i < image_count; ++i) {
    const cv::Vec4d& r = span[static_cast<std::size_t>(i)];
    if (r[0] > r[2]) continue;  // no face uses the image
    const cv::Mat& m = vt.images[static_cast<std::size_t>(i)];
    const int x0 = std::clamp(static_cast<int>(std::floor(r[0])) - kMarginPx, 0, m.cols - 1);
    const int y0 = std::clamp(static_cast<int>(std::floor(r[1])) - kMarginPx, 0, m.rows - 1);
    const int x1 = std::clamp(static_cast<int>(std::ceil(r[2])) + kMarginPx, x0 + 1, m.cols);
    const int y1 = std::clamp(static_cast<int>(std::ceil(r[3])) + kMarginPx, y0 + 1, m.rows);
    patch_of_image[static_cast<std::size_t>(i)] = static_cast<int>(patches.size());
    patches.push_back(Patch{i, cv::Rect(x0, y0, x1 - x0, y1 - y0), {}, {}});
  }
  if (any_grey) patches.push_back(Patch{-1, cv::Rect(0, 0, kGreyPatchPx, kGreyPatchPx), {}, {}});
  const cv::Size atlas_size = Layout(&patches, atlas_size_px);

  cv::Mat atlas(atlas_size, CV_8UC3, cv::Scalar(0, 0, 0));
  for (const Patch& p : patches) {
    cv::Mat target = atlas(cv::Rect(p.place, p.size));
    if (p.image < 0) {
      target.setTo(kGrey);
    } else if (p.size == p.source.size()) {
      vt.images[static_cast<std::size_t>(p.image)](p.source).copyTo(target);
    } else {
      cv::resize(vt.images[static_cast<std::size_t>(p.image)](p.source), target, p.size, 0, 0,
                 cv::INTER_AREA);
    }
  }
  // One atlas uv per distinct point; the grey patch's centre for untextured faces.
  std::vector<Eigen::Vector2f> uvs;
  std::vector<Eigen::Vector3i> uv_faces(mesh->faces.size(), Eigen::Vector3i::Zero());
  std::map<std::pair<float, float>, int> uv_of_point;
  int grey_uv = -1;
  for (std::size_t f = 0; f < mesh->faces.size(); ++f) {
    const int image = vt.face_image[f];
    if (image < 0) {
      if (grey_uv < 0) {
        const Patch& grey = patches.back();
        grey_uv = static_cast<int>(uvs.size());
        uvs.emplace_back(
            static_cast<float>((grey.place.x + 0.5 * grey.size.width) / atlas_size.width),
            static_cast<float>((grey.place.y + 0.5 * grey.size.height) / atlas_size.height));
      }
      uv_faces[f] = Eigen::Vector3i::Constant(grey_uv);
      continue;
    }
    const Patch& p =
        patches[static_cast<std::size_t>(patch_of_image[static_cast<std::size_t>(image)])];
    const double sx = static_cast<double>(p.size.width) / p.source.width;
    const double sy = static_cast<double>(p.size.height) / p.source.height;
    for (int c = 0; c < 3; ++c) {
      const cv::Point2d pixel = pixel_of(image, vt.uv_faces[f][c]);
      const Eigen::Vector2f atlas_point(
          static_cast<float>((p.place.x + (pixel.x - p.source.x) * sx) / atlas_size.width),
          static_cast<float>((p.place.y + (pixel.y - p.source.y) * sy) / atlas_size.height));
      // Equal points share one uv (neighbouring strips textured from the same view meet there).
      const auto [it, added] = uv_of_point.try_emplace(
          std::make_pair(atlas_point.x(), atlas_point.y()), static_cast<int>(uvs.size()));
      if (added) uvs.push_back(atlas_point);
      uv_faces[f][c] = it->second;
    }
  }
  mesh->texture = atlas;
  mesh->uvs = std::move(uvs);
  mesh->uv_faces = std::move(uv_faces);
  return {};
}

}  // namespace revolve::reconstruct
