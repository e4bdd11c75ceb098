#include "reconstruct/reconstructor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/log.h"
#include "base/mask_rect.h"
#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/meridian/meridian.h"
#include "reconstruct/texture/texture.h"

namespace revolve::reconstruct {
namespace {

constexpr int kMinResolution = 16;
constexpr int kMaxResolution = 1024;

// Reconstructor::FrameWindow for the hull: a surface vertex lies on a grid edge from a voxel
// centre whose nearest pixel is in the silhouette (less than half a pixel off its bounding
// rectangle) at most a voxel away; the texture reads kTextureReadMarginPx around the vertices'
// projections; one pixel more for the texture's float projections.
cv::Rect HullFrameWindow(const VoxelGrid& grid, const cv::Mat& mask, const View& view) {
  const cv::Rect frame(0, 0, view.width_px, view.height_px);
  const cv::Rect roi = MaskRect(mask);
  const std::optional<double> step_px = VoxelStepBoundPx(grid, view);
  if (roi.empty() || !step_px || !(*step_px < 1e6)) return frame;
  const int margin = static_cast<int>(std::ceil(*step_px)) + kTextureReadMarginPx + 2;
  return cv::Rect(roi.x - margin, roi.y - margin, roi.width + 2 * margin, roi.height + 2 * margin) &
         frame;
}

class HullReconstructor final : public Reconstructor {
 public:
  HullReconstructor(const VoxelGrid& grid, const ReconstructOptions& options)
      : hull_(grid), options_(options) {}

  Expected<void> Integrate(const cv::Mat& mask, const cv::Mat& image, const View& view) override {
    if (!image.empty() && (image.cols != view.width_px || image.rows != view.height_px)) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("frame is {}x{}, the view {}x{}", image.cols, image.rows,
                                   view.width_px, view.height_px));
    }
    return Add(mask, image, cv::Point(), view);
  }

  cv::Rect FrameWindow(const cv::Mat& mask, const View& view) const override {
    return HullFrameWindow(hull_.grid(), mask, view);
  }

