// Silhouette consensus: each view's mask checked against the hull the other views carve (one of
// them outvoted, ConsensusOptions::tolerated_misses). A pixel of view i stays object only if its
// ray meets the hull of the other views (within a pixel), and each view gets a confidence: how
// well its mask matches that hull's silhouette.
//
// Why: carving trusts every mask completely, so a view that lost part of the object (a shadow
// cut away) carves it from the model, and a view that took in part of the backdrop (a stand, a
// cloth) leaves a mask that disagrees with the model. The other views tell both apart.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"

namespace revolve::reconstruct {

struct ConsensusOptions {
  int resolution = 64;  // voxels along the longest side of the box, per leave-one-out hull
  // The other views' silhouette (the coarse hull's marching-cubes surface, vertices at the
  // edges' midpoints: within a voxel of the continuous hull's) is dilated by this, or by a
  // voxel's projected span if that is more, before the cut.
  int tolerance_px = 1;
  // The other views' hull keeps what this many of them carve when there are at least 8 of them:
  // a view that lost part of the object (a shadow cut away in one frame) does not carve it from
  // the hull the others are checked against, so they agree with one another and it disagrees.
  int tolerated_misses = 1;
};

struct SilhouetteConsensus {
  // Per view: IoU of its mask with the silhouette of the hull carved by all the other views.
  std::vector<double> agreement;
  // Per view: the mask cut to the other views' hull silhouette (dilated, see tolerance_px), held
  // over cut_roi[i] only (the cut mask is zero outside it): the whole masks would be a second
  // copy of the set's masks (44 MB for 36 views of 1280x960). CutMask gives the whole mask.
  std::vector<cv::Mat> masks;
  std::vector<cv::Rect> cut_roi;
  std::vector<cv::Size> size;  // per view: its mask's size

  // View i's cut mask at its mask's size. Precondition: i < masks.size().
  cv::Mat CutMask(std::size_t i) const;
};

// The leave-one-out hulls come from one carve per view (VisualHull::LeaveOneOut), not one carve
// per view and hull.
// Contract: masks (CV_8UC1) and views (depth > 0 in front of each camera, i.e. normalised)
// of one count (>= 3), each mask of its view's size, or (`mask_origins` not empty) a window of
// such a mask whose pixel (0, 0) is the view's mask_origins[i], none set outside it. Errors:
// bad_input otherwise, or an empty or inverted box.
Expected<SilhouetteConsensus> ConsensusOfSilhouettes(
    const std::vector<cv::Mat>& masks, const std::vector<View>& views,
    const Eigen::Vector3d& box_min, const Eigen::Vector3d& box_max,
    const ConsensusOptions& options = {}, const std::vector<cv::Point>& mask_origins = {});

// `mask` where `others` dilated by the ellipse of `radius` (cv::getStructuringElement's
// MORPH_ELLIPSE, 2 radius + 1 wide) is set: cv::bitwise_and(mask, dilated), the pixels of
// `others` outside the Mat counting as zero; without dilating `others`: a mask pixel on `others`
// is kept (the ellipse's centre), only those off it look for one within the ellipse.
// Precondition: CV_8UC1, one size; radius >= 0.
cv::Mat CutToDilated(const cv::Mat& mask, const cv::Mat& others, int radius);

}  // namespace revolve::reconstruct
