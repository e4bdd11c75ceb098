// MaskRect (base/mask_rect.h) against the rectangle of the mask's non-zero pixels, and against
// cv::boundingRect, which it stands in for.
#include "base/mask_rect.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace revolve {
namespace {

// The rectangle of the non-zero pixels, from their list.
cv::Rect OfPixels(const cv::Mat& mask) {
  std::vector<cv::Point> pixels;
  cv::findNonZero(mask, pixels);
  return pixels.empty() ? cv::Rect() : cv::boundingRect(pixels);
}

TEST(MaskRect, TheRectangleOfTheSetPixels) {
  std::mt19937 random(7);
  const auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(random); };
  int compared = 0;
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(7, 3), cv::Size(9, 17), cv::Size(64, 40),
                              cv::Size(1283, 961), cv::Size(31, 1)}) {
    for (int trial = 0; trial < 40; ++trial) {
      cv::Mat mask = cv::Mat::zeros(size, CV_8UC1);
      const int kind = trial % 5;
      if (kind == 1) {  // one pixel
        mask.at<std::uint8_t>(pick(size.height), pick(size.width)) = 255;
      } else if (kind == 2) {  // a blob
        cv::circle(mask, cv::Point(pick(size.width), pick(size.height)),
                   1 + pick(std::max(1, size.width / 3)), cv::Scalar(255), cv::FILLED);
      } else if (kind == 3) {  // scattered pixels of any value
        for (int n = 0; n < 1 + pick(6); ++n) {
          mask.at<std::uint8_t>(pick(size.height), pick(size.width)) =
              static_cast<std::uint8_t>(1 + pick(255));
        }
      } else if (kind == 4) {  // everything
        mask.setTo(1);
      }
      EXPECT_EQ(MaskRect(mask), OfPixels(mask)) << size << " trial " << trial;
      // OpenCV 4.6's own reads rows from their first 4-byte boundary and misses pixels before
      // it on some rows (a 7-pixel-wide mask's second row): the same where rows are aligned.
      if (size.width % 4 == 0) {
        EXPECT_EQ(MaskRect(mask), cv::boundingRect(mask)) << size;
      }
      // A view into it (rows not continuous), on odd offsets.
      if (size.width > 4 && size.height > 4) {
        const cv::Rect part(1 + pick(size.width / 4), pick(size.height / 4), size.width / 2,
                            size.height / 2 + 1);
        const cv::Mat view = mask(part);
        EXPECT_EQ(MaskRect(view), OfPixels(view)) << size << " view " << part;
      }
      ++compared;
    }
  }
  EXPECT_EQ(compared, 240);
  EXPECT_EQ(MaskRect(cv::Mat::zeros(5, 12, CV_8UC1)), cv::Rect());
}

}  // namespace
}  // namespace revolve