  Expected<void> IntegrateWindow(const cv::Mat& mask, const cv::Mat& image, cv::Point image_origin,
                                 const View& view) override {
    const cv::Rect window(image_origin, image.size());
    const cv::Rect needed = HullFrameWindow(hull_.grid(), mask, view);
    if (!image.empty() && ((window & cv::Rect(0, 0, view.width_px, view.height_px)) != window ||
                           (window & needed) != needed)) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("the frame's window {}x{} at ({}, {}) does not hold the "
                                   "pixels {}x{} at ({}, {}) the texture may read",
                                   image.cols, image.rows, image_origin.x, image_origin.y,
                                   needed.width, needed.height, needed.x, needed.y));
    }
    return Add(mask, image, image_origin, view);
  }

  Expected<Mesh> Finish() override {
    Mesh mesh;
    if (Expected<void> finished = FinishStaged(&mesh, {}); !finished) {
      return std::unexpected(finished.error());
    }
    return mesh;
  }

  Expected<void> FinishStaged(Mesh* out, const MeshStageHook& on_stage) override {
    const auto start = std::chrono::steady_clock::now();
    if (hull_.OccupiedCount() == 0) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("the visual hull is empty after {} views: the silhouettes "
                                   "are empty or the carving volume misses the object",
                                   hull_.view_count()));
    }
    HullSurfaceOptions surface;
    if (options_.flat_bottom) {
      surface.clip_below_z_mm = 0.0;
    }
    Mesh& mesh = *out;
    mesh = hull_.ExtractSurface(surface);
    const VoxelGrid& grid = hull_.grid();
    Logger("reconstruct")
        ->info(
            "hull: {} views, {}x{}x{} voxels of {:.3g} {}, {} occupied; mesh {} vertices, {} "
            "triangles in {:.0f} ms",
            hull_.view_count(), grid.dims.x(), grid.dims.y(), grid.dims.z(), grid.voxel_mm,
            options_.length_unit, hull_.OccupiedCount(), mesh.vertices.size(), mesh.faces.size(),
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count());
    if (mesh.faces.empty()) {
      return MakeError(ErrorCode::kInternal, "the visual hull is not empty but has no surface");
    }
    if (on_stage) on_stage(MeshStage::kSurface);
    if (options_.finish_once) hull_.ReleaseViews();
    if (std::any_of(images_.begin(), images_.end(), [](const cv::Mat& m) { return !m.empty(); })) {
      const auto texture_start = std::chrono::steady_clock::now();
      TextureOptions texture;
      texture.atlas = options_.texture;
      texture.texture_size_px = options_.texture_size_px;
      texture.on_stage = on_stage;
      Expected<TextureStats> textured = TextureMesh(&mesh, views_, images_, texture, origins_);
      if (!textured) {
        return std::unexpected(textured.error());
      }
      const double texture_ms = std::chrono::duration<double, std::milli>(
                                    std::chrono::steady_clock::now() - texture_start)
                                    .count();
      if (texture.atlas) {
        Logger("reconstruct")
            ->info(
                "texture: {} views, {} charts, atlas {}x{} at {:.2f} texel/px, {} faces unseen, "
                "in {:.0f} ms",
                textured->views_used, textured->charts, mesh.texture.cols, mesh.texture.rows,
                textured->atlas_scale, textured->unseen_faces, texture_ms);
      } else {
        Logger("reconstruct")
            ->info(
                "texture: the vertices' colours from {} views (no atlas: no format carries "
                "one), {} vertices unseen, in {:.0f} ms",
                textured->views_used, textured->unseen_vertices, texture_ms);
      }
    }
    if (on_stage) on_stage(MeshStage::kDone);
    return {};
  }

 private:
  Expected<void> Add(const cv::Mat& mask, const cv::Mat& image, cv::Point image_origin,
                     const View& view) {
    const auto start = std::chrono::steady_clock::now();
    if (Expected<void> result = hull_.Integrate(mask, view); !result) {
      return result;
    }
    views_.push_back(view);
    origins_.push_back(image_origin);
    cv::Mat bgr;  // a copy: a camera may reuse its frame buffers
    if (image.empty()) {
      // no colour from this view
    } else if (image.type() == CV_8UC3) {
      bgr = options_.share_frames ? image : image.clone();
    } else if (image.type() == CV_8UC1) {
      cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
    } else if (image.type() == CV_8UC4) {
      cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
    }
    images_.push_back(bgr);
    Logger("reconstruct")
        ->debug("hull: view {} carved in {:.1f} ms", hull_.view_count(),
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                    .count());
    return {};
  }

  VisualHull hull_;
  ReconstructOptions options_;
  std::vector<View> views_;
  std::vector<cv::Mat> images_;
  std::vector<cv::Point> origins_;  // per view: the frame pixel of images_[k]'s (0, 0)
};

}  // namespace

Expected<void> Reconstructor::FinishStaged(Mesh* mesh, const MeshStageHook& on_stage) {
  Expected<Mesh> finished = Finish();
  if (!finished) return std::unexpected(finished.error());
  *mesh = std::move(*finished);
  if (on_stage) on_stage(MeshStage::kDone);
  return {};
}

cv::Rect Reconstructor::FrameWindow(const cv::Mat& /*mask*/, const View& view) const {
  return cv::Rect(0, 0, view.width_px, view.height_px);
}

Expected<void> Reconstructor::IntegrateWindow(const cv::Mat& mask, const cv::Mat& image,
                                              cv::Point image_origin, const View& view) {
  if (!image.empty() && (image_origin != cv::Point() || image.cols != view.width_px ||
                         image.rows != view.height_px)) {
    return MakeError(ErrorCode::kBadInput, "this method reads whole frames, not windows");
  }
  return Integrate(mask, image, view);
}

