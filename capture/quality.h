// Quality gates for one stop's frame and silhouette: pure checks the station runs after
// segmentation. A stop that fails a gate is captured again (QualityOptions::recaptures times);
// if it still fails, the scan goes on and the manifest carries the warnings.
#pragma once

#include <span>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "config/config.h"

namespace revolve::capture {

// [quality]
struct QualityOptions {
  bool enabled = true;
  int recaptures = 2;  // how often the station captures a failing stop again
  // empty_mask: the silhouette covers less than this fraction of the image.
  double min_area_fraction = 0.002;
  // touches_border: a silhouette pixel lies within this many pixels of the image's edge.
  int border_margin_px = 1;
  // overexposed / underexposed: more than this fraction of the silhouette's pixels has a
  // channel at >= 254 (clipped highlights) or every channel at <= 1 (crushed shadows).
  double max_clipped_fraction = 0.02;
  // blurred: the silhouette's edge is wider than this (contrast across the edge divided by the
  // steepest gradient on it; a sharp edge is ~2 px, a Gaussian blur of sigma s ~2.5 s px).
  double max_edge_width_px = 4.0;
  // area_jump: the area differs from a neighbouring stop's by more than this fraction of the
  // larger of the two.
  double max_area_change = 0.35;
  // centroid_jump: the centroid moved more than this fraction of the silhouette's bounding-box
  // diagonal (the larger of the two) from a neighbouring stop's.
  double max_centroid_shift = 0.15;
};

// Parses [quality]; unknown keys and out-of-range values are bad_input naming file:line:column.
Expected<QualityOptions> ParseQualityOptions(const config::Section& section);

// What a stop's silhouette and frame measure.
struct StopStats {
  int area_px = 0;
  cv::Point2d centroid_px;        // of the silhouette
  cv::Rect bbox_px;               // of the silhouette
  double edge_width_px = 0.0;     // 0 when the edge has too little contrast to measure
  double clipped_fraction = 0.0;  // silhouette pixels with a channel >= 254
  double crushed_fraction = 0.0;  // silhouette pixels with every channel <= 1
};

struct QualityWarning {
  std::string code;     // empty_mask | touches_border | overexposed | underexposed | blurred |
                        // area_jump | centroid_jump
  std::string message;  // for people: what was seen and what to do
};

struct StopAssessment {
  StopStats stats;
  std::vector<QualityWarning> warnings;  // empty: the stop passed every gate
  bool ok() const { return warnings.empty(); }
};

// Measures a frame (CV_8UC1/3/4) and its mask (CV_8UC1, same size, 0/255).
StopStats MeasureStop(const cv::Mat& image, const cv::Mat& mask);

// True when every sample of `image` (CV_8U, any channels) is 0 or 255: a binary silhouette
// image rather than a photo.
bool IsBinaryImage(const cv::Mat& image);

// Runs every gate on one stop. A binary silhouette image skips the exposure and blur gates.
// `neighbours` are the stats of the stops next to it that are already accepted (the previous stop;
// at the last stop also the first), for the jump gates. With options.enabled false, measures only.
// An empty mask skips the gates that need a silhouette. Contract: image and mask as for
// MeasureStop.
StopAssessment AssessStop(const cv::Mat& image, const cv::Mat& mask,
                          std::span<const StopStats> neighbours, const QualityOptions& options);

}  // namespace revolve::capture
