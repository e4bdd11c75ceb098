// PackMaskBits (base/mask_bits.h) against each pixel read on its own.
#include "base/mask_bits.h"

#include <gtest/gtest.h>

#include <random>

namespace revolve {
namespace {

TEST(MaskBits, EachBitIsItsPixelSetOrNot) {
  std::mt19937 random(5);
  const auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(random); };
  int compared = 0;
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(7, 3), cv::Size(64, 5), cv::Size(65, 4),
                              cv::Size(200, 9), cv::Size(1283, 3)}) {
    for (int trial = 0; trial < 20; ++trial) {
      // Any byte value, and runs of zeros and of set bytes as a silhouette's rows have.
      cv::Mat mask(size, trial % 2 == 0 ? CV_8UC1 : CV_8SC1);
      for (int y = 0; y < size.height; ++y) {
        for (int x = 0; x < size.width; ++x) {
          const bool run = (x / 9 + y + trial) % 3 == 0;
          mask.at<std::uint8_t>(y, x) =
              run ? 255 : (pick(4) == 0 ? static_cast<std::uint8_t>(pick(256)) : 0);
        }
      }
      // The whole mask, and a rectangle inside it (a view of it: rows apart in memory).
      const int x0 = pick(size.width), y0 = pick(size.height);
      for (const cv::Rect roi :
           {cv::Rect(cv::Point(), size),
            cv::Rect(x0, y0, 1 + pick(size.width - x0), 1 + pick(size.height - y0))}) {
        const int words = (roi.width + 63) / 64 + trial % 2;  // with a spare word, or none
        const std::vector<std::uint64_t> bits = PackMaskBits(mask, roi, words);
        ASSERT_EQ(bits.size(), static_cast<std::size_t>(words * roi.height));
        for (int y = 0; y < roi.height; ++y) {
          for (int x = 0; x < words * 64; ++x) {
            const bool bit = ((bits[y * words + x / 64] >> (x % 64)) & 1u) != 0;
            const bool set = x < roi.width && mask.at<std::uint8_t>(roi.y + y, roi.x + x) != 0;
            ASSERT_EQ(bit, set) << size << " roi " << roi << " pixel " << x << ", " << y;
            ++compared;
          }
        }
      }
    }
  }
  EXPECT_GT(compared, 100000);
}

TEST(MaskBits, AnEmptyRectangleHasNoBits) {
  const cv::Mat mask(4, 4, CV_8UC1, cv::Scalar(255));
  EXPECT_TRUE(PackMaskBits(mask, cv::Rect(), 0).empty());
  EXPECT_TRUE(PackMaskBits(mask, cv::Rect(1, 1, 0, 2), 0).empty());
}

}  // namespace
}  // namespace revolve