Expected<ReconstructOptions> ParseOptions(const config::Section& section) {
  ReconstructOptions options;
  Expected<std::string> method = section.String("method", options.method, {"hull", "meridian"});
  if (!method) {
    return std::unexpected(method.error());
  }
  options.method = *method;
  Expected<std::int64_t> row_step =
      section.Integer("meridian_row_step_px", options.meridian_row_step_px, 1, 256);
  if (!row_step) {
    return std::unexpected(row_step.error());
  }
  options.meridian_row_step_px = static_cast<int>(*row_step);
  Expected<bool> both_sides = section.Boolean("meridian_both_sides", options.meridian_both_sides);
  if (!both_sides) {
    return std::unexpected(both_sides.error());
  }
  options.meridian_both_sides = *both_sides;

  Expected<std::int64_t> resolution =
      section.Integer("resolution", options.resolution, kMinResolution, kMaxResolution);
  if (!resolution) {
    return std::unexpected(resolution.error());
  }
  options.resolution = static_cast<int>(*resolution);

  Expected<double> radius_mm = section.Number("volume_radius_mm", 60.0, 1.0, 10000.0);
  if (!radius_mm) {
    return std::unexpected(radius_mm.error());
  }
  Expected<double> height_mm = section.Number("volume_height_mm", 120.0, 1.0, 10000.0);
  if (!height_mm) {
    return std::unexpected(height_mm.error());
  }
  options.bbox_min_mm = Eigen::Vector3d(-*radius_mm, -*radius_mm, 0.0);
  options.bbox_max_mm = Eigen::Vector3d(*radius_mm, *radius_mm, *height_mm);

  Expected<std::vector<std::string>> formats = section.Strings("formats", options.formats);
  if (!formats) {
    return std::unexpected(formats.error());
  }
  constexpr const char* kFormatList = R"("ply", "obj", "stl", "glb", "wrl")";
  if (formats->empty()) {
    return std::unexpected(
        section.BadValue("formats", fmt::format("expected at least one of {}", kFormatList)));
  }
  options.formats.clear();
  for (const std::string& format : *formats) {
    if (!IsModelFormat(format)) {
      return std::unexpected(
          section.BadValue("formats", fmt::format("\"{}\" is not one of {}", format, kFormatList)));
    }
    if (std::find(options.formats.begin(), options.formats.end(), format) ==
        options.formats.end()) {
      options.formats.push_back(format);
    }
  }

  Expected<bool> texture = section.Boolean("texture", options.texture);
  if (!texture) {
    return std::unexpected(texture.error());
  }
  options.texture = *texture;
  Expected<std::int64_t> texture_size =
      section.Integer("texture_size_px", options.texture_size_px, 64, 16384);
  if (!texture_size) {
    return std::unexpected(texture_size.error());
  }
  options.texture_size_px = static_cast<int>(*texture_size);
  Expected<bool> flat_bottom = section.Boolean("flat_bottom", options.flat_bottom);
  if (!flat_bottom) {
    return std::unexpected(flat_bottom.error());
  }
  options.flat_bottom = *flat_bottom;

  if (Expected<void> unknown = section.CheckNoUnknownKeys(); !unknown) {
    return std::unexpected(unknown.error());
  }
  return options;
}

Expected<std::unique_ptr<Reconstructor>> Create(const ReconstructOptions& options) {
  if (options.method == "meridian") {
    if (options.meridian_row_step_px < 1 || options.meridian_row_step_px > 256) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("meridian row step {} px is out of range [1, 256]",
                                   options.meridian_row_step_px));
    }
    return std::make_unique<MeridianReconstructor>(
        MeridianOptions{options.meridian_row_step_px, options.meridian_both_sides,
                        options.texture ? options.texture_size_px : 0});
  }
  if (options.method != "hull") {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("unknown reconstruction method \"{}\" (expected hull or "
                                 "meridian)",
                                 options.method));
  }
  if (options.resolution < kMinResolution || options.resolution > kMaxResolution) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("resolution {} is out of range [{}, {}]", options.resolution,
                                 kMinResolution, kMaxResolution));
  }
  Expected<VoxelGrid> grid =
      VoxelGrid::FromBox(options.bbox_min_mm, options.bbox_max_mm, options.resolution);
  if (!grid) {
    return std::unexpected(grid.error());
  }
  return std::make_unique<HullReconstructor>(*grid, options);
}

}  // namespace revolve::reconstruct
