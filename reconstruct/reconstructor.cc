#include "reconstruct/reconstructor.h"

#include <algorithm>
#include <chrono>

#include <fmt/format.h>

#include "base/log.h"
#include "reconstruct/hull/visual_hull.h"

namespace revolve::reconstruct {
namespace {

constexpr int kMinResolution = 16;
constexpr int kMaxResolution = 1024;

class HullReconstructor final : public Reconstructor {
 public:
  explicit HullReconstructor(const VoxelGrid& grid) : hull_(grid) {}

  Expected<void> Integrate(const cv::Mat& mask, const cv::Mat& /*image*/,
                           const View& view) override {
    const auto start = std::chrono::steady_clock::now();
    if (Expected<void> result = hull_.Integrate(mask, view); !result) {
      return result;
    }
    Logger("reconstruct")
        ->debug("hull: view {} carved in {:.1f} ms", hull_.view_count(),
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                    .count());
    return {};
  }

  Expected<Mesh> Finish() override {
    const auto start = std::chrono::steady_clock::now();
    if (hull_.OccupiedCount() == 0) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("the visual hull is empty after {} views: the silhouettes "
                                   "are empty or the carving volume misses the object",
                                   hull_.view_count()));
    }
    Mesh mesh = hull_.ExtractSurface();
    const VoxelGrid& grid = hull_.grid();
    Logger("reconstruct")
        ->info(
            "hull: {} views, {}x{}x{} voxels of {:.3f} mm, {} occupied; mesh {} vertices, {} "
            "triangles in {:.0f} ms",
            hull_.view_count(), grid.dims.x(), grid.dims.y(), grid.dims.z(), grid.voxel_mm,
            hull_.OccupiedCount(), mesh.vertices.size(), mesh.faces.size(),
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count());
    if (mesh.faces.empty()) {
      return MakeError(ErrorCode::kInternal, "the visual hull is not empty but has no surface");
    }
    return mesh;
  }

 private:
  VisualHull hull_;
};

}  // namespace

Expected<ReconstructOptions> ParseOptions(const config::Section& section) {
  ReconstructOptions options;
  Expected<std::string> method = section.String("method", options.method, {"hull"});
  if (!method) {
    return std::unexpected(method.error());
  }
  options.method = *method;

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
  if (formats->empty()) {
    return std::unexpected(
        section.BadValue("formats", "expected at least one of \"ply\", \"wrl\""));
  }
  options.formats.clear();
  for (const std::string& format : *formats) {
    if (format != "ply" && format != "wrl") {
      return std::unexpected(section.BadValue(
          "formats", fmt::format("\"{}\" is not one of \"ply\", \"wrl\"", format)));
    }
    if (std::find(options.formats.begin(), options.formats.end(), format) ==
        options.formats.end()) {
      options.formats.push_back(format);
    }
  }

  if (Expected<void> unknown = section.CheckNoUnknownKeys(); !unknown) {
    return std::unexpected(unknown.error());
  }
  return options;
}

Expected<std::unique_ptr<Reconstructor>> Create(const ReconstructOptions& options) {
  if (options.method != "hull") {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("unknown reconstruction method \"{}\" (expected hull)", options.method));
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
  return std::make_unique<HullReconstructor>(*grid);
}

}  // namespace revolve::reconstruct
