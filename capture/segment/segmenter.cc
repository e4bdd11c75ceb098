#include "capture/segmenter.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "capture/segment/mask_ops.h"

namespace revolve::capture {
namespace {

constexpr int kMaxMorphologyRadiusPx = 50;
// Otsu splits any image in two, even an empty scene's noise. When the two classes' mean grey
// levels differ by less than this, there is no object: the mask is empty.
constexpr double kMinOtsuContrast = 16.0;

// A dark backdrop and a brighter object: grey > threshold is object.
class ThresholdSegmenter final : public Segmenter {
 public:
  explicit ThresholdSegmenter(const SegmentOptions& options) : options_(options) {}

  Expected<cv::Mat> Segment(const cv::Mat& image, const cv::Mat& /*background*/) const override {
    if (image.empty()) return MakeError(ErrorCode::kBadInput, "segmentation: empty image");
    if (image.depth() != CV_8U ||
        (image.channels() != 1 && image.channels() != 3 && image.channels() != 4)) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("segmentation: unsupported image type {} (8-bit grey, BGR "
                                   "or BGRA expected)",
                                   cv::typeToString(image.type())));
    }
    const cv::Mat grey = GreyLevels(image);
    cv::Mat mask;
    if (options_.method == "otsu") {
      const double threshold =
          cv::threshold(grey, mask, 0.0, 255.0, cv::THRESH_BINARY | cv::THRESH_OTSU);
      const cv::Mat below = grey <= threshold;
      const double dark_mean = cv::mean(grey, below)[0];
      const double bright_mean = cv::mean(grey, mask)[0];
      if (cv::countNonZero(mask) == 0 || cv::countNonZero(below) == 0 ||
          bright_mean - dark_mean < kMinOtsuContrast) {
        return cv::Mat(cv::Mat::zeros(image.size(), CV_8UC1));
      }
    } else {
      cv::threshold(grey, mask, options_.threshold, 255.0, cv::THRESH_BINARY);
    }
    mask = CloseMask(OpenMask(mask, options_.open_px), options_.close_px);
    if (options_.keep_largest) mask = KeepLargestComponent(mask);
    return FillHoles(mask);
  }

 private:
  SegmentOptions options_;
};

Expected<void> Validate(const SegmentOptions& options) {
  if (options.method != "otsu" && options.method != "fixed") {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("[segment] method = \"{}\" is not one of \"otsu\", \"fixed\"", options.method));
  }
  if (options.threshold < 0 || options.threshold > 255) {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("[segment] threshold = {} is out of range [0, 255]", options.threshold));
  }
  for (const auto& [key, radius] :
       {std::pair{"open_px", options.open_px}, std::pair{"close_px", options.close_px}}) {
    if (radius < 0 || radius > kMaxMorphologyRadiusPx) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("[segment] {} = {} is out of range [0, {}]", key, radius,
                                   kMaxMorphologyRadiusPx));
    }
  }
  return {};
}

}  // namespace

Expected<SegmentOptions> ParseSegmentOptions(const config::Section& section) {
  SegmentOptions options;
  auto method = section.String("method", options.method, {"otsu", "fixed"});
  if (!method) return std::unexpected(method.error());
  auto threshold = section.Integer("threshold", options.threshold, 0, 255);
  if (!threshold) return std::unexpected(threshold.error());
  auto open_px = section.Integer("open_px", options.open_px, 0, kMaxMorphologyRadiusPx);
  if (!open_px) return std::unexpected(open_px.error());
  auto close_px = section.Integer("close_px", options.close_px, 0, kMaxMorphologyRadiusPx);
  if (!close_px) return std::unexpected(close_px.error());
  auto keep_largest = section.Boolean("keep_largest", options.keep_largest);
  if (!keep_largest) return std::unexpected(keep_largest.error());
  if (auto ok = section.CheckNoUnknownKeys(); !ok) return std::unexpected(ok.error());
  options.method = *method;
  options.threshold = static_cast<int>(*threshold);
  options.open_px = static_cast<int>(*open_px);
  options.close_px = static_cast<int>(*close_px);
  options.keep_largest = *keep_largest;
  return options;
}

Expected<std::unique_ptr<Segmenter>> CreateSegmenter(const SegmentOptions& options) {
  if (auto ok = Validate(options); !ok) return std::unexpected(ok.error());
  return std::unique_ptr<Segmenter>(std::make_unique<ThresholdSegmenter>(options));
}

}  // namespace revolve::capture
