// Silhouette segmentation: a frame in, a binary mask out.
#pragma once

#include <memory>
#include <string>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "config/config.h"

namespace revolve::capture {

// [segment]
struct SegmentOptions {
  std::string method = "otsu";  // otsu | fixed
  int threshold = 128;          // grey level for method = "fixed"
  int open_px = 1;              // opening radius; 0 disables
  int close_px = 1;             // closing radius; 0 disables
  bool keep_largest = true;     // keep only the largest 8-connected component
};

// Parses [segment] (the keys above, with their ranges); unknown keys are errors naming
// file:line:column and the key.
Expected<SegmentOptions> ParseSegmentOptions(const config::Section& section);

class Segmenter {
 public:
  virtual ~Segmenter() = default;

  // Returns a CV_8UC1 mask of the image's size: 255 on the object, 0 elsewhere.
  // `background` (may be empty) is a frame of the empty scene for methods that use one.
  // Errors: bad_input for an empty or unsupported image.
  virtual Expected<cv::Mat> Segment(const cv::Mat& image, const cv::Mat& background) const = 0;
};

// Threshold segmentation for a dark backdrop and a brighter object: grey > threshold (Otsu's or
// the fixed one), opening then closing (elliptical kernels), the largest 8-connected component,
// holes filled. Otsu on an image whose two classes differ by less than 16 grey levels (an empty
// scene) gives an all-zero mask. The background frame is not used.
// Errors: bad_input for an unknown method or an out-of-range value.
Expected<std::unique_ptr<Segmenter>> CreateSegmenter(const SegmentOptions& options);

}  // namespace revolve::capture
