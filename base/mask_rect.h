// The bounding rectangle of a mask's set pixels, found from the mask's edges inwards: most of a
// silhouette's frame is empty rows and the margins beside the object, which are skipped eight
// bytes at a time.
#pragma once

#include <opencv2/core.hpp>

namespace revolve {

// cv::boundingRect(mask) for a CV_8UC1 (or CV_8SC1) image, any view of one: the smallest
// rectangle holding every non-zero pixel; Rect(0, 0, 0, 0) when none is. The same rectangle,
// for a fraction of the reads (cv::boundingRect reads every byte of the empty rows, four at a
// time). Precondition: mask.depth() is CV_8U or CV_8S and it has one channel.
cv::Rect MaskRect(const cv::Mat& mask);

}  // namespace revolve
