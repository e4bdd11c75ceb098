// The rotation axis without a board: from the silhouettes of a scan.
//
// Views 180 degrees apart see the object from opposite sides: for an orthographic camera whose
// image plane contains the axis direction (the thesis's rig) the silhouette at theta + 180 is the
// silhouette at theta mirrored about the axis's image line, so each row's left edge in one view
// and right edge in the other lie symmetrically about that line. The fit collects these
// midpoints over every opposite pair and row and fits the line u = column + slope * (v - row)
// robustly. For a pinhole camera the mirror symmetry holds to first order in (object size /
// distance), and the perspective terms cancel when averaged over a full revolution; the result is
// then a good estimate and a check, not a calibration.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"

namespace revolve::calibrate {

struct SilhouetteAxisOptions {
  // Two views count as opposite when their angles differ by 180 deg within this tolerance.
  double pair_tolerance_deg = 1.0;
  int min_pairs = 2;
  // Midpoints further than this many robust standard deviations from the line are outliers
  // (segmentation specks, rows cut by the image border).
  double outlier_sigmas = 3.0;
  bool fit_tilt = true;  // false: the axis is taken as vertical in the image
};

// The axis's image line: u = column_px + tan(tilt) * (v - reference_row_px).
struct SilhouetteAxis {
  double column_px = 0.0;         // the axis's column at the reference row
  double reference_row_px = 0.0;  // the image's middle row, (height - 1) / 2
  // Angle of the line from the image's vertical, positive when its lower end lies to the right
  // of its upper end (the image is turned clockwise relative to the axis).
  double tilt_deg = 0.0;
  double rms_px = 0.0;      // RMS distance of the inlier midpoints from the line
  double mirror_iou = 0.0;  // mean IoU of opposite silhouettes after mirroring about the line
  int pairs = 0;            // opposite view pairs used
  int samples = 0;          // inlier midpoints

  double ColumnAt(double row_px) const;
  // The column offset from the image's middle column, (width - 1) / 2: what the thesis's
  // calibration-free geometry assumes to be 0.
  double OffsetFromMiddlePx(int width_px) const { return column_px - 0.5 * (width_px - 1); }
};

// Estimates the axis line from binary masks (CV_8UC1, nonzero = object) taken at `angles_deg`.
// Pure. Errors (bad_input): masks and angles differ in number or masks in size, no pair of views
// 180 deg apart ("the silhouette fallback needs views half a turn apart: an even number of stops
// over a full turn"), empty silhouettes, too few rows seen in both views of the pairs.
Expected<SilhouetteAxis> AxisFromSilhouettes(const std::vector<cv::Mat>& masks,
                                             const std::vector<double>& angles_deg,
                                             const SilhouetteAxisOptions& options = {});

// Where a calibrated rig's axis appears in its image, as the same kind of line, for comparing a
// calibration with the silhouettes of a scan (rms_px, mirror_iou, pairs, samples are 0).
SilhouetteAxis ProjectedAxisLine(const Rig& rig);

}  // namespace revolve::calibrate
