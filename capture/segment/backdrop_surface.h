// A backdrop lit unevenly but smoothly (light from one side, a lens's vignetting), as graphcut
// cuts against it and the set survey judges it: per channel, a quadratic surface fitted to the
// outline of a rectangle. Internal to capture/segment.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace revolve::capture {

// The pixels on the outline of `box` (its one-pixel ring), each once.
std::vector<cv::Point> RectOutline(const cv::Rect& box);

// The bounding rectangle of `roi` (CV_8UC1, may be empty), or the whole image of `size` when it
// is empty or has no pixel set: the rectangle whose outline shows the backdrop.
cv::Rect RoiBox(cv::Size size, const cv::Mat& roi);

class BackdropSurface {
 public:
  // Per channel a + b u + c v + d u^2 + e v^2 + g u v, (u, v) the pixel's position in `box` scaled
  // to -1..1: the outline determines all six terms (each side's curve, and the sides' levels).
  // Fitted to the pixels of `bgr` (CV_8UC3) on the outline of `box` (within the image) by least
  // squares, then twice again to the pixels within 3 robust sigmas (1.4826 MAD, at least 2
  // levels) of the last fit, so that an object or a stand crossing the outline does not bend it.
  // nullopt when the outline has fewer than 16 pixels or the fit is not finite.
  static std::optional<BackdropSurface> FitToOutline(const cv::Mat& bgr, const cv::Rect& box);

  // The largest rise of a channel over the rectangle (max - min on a grid of 9 x 9 points).
  double Rise() const;
  // The surface's colour at pixel (x, y) (B, G, R; not clamped).
  cv::Vec3d At(int x, int y) const;
  // The surface at every pixel of an image of `size` (CV_8UC3, saturated; a view into a larger
  // image): its values, rounded, on a grid of every 8th pixel, interpolated bilinearly between
  // (cv::resize): within about a level of At() (two roundings; a lit backdrop's surface bends by
  // a hundredth of a level between grid points).
  cv::Mat Image(cv::Size size) const;

 private:
  using Terms = Eigen::Matrix<double, 6, 1>;
  static Terms TermsAt(double u, double v);

  double cx_ = 0.0, cy_ = 0.0, sx_ = 1.0, sy_ = 1.0;  // (u, v) = ((x - cx) / sx, (y - cy) / sy)
  std::array<Terms, 3> channels_{};
};

// What the set's survey (SurveyBackdrop) found of one frame, for Segmenter::SegmentWithFacts:
// the surface fitted to its whole outline, FitToOutline(frame, the whole frame) (nullopt where
// none fits), which graphcut fits without a region of interest.
struct FrameFacts {
  std::optional<BackdropSurface> whole_outline;
};

}  // namespace revolve::capture
