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

// `jpeg` with an EXIF block (APP1, right after SOI) whose IFD0 holds one entry: the orientation
// (tag 0x0112, SHORT) = `orientation`, in a TIFF structure of either byte order.
inline std::vector<std::uint8_t> WithExifOrientation(const std::vector<std::uint8_t>& jpeg,
                                                     int orientation, bool big_endian = false) {
  const auto o = static_cast<std::uint8_t>(orientation);
  const std::vector<std::uint8_t> little = {
      0xFF, 0xE1, 0x00, 0x22, 'E', 'x', 'i', 'f', 0, 0, 'I', 'I', 0x2A, 0, 8, 0, 0, 0,
      1,    0,    0x12, 0x01, 3,   0,   1,   0,   0, 0, o,   0,   0,    0, 0, 0, 0, 0};
  const std::vector<std::uint8_t> big = {
      0xFF, 0xE1, 0x00, 0x22, 'E', 'x', 'i', 'f', 0, 0, 'M', 'M', 0, 0x2A, 0, 0, 0, 8,
      0,    1,    0x01, 0x12, 0,   3,   0,   0,   0, 1, 0,   o,   0, 0,    0, 0, 0, 0};
  const std::vector<std::uint8_t>& exif = big_endian ? big : little;
  std::vector<std::uint8_t> out(jpeg.begin(), jpeg.begin() + 2);
  out.insert(out.end(), exif.begin(), exif.end());
  out.insert(out.end(), jpeg.begin() + 2, jpeg.end());
  return out;
}

}  // namespace revolve::test_support
