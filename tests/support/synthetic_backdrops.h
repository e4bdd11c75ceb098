// Backdrops like real ones for segmentation tests: an uneven cloth, and frames composited over a
// backdrop with sensor noise. Header-only; test code only.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace revolve::test_support {

// A smooth random field in [low, high] (folds of a cloth), grey with a slight tint (B +6, R +3),
// CV_8UC3 of `size`; the same seed gives the same cloth.
inline cv::Mat Cloth(cv::Size size, double low, double high, std::uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat coarse(size.height / 24 + 2, size.width / 24 + 2, CV_32F);
  rng.fill(coarse, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::Mat field;
  cv::resize(coarse, field, size, 0.0, 0.0, cv::INTER_CUBIC);
  cv::GaussianBlur(field, field, {0, 0}, 6.0);
  cv::normalize(field, field, low, high, cv::NORM_MINMAX);
  cv::Mat grey;
  field.convertTo(grey, CV_8U);
  cv::Mat bgr;
  cv::merge(std::vector<cv::Mat>{grey + 6, grey, grey + 3}, bgr);
  return bgr;
}

// `image` (CV_8UC3) with Gaussian noise of `sigma` levels added to every channel (saturated),
// seeded by `seed`.
inline cv::Mat WithNoise(const cv::Mat& image, double sigma, std::uint64_t seed) {
  cv::Mat noise(image.size(), CV_16SC3);
  cv::RNG(seed).fill(noise, cv::RNG::NORMAL, 0.0, sigma);
  cv::Mat noisy;
  image.convertTo(noisy, CV_16SC3);
  noisy += noise;
  cv::Mat out;
  noisy.convertTo(out, CV_8UC3);
  return out;
}

// The part of `object_mask` (CV_8UC1) below 2/3 of its bounding box's height, where `image`
// (CV_8UC3) is darkened to `fraction` of its brightness: the object's lower third in deep shadow.
inline void ShadeLowerThird(cv::Mat& image, const cv::Mat& object_mask, double fraction) {
  const cv::Rect box = cv::boundingRect(object_mask);
  const cv::Rect lower(box.x, box.y + 2 * box.height / 3, box.width,
                       box.height - 2 * box.height / 3);
  if (lower.area() == 0) return;
  cv::Mat region = image(lower);
  cv::Mat dark;
  region.convertTo(dark, -1, fraction, 0.0);
  dark.copyTo(region, object_mask(lower));
}

}  // namespace revolve::test_support
