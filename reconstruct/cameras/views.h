// Views for reconstruction (base/rig.h View) from the three camera models, and what every model
// needs before carving: the depth sign of imported matrices and a carving volume.
//
// Camera models:
//  - thesis (calibration-free, orthographic): ThesisView. The thesis's assumptions (sec. 4.3):
//    the rotation axis on the image's middle column, aspect 1, no skew, and its choice
//    Z0 = s1 = c (eq. 4.6 -> 4.7) make a pixel one unit of length. In the object frame of
//    base/rig.h (z up the axis) the pixel (u, v) of the view at plate angle theta lies on the
//    line through the table point (u - u0, *, z) with u0 = (width - 1) / 2 and
//    z = (height - 1) - v: the bottom row's centre is z = 0. A point on the meridian plane
//    through the axis facing the camera at signed distance r = u - u0 from the axis is then
//    x = r cos(theta), y = -r sin(theta), z = row height: eq. 4.9-4.11 written in a right-handed
//    z-up frame (the thesis's frame is y-up and left-handed). Lengths are in pixels ("unscaled").
//  - calibrated turntable rig: Rig::PixelFromObject (base/rig.h).
//  - imported per-view matrices: reconstruct/cameras/camera_file.h, sign-fixed here.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"

namespace revolve::reconstruct {

// The thesis's orthographic view of the plate at `plate_angle_deg` in a width x height image
// (see the file comment; units: pixels). Affine: last row [0 0 0 1].
View ThesisView(int width_px, int height_px, double plate_angle_deg);

// A line in the object frame: origin + s * direction, |direction| = 1, direction pointing away
// from the camera (depth grows along it; for an affine view: along the viewing direction).
struct Ray {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
};

// The points that project onto `pixel` (pinhole or affine, any sign of P). nullopt when the
// projection's top two rows are degenerate there.
std::optional<Ray> BackProject(const View& view, const Eigen::Vector2d& pixel);

// The depth of a point: the third coordinate of P * [X; 1] (for an affine view the constant s).
double Depth(const View& view, const Eigen::Vector3d& point_object);

// `view` with P negated when `point_in_front` has a negative depth, so that View's contract
// holds (depth > 0 in front). An affine view is normalised on its constant last-row entry.
View NormaliseViewSign(View view, const Eigen::Vector3d& point_in_front);

// The point closest (least squares) to the rays through the centroids of the silhouettes: a
// point inside the object seen by every view, whatever the sign of each P. Views with an empty
// mask are skipped. `mask_origins` as CarvingVolumeFromSilhouettes's. Errors: bad_input when
// fewer than two rays remain or they are (nearly) parallel.
Expected<Eigen::Vector3d> SilhouetteCentre(const std::vector<cv::Mat>& masks,
                                           const std::vector<View>& views,
                                           const std::vector<cv::Point>& mask_origins = {});

struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
  Eigen::Vector3d Size() const { return max - min; }
  Eigen::Vector3d Centre() const { return 0.5 * (min + max); }
};

struct AutoVolumeOptions {
  int resolution = 64;  // cells along the longest side of each coarse pass
  // A cell survives when it lies inside the silhouette of every view that sees it and is seen by
  // at least this fraction of the views (points outside most fields of view are not object).
  double min_seen_fraction = 0.5;
  double margin_cells = 1.5;  // padding around the surviving cells, in cells of the last pass
  // A cell seen by at least 8 views survives when this many of them place it outside their
  // silhouettes: one mask that lost a part of the object (a shadow cut away in one frame) does
  // not cut the box short of it, so the silhouette consensus can find that mask out.
  int tolerated_misses = 1;
  // Blocks of cells that fall for certain (whole rows' stretches seen off the silhouettes'
  // rectangles) are passed over untested; the same volume. False: every cell tested one by one
  // (the reference the tests compare with).
  bool block_tests = true;
};

struct AutoVolume {
  Box box;                                           // the carving volume
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // SilhouetteCentre
  bool touches_limit = false;  // the coarse hull still reached the search box (unbounded views)
};

// The carving volume found from the silhouettes themselves: the centre (SilhouetteCentre), the
// views' signs fixed with it (NormaliseViewSign), a search box around it sized from the
// silhouettes' extents (doubled while the coarse hull touches it, up to 3 times), then two coarse
// carving passes (the second inside the first's box), the box of the surviving cell centres
// padded by `margin_cells`. `views` may have either sign; callers carving with them must
// normalise them with the returned centre. `mask_origins` empty: each mask is its view's whole
// image; else mask i is a window of it from mask_origins[i] on (within the image), none of the
// silhouette outside it: the same volume as the whole masks give. Errors: bad_input when the
// masks and views disagree in number or size, fewer than two masks hold an object, or nothing
// survives (the silhouettes agree on no point: wrong cameras).
Expected<AutoVolume> CarvingVolumeFromSilhouettes(const std::vector<cv::Mat>& masks,
                                                  const std::vector<View>& views,
                                                  const AutoVolumeOptions& options = {},
                                                  const std::vector<cv::Point>& mask_origins = {});

}  // namespace revolve::reconstruct
