#include "reconstruct/hull/silhouette_consensus.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/metrics/reprojection.h"
#include "reconstruct/parallel.h"

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
  result.agreement.resize(masks.size());
  result.masks.resize(masks.size());
  // The leave-one-out hulls on all cores (reconstruct/parallel.h), each view's results in its
  // slot; the first error in view order is returned.
  // Each view is prepared once for all the hulls it carves.
  std::vector<std::optional<Error>> errors(masks.size());
  std::vector<VisualHull::PreparedView> prepared(masks.size());
  ParallelFor(0, masks.size(), [&](std::size_t j) {
    Expected<VisualHull::PreparedView> view = VisualHull::PrepareView(masks[j], views[j]);
    if (view) {
      prepared[j] = std::move(*view);
    } else {
      errors[j] = view.error();
    }
  });
  for (const std::optional<Error>& error : errors) {
    if (error) return std::unexpected(*error);
  }
  ParallelFor(0, masks.size(), [&](std::size_t i) {
    VisualHull hull(*grid);
    for (std::size_t j = 0; j < masks.size(); ++j) {
      if (j != i) hull.Integrate(prepared[j]);
    }
    const cv::Mat others = RenderSilhouette(hull.ExtractSurface(), views[i]);
    result.agreement[i] = MaskIoU(masks[i], others);
    // The coarse hull's surface may lie up to half a voxel inside the true one.
    const int radius =
        std::max(options.tolerance_px,
                 static_cast<int>(std::ceil(0.5 * VoxelSpanPx(views[i], middle, grid->voxel_mm))));
    cv::Mat allowed;
    cv::dilate(
        others, allowed,
        cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1)));
    result.masks[i] = masks[i] & allowed;
  });
  return result;
}

}  // namespace revolve::reconstruct
