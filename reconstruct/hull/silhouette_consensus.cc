#include "reconstruct/hull/silhouette_consensus.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/mask_rect.h"
#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/metrics/reprojection.h"
#include "reconstruct/parallel.h"

namespace revolve::reconstruct {
namespace {

// Other views needed for ConsensusOptions::tolerated_misses to apply.
constexpr std::size_t kMinViewsToOutvote = 8;

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
                                                     const ConsensusOptions& options,
                                                     const std::vector<cv::Point>& mask_origins) {
  if (masks.size() != views.size() || masks.size() < 3 ||
      (!mask_origins.empty() && mask_origins.size() != masks.size())) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("silhouette consensus: {} masks for {} views (3 or more needed)",
                                 masks.size(), views.size()));
  }
  // Mask i over `rect` of its view's image (zero where the mask is not held).
  const auto mask_over = [&](std::size_t i, const cv::Rect& rect) -> cv::Mat {
    if (mask_origins.empty()) return masks[i](rect);
    cv::Mat over(rect.size(), CV_8UC1, cv::Scalar(0));
    const cv::Rect held(mask_origins[i], masks[i].size());
    if (const cv::Rect both = held & rect; !both.empty()) {
      masks[i](both - held.tl()).copyTo(over(both - rect.tl()));
    }
    return over;
  };
  Expected<VoxelGrid> grid = VoxelGrid::FromBox(box_min, box_max, options.resolution);
  if (!grid) return std::unexpected(grid.error());
  const Eigen::Vector3d middle = 0.5 * (box_min + box_max);
  SilhouetteConsensus result;
  result.agreement.resize(masks.size());
  result.masks.resize(masks.size());
  result.cut_roi.resize(masks.size());
  result.size.resize(masks.size());
  // The leave-one-out hulls on all cores (reconstruct/parallel.h), each view's results in its
  // slot; the first error in view order is returned.
  // Each view is prepared once for all the hulls it carves.
  std::vector<std::optional<Error>> errors(masks.size());
  std::vector<VisualHull::PreparedView> prepared(masks.size());
  ParallelFor(0, masks.size(), [&](std::size_t j) {
    // A window is prepared as it is (the same view as its whole mask gives).
    const auto prepare = [&]() -> Expected<VisualHull::PreparedView> {
      if (mask_origins.empty()) return VisualHull::PrepareView(masks[j], views[j]);
      const cv::Rect image(0, 0, views[j].width_px, views[j].height_px);
      const cv::Rect held(mask_origins[j], masks[j].size());
      if (image.empty() || (held & image) != held) {
        return MakeError(ErrorCode::kBadInput,
                         fmt::format("silhouette consensus: mask {}'s window lies outside its "
                                     "view's {}x{} image",
                                     j, views[j].width_px, views[j].height_px));
      }
      return VisualHull::PrepareView(masks[j], mask_origins[j], views[j]);
    };
    Expected<VisualHull::PreparedView> view = prepare();
    if (view) {
      prepared[j] = std::move(*view);
    } else {
      errors[j] = view.error();
    }
  });
  for (const std::optional<Error>& error : errors) {
    if (error) return std::unexpected(*error);
  }
  std::vector<cv::Rect> mask_rects(masks.size());  // each mask's MaskRect, found in preparing it
  for (std::size_t j = 0; j < masks.size(); ++j) mask_rects[j] = prepared[j].mask_rect();
  // Each view carves once; hull i is the other views' survivors (VisualHull::LeaveOneOut).
  const VisualHull::LeaveOneOut hulls(*grid, std::move(prepared));
  HullSurfaceOptions midpoints;
  midpoints.sub_voxel = false;
  ParallelFor(0, masks.size(), [&](std::size_t i) {
    const int tolerated = masks.size() - 1 >= kMinViewsToOutvote ? options.tolerated_misses : 0;
    const Mesh surface =
        hulls.Without(i, /*keep_views=*/false, tolerated).ExtractSurface(midpoints);
    // Drawn within its own rectangle: an image of the view's size is neither cleared nor read.
    const BoxedSilhouette others = RenderSilhouetteInBox(surface, views[i], /*closed=*/true);
    // The midpoint surface lies within a voxel of the hull's: dilated by a voxel's span.
    const int radius =
        std::max(options.tolerance_px,
                 static_cast<int>(std::ceil(VoxelSpanPx(views[i], middle, grid->voxel_mm))));
    // Only the pixels within `radius` of either silhouette can be set in what follows.
    const cv::Rect image(0, 0, views[i].width_px, views[i].height_px);
    cv::Rect others_rect;
    if (!others.box.empty()) {
      others_rect = MaskRect(others.pixels);
      if (!others_rect.empty()) others_rect += others.box.tl();
    }
    cv::Rect roi = others_rect | mask_rects[i];
    roi =
        cv::Rect(roi.x - radius, roi.y - radius, roi.width + 2 * radius, roi.height + 2 * radius) &
        image;
    // The other views' silhouette over the roi (zero where it was not drawn).
    cv::Mat others_roi(roi.size(), CV_8UC1, cv::Scalar(0));
    if (const cv::Rect drawn = others.box & roi; !drawn.empty()) {
      others.pixels(drawn - others.box.tl()).copyTo(others_roi(drawn - roi.tl()));
    }
    const cv::Mat mask_roi = mask_over(i, roi);
    result.agreement[i] = MaskIoU(mask_roi, others_roi);
    result.masks[i] = CutToDilated(mask_roi, others_roi, radius);
    result.cut_roi[i] = roi;
    result.size[i] = image.size();
  });
  return result;
}

cv::Mat CutToDilated(const cv::Mat& mask, const cv::Mat& others, int radius) {
  cv::Mat cut = mask.clone();
  const cv::Mat ellipse =
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
  std::vector<cv::Point> reach;  // the ellipse's offsets from its centre
  for (int y = 0; y < ellipse.rows; ++y) {
    for (int x = 0; x < ellipse.cols; ++x) {
      if (ellipse.at<std::uint8_t>(y, x) != 0) reach.emplace_back(x - radius, y - radius);
    }
  }
  for (int y = 0; y < cut.rows; ++y) {
    std::uint8_t* row = cut.ptr<std::uint8_t>(y);
    const std::uint8_t* on = others.ptr<std::uint8_t>(y);
    for (int x = 0; x < cut.cols; ++x) {
      if (row[x] == 0 || on[x] != 0) continue;
      const bool near = std::any_of(reach.begin(), reach.end(), [&](const cv::Point& d) {
        const int u = x + d.x;
        const int v = y + d.y;
        return u >= 0 && v >= 0 && u < others.cols && v < others.rows &&
               others.at<std::uint8_t>(v, u) != 0;
      });
      if (!near) row[x] = 0;
    }
  }
  return cut;
}

cv::Mat SilhouetteConsensus::CutMask(std::size_t i) const {
  cv::Mat mask = cv::Mat::zeros(size[i], CV_8UC1);
  if (!masks[i].empty()) masks[i].copyTo(mask(cut_roi[i]));
  return mask;
}

}  // namespace revolve::reconstruct
