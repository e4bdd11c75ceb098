// Pure operations on binary masks (CV_8UC1, 0 or 255), the steps of silhouette segmentation.
#pragma once

#include <opencv2/core.hpp>

namespace revolve::capture {

// Grey level of an 8-bit image: the image itself for one channel, cv::cvtColor for BGR and
// BGRA. Contract: depth CV_8U with 1, 3 or 4 channels.
cv::Mat GreyLevels(const cv::Mat& image);

// Opening (radius_px > 0) with an elliptical kernel of diameter 2 * radius_px + 1: removes
// specks and one-pixel spurs narrower than the kernel. radius_px <= 0 returns the mask as is.
cv::Mat OpenMask(const cv::Mat& mask, int radius_px);

// Closing with the same kernel: fills pinholes and cracks narrower than the kernel.
cv::Mat CloseMask(const cv::Mat& mask, int radius_px);

// The largest 8-connected component of a mask (ties: the lowest label, i.e. the first in raster
// order); an all-zero mask when there is none.
cv::Mat KeepLargestComponent(const cv::Mat& mask);

// The pixels of `through` 8-connected through `through` to a pixel of `seeds` (both CV_8UC1,
// non-zero set; seeds outside `through` reach nothing): 255 there, 0 elsewhere.
cv::Mat ConnectedThrough(const cv::Mat& through, const cv::Mat& seeds);

// Sets every background pixel that is not 4-connected to the image border (a hole) to 255.
// 4-connected background is the complement of 8-connected foreground, so a ring closed only
// diagonally still counts as closed.
cv::Mat FillHoles(const cv::Mat& mask);

// FillHoles, but holes (4-connected background regions not reaching the border) larger than
// `max_area_px` stay open. max_area_px <= 0 fills every hole.
cv::Mat FillHolesUpTo(const cv::Mat& mask, int max_area_px);

// Large frames are segmented on a copy reduced by an integer factor (the work size, at least
// kWorkSidePx on its longer side), and the edge is then placed again at full size.
constexpr int kWorkSidePx = 640;

// The largest integer factor that divides both sides and keeps the longer one at least
// kWorkSidePx; 1 for frames up to twice that size (or whose sides share no such factor).
int WorkFactor(cv::Size size);

// `image` reduced by `factor` (pixel averages, cv::INTER_AREA); the image itself for factor 1.
// Contract: factor divides both sides.
cv::Mat Reduced(const cv::Mat& image, int factor);

// Where Enlarged places the edge again: `part`, the rectangle of the mask's set pixels and a
// pixel more (within the mask), and `edge`, the mask's morphological gradient there (non-zero
// where a 3x3 neighbourhood holds both values; the gradient of a view reads the mask's own pixels
// past the view's edge). Both empty when no pixel is set.
struct MaskEdge {
  cv::Rect part;
  cv::Mat edge;
};
MaskEdge EdgeOf(const cv::Mat& mask);

// Values over a part of an image: `values` are the image's pixels from `origin` on; no pixel
// outside has one.
struct ImagePart {
  cv::Mat values;
  cv::Point origin;
};

// A mask of the work size (CV_8UC1, 0/255) enlarged by `factor` to `full_size`, the edge placed
// again at full size: every full-size pixel under a work pixel on the mask's edge (a 3x3
// neighbourhood that holds both values) is object when its `score` (CV_8UC1, full-size pixels:
// the whole image, or a part holding every pixel under the edge) is at least the work pixel's
// level in `levels` (CV_32FC1: 1x1 for one level everywhere, else work-size pixels, the whole or
// a part; a pixel outside the part has no level); a negative level, or none, keeps the enlarged
// value. Away from the edge, the work mask holds: specks it dropped and holes it filled stay so.
// `edge` (may be null): EdgeOf(mask), when the caller has it.
cv::Mat Enlarged(const cv::Mat& mask, int factor, cv::Size full_size, const ImagePart& score,
                 const ImagePart& levels, const MaskEdge* edge = nullptr);

}  // namespace revolve::capture
