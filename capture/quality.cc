#include "capture/quality.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <opencv2/imgproc.hpp>

#include "base/mask_rect.h"
#include "capture/segment/mask_ops.h"

namespace revolve::capture {
namespace {

// The edge width cannot be measured across a step smaller than this (grey levels).
constexpr double kMinEdgeContrast = 12.0;

cv::Mat Disc(int radius_px) {
  return cv::getStructuringElement(cv::MORPH_ELLIPSE,
                                   cv::Size(2 * radius_px + 1, 2 * radius_px + 1));
}

double EdgeWidthPx(const cv::Mat& grey, const cv::Mat& mask) {
  cv::Mat inner_near, inner_far, outer_near, outer_far;
  cv::erode(mask, inner_near, Disc(3));
  cv::erode(mask, inner_far, Disc(8));
  cv::dilate(mask, outer_near, Disc(3));
  cv::dilate(mask, outer_far, Disc(8));
  const cv::Mat inner_ring = inner_near & ~inner_far;
  const cv::Mat outer_ring = outer_far & ~outer_near;
  if (cv::countNonZero(inner_ring) == 0 || cv::countNonZero(outer_ring) == 0) return 0.0;
  const double contrast = std::abs(cv::mean(grey, inner_ring)[0] - cv::mean(grey, outer_ring)[0]);
  if (contrast < kMinEdgeContrast) return 0.0;
  cv::Mat gx, gy, magnitude;
  cv::Sobel(grey, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
  cv::Sobel(grey, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
  cv::magnitude(gx, gy, magnitude);
  cv::Mat steepest;
  cv::dilate(magnitude, steepest, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  cv::Mat eroded;
  cv::erode(mask, eroded, cv::Mat());
  const cv::Mat contour = mask & ~eroded;
  std::vector<float> values;
  for (int y = 0; y < contour.rows; ++y) {
    const auto* c = contour.ptr<std::uint8_t>(y);
    const auto* s = steepest.ptr<float>(y);
    for (int x = 0; x < contour.cols; ++x) {
      if (c[x]) values.push_back(s[x]);
    }
  }
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  const double gradient = values[values.size() / 2];
  return gradient > 0.0 ? contrast / gradient : std::numeric_limits<double>::infinity();
}

}  // namespace

Expected<QualityOptions> ParseQualityOptions(const config::Section& section) {
  QualityOptions o;
  auto enabled = section.Boolean("enabled", o.enabled);
  if (!enabled) return std::unexpected(enabled.error());
  auto recaptures = section.Integer("recaptures", o.recaptures, 0, 10);
  if (!recaptures) return std::unexpected(recaptures.error());
  auto min_area = section.Number("min_area_fraction", o.min_area_fraction, 0.0, 1.0);
  if (!min_area) return std::unexpected(min_area.error());
  auto margin = section.Integer("border_margin_px", o.border_margin_px, 0, 1000);
  if (!margin) return std::unexpected(margin.error());
  auto clipped = section.Number("max_clipped_fraction", o.max_clipped_fraction, 0.0, 1.0);
  if (!clipped) return std::unexpected(clipped.error());
  auto edge = section.Number("max_edge_width_px", o.max_edge_width_px, 0.5, 1000.0);
  if (!edge) return std::unexpected(edge.error());
  auto area = section.Number("max_area_change", o.max_area_change, 0.0, 1.0);
  if (!area) return std::unexpected(area.error());
  auto shift = section.Number("max_centroid_shift", o.max_centroid_shift, 0.0, 10.0);
  if (!shift) return std::unexpected(shift.error());
  if (auto ok = section.CheckNoUnknownKeys(); !ok) return std::unexpected(ok.error());
  o.enabled = *enabled;
  o.recaptures = static_cast<int>(*recaptures);
  o.min_area_fraction = *min_area;
  o.border_margin_px = static_cast<int>(*margin);
  o.max_clipped_fraction = *clipped;
  o.max_edge_width_px = *edge;
  o.max_area_change = *area;
  o.max_centroid_shift = *shift;
  return o;
}

StopStats MeasureStop(const cv::Mat& image, const cv::Mat& mask) {
  StopStats stats;
  const cv::Mat binary = mask != 0;
  const cv::Moments m = cv::moments(binary, true);
  stats.area_px = static_cast<int>(m.m00);
  if (stats.area_px == 0) return stats;
  stats.centroid_px = cv::Point2d(m.m10 / m.m00, m.m01 / m.m00);
  stats.bbox_px = MaskRect(binary);
  cv::Mat bgr = image;
  if (image.channels() == 1) cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  if (image.channels() == 4) cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
  std::vector<cv::Mat> channels;
  cv::split(bgr, channels);
  cv::Mat max_channel = cv::max(cv::max(channels[0], channels[1]), channels[2]);
  stats.clipped_fraction = cv::countNonZero((max_channel >= 254) & binary) / m.m00;
  stats.crushed_fraction = cv::countNonZero((max_channel <= 1) & binary) / m.m00;
  stats.edge_width_px = EdgeWidthPx(GreyLevels(image), binary);
  return stats;
}

bool IsBinaryImage(const cv::Mat& image) {
  for (int y = 0; y < image.rows; ++y) {
    const std::uint8_t* row = image.ptr<std::uint8_t>(y);
    const int n = image.cols * image.channels();
    for (int i = 0; i < n; ++i) {
      if (row[i] != 0 && row[i] != 255) return false;
    }
  }
  return true;
}

StopAssessment AssessStop(const cv::Mat& image, const cv::Mat& mask,
                          std::span<const StopStats> neighbours, const QualityOptions& options) {
  StopAssessment a;
  a.stats = MeasureStop(image, mask);
  if (!options.enabled) return a;
  const StopStats& s = a.stats;
  auto warn = [&](std::string code, std::string message) {
    a.warnings.push_back({std::move(code), std::move(message)});
  };
  const double image_area = static_cast<double>(image.total());
  if (s.area_px < options.min_area_fraction * image_area) {
    warn("empty_mask",
         fmt::format("the silhouette covers {} px ({:.2f}% of the image, at least {:.2f}% "
                     "expected): no object, or the segmentation does not suit the backdrop",
                     s.area_px, 100.0 * s.area_px / image_area, 100.0 * options.min_area_fraction));
    return a;
  }
  const int margin = options.border_margin_px;
  std::vector<std::string> sides;
  if (s.bbox_px.x <= margin) sides.push_back("left");
  if (s.bbox_px.x + s.bbox_px.width >= image.cols - margin) sides.push_back("right");
  if (s.bbox_px.y <= margin) sides.push_back("top");
  if (s.bbox_px.y + s.bbox_px.height >= image.rows - margin) sides.push_back("bottom");
  if (!sides.empty()) {
    warn("touches_border",
         fmt::format("the silhouette touches the image's {} edge: the object is too big or off "
                     "centre; move the camera back or centre the object",
                     fmt::join(sides, " and ")));
  }
  // A binary silhouette image (the thesis's input, served by the replay camera) is all "clipped"
  // by design: exposure and blur say nothing about it.
  const bool photo = !IsBinaryImage(image);
  if (photo && s.clipped_fraction > options.max_clipped_fraction) {
    warn("overexposed",
         fmt::format("{:.1f}% of the object's pixels are clipped white: lower exposure_us or gain",
                     100.0 * s.clipped_fraction));
  }
  if (photo && s.crushed_fraction > options.max_clipped_fraction) {
    warn("underexposed",
         fmt::format("{:.1f}% of the object's pixels are clipped black: raise exposure_us, gain "
                     "or the light",
                     100.0 * s.crushed_fraction));
  }
  if (photo && s.edge_width_px > options.max_edge_width_px) {
    warn("blurred",
         fmt::format("the silhouette's edge is {:.1f} px wide (at most {:.1f} expected): check "
                     "the focus, or the table was still moving (raise settle_ms)",
                     s.edge_width_px, options.max_edge_width_px));
  }
  for (const StopStats& n : neighbours) {
    if (n.area_px <= 0) continue;
    const double larger = std::max(s.area_px, n.area_px);
    const double change = std::abs(s.area_px - n.area_px) / larger;
    if (change > options.max_area_change) {
      warn("area_jump",
           fmt::format("the silhouette's area changed by {:.0f}% from a neighbouring stop's "
                       "({} px to {} px): something entered the view, or the object moved",
                       100.0 * change, n.area_px, s.area_px));
    }
    const double diagonal = std::max(std::hypot(s.bbox_px.width, s.bbox_px.height),
                                     std::hypot(n.bbox_px.width, n.bbox_px.height));
    const double shift =
        std::hypot(s.centroid_px.x - n.centroid_px.x, s.centroid_px.y - n.centroid_px.y);
    if (diagonal > 0.0 && shift > options.max_centroid_shift * diagonal) {
      warn("centroid_jump",
           fmt::format("the silhouette's centre moved {:.0f} px ({:.0f}% of its size) from a "
                       "neighbouring stop's: the object slipped on the plate, or something "
                       "entered the view",
                       shift, 100.0 * shift / diagonal));
    }
  }
  return a;
}

}  // namespace revolve::capture
