// Pictures and their encoded bytes for the tests of image readers. Header-only; test code only.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace revolve::test_support {

// A BGR picture of noise with a white disc, so that its compressed data is not trivially small.
inline cv::Mat TexturedPicture(int width, int height) {
  cv::Mat image(height, width, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::circle(image, {width / 2, height / 2}, std::min(width, height) / 3, {255, 255, 255}, -1);
  return image;
}

// `image` encoded by OpenCV as `ext` (".png", ".jpg", ...); a failure fails the test.
inline std::vector<std::uint8_t> EncodeImage(const std::string& ext, const cv::Mat& image,
                                             const std::vector<int>& params = {}) {
  std::vector<std::uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(ext, image, bytes, params)) << ext;
  return bytes;
}

}  // namespace revolve::test_support
