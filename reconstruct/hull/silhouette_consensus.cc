#include "reconstruct/hull/silhouette_consensus.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/metrics/reprojection.h"

namespace revolve::reconstruct {
namespace {

// Pixels one voxel spans at the box's middle in `view` (the longest of the three axes).
double VoxelSpanPx(const View& view, const Eigen::Vector3d& middle, double voxel) {
  const auto project = [&](const Eigen::Vector3d& x) -> Eigen::Vector2d {
    const Eigen::Vector3d h = view.pixel_from_object * x.homogeneous();
    return h.head<2>() / h.z();
  };
  const Eigen::Vector2d c = project(middle);
  double span = 0.0;
  for (int a = 0; a < 3; ++a) {
    span = std::max(span, (project(middle + voxel * Eigen::Vector3d::Unit(a)) - c).norm());
  }
  return std::isfinite(span) ? span : 0.0;
}

}  // namespace

Expected<SilhouetteConsensus> ConsensusOfSilhouettes(const std::vector<cv::Mat>& masks,
                                                     const std::vector<View>& views,
                                                     const Eigen::Vector3d& box_min,
                                                     const Eigen::Vector3d& box_max,
                                                     const ConsensusOptions& options) {
  if (masks.size() != views.size() || masks.size() < 3) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("silhouette consensus: {} masks for {} views (3 or more needed)",
                                 masks.size(), views.size()));
  }
  Expected<VoxelGrid> grid = VoxelGrid::FromBox(box_min, box_max, options.resolution);
  if (!grid) return std::unexpected(grid.error());
  const Eigen::Vector3d middle = 0.5 * (box_min + box_max);
  SilhouetteConsensus result;
  for (std::size_t i = 0; i < masks.size(); ++i) {
    VisualHull hull(*grid);
    for (std::size_t j = 0; j < masks.size(); ++j) {
      if (j == i) continue;
      if (Expected<void> done = hull.Integrate(masks[j], views[j]); !done) {
        return std::unexpected(done.error());
      }
    }
    const cv::Mat others = RenderSilhouette(hull.ExtractSurface(), views[i]);
    result.agreement.push_back(MaskIoU(masks[i], others));
    // The coarse hull's surface may lie up to half a voxel inside the true one.
    const int radius =
        std::max(options.tolerance_px,
                 static_cast<int>(std::ceil(0.5 * VoxelSpanPx(views[i], middle, grid->voxel_mm))));
    cv::Mat allowed;
    cv::dilate(
        others, allowed,
        cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1)));
    result.masks.push_back(masks[i] & allowed);
  }
  return result;
}

}  // namespace revolve::reconstruct
