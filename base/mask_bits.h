// A mask's pixels one bit each, for tests that read it at random (a row of bits fits a few
// cache lines where its bytes fill many): the visual hull's views and the carving volume's
// silhouettes.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace revolve {

// The pixels of `roi` of an 8-bit mask (CV_8UC1 or CV_8SC1, any view of one) as rows of `words`
// 64-bit words, row y at [y * words, (y + 1) * words): bit x of a row (bit x % 64 of its word
// x / 64) is set when pixel (roi.x + x, roi.y + y) is not zero; the words past a row's pixels are
// zero. Preconditions: roi within the mask; words >= (roi.width + 63) / 64.
std::vector<std::uint64_t> PackMaskBits(const cv::Mat& mask, const cv::Rect& roi, int words);

}  // namespace revolve
