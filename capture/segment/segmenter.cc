#include "capture/segmenter.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include <fmt/format.h>
#include <Eigen/Core>
#include <opencv2/imgproc.hpp>

#include "base/mask_rect.h"
#include "capture/segment/backdrop_surface.h"
#include "capture/segment/graph_cut.h"
#include "capture/segment/mask_ops.h"

namespace revolve::capture {
namespace {

// BackdropDistance's `count` pixels of one row: `p` and (per_pixel) `b` point at their BGR
// pixels, `b` at the one backdrop colour otherwise; into `o`.
void BackdropDistanceRow(const std::uint8_t* p, const std::uint8_t* b, bool per_pixel, bool shadows,
                         int count, std::uint8_t* o);

constexpr int kMaxMorphologyRadiusPx = 50;
constexpr int kMaxCoordinatePx = 1 << 20;
// A chroma key whose chroma (|Cb, Cr| in 8-bit units) is weaker than this is grey: no key.
constexpr double kMinKeyChroma = 12.0;
// auto: a backdrop whose chroma reaches this is coloured (a chroma key: a green or blue screen is
// 60..70); below it, grey (graphcut: a cream or warm white backdrop, ~30 under tungsten light,
// shares its chroma with the light parts of most objects).
constexpr double kColouredBackdropChroma = 40.0;
// auto: a backdrop brighter than this (luma) shows soft shadows worth the shadow model.
constexpr double kShadowModelMinLuma = 60.0;
// graphcut: holes of at most this many pixels are filled whatever they show.
constexpr int kMinOpenHolePx = 16;
// graphcut: a backdrop whose fitted surface (BackdropSurface) rises more than this (levels, some
// channel) across the outline's rectangle is cut against the surface rather than one colour.
constexpr double kMinBackdropSlope = 6.0;

Expected<void> CheckImage(const cv::Mat& image, std::string_view what) {
  if (image.empty())
    return MakeError(ErrorCode::kBadInput, fmt::format("segmentation: empty {}", what));
  if (image.depth() != CV_8U ||
      (image.channels() != 1 && image.channels() != 3 && image.channels() != 4)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("segmentation: unsupported {} type {} (8-bit grey, BGR or BGRA "
                                 "expected)",
                                 what, cv::typeToString(image.type())));
  }
  return {};
}

// The backdrop graphcut cuts `bgr` (CV_8UC3) against where the outline of the region of interest's
// bounding rectangle shows it lit unevenly (its BackdropSurface rises more than
// kMinBackdropSlope levels: light from one side, a lens's vignetting): that surface at every
// pixel (CV_8UC3 of the image's size); empty when the backdrop is even (one colour then).
cv::Mat UnevenBackdrop(const std::optional<BackdropSurface>& surface, cv::Size size) {
  if (!surface || !(surface->Rise() > kMinBackdropSlope)) return {};
  return surface->Image(size);
}
cv::Mat UnevenBackdrop(const cv::Mat& bgr, const cv::Mat& roi) {
  return UnevenBackdrop(BackdropSurface::FitToOutline(bgr, RoiBox(bgr.size(), roi)), bgr.size());
}

// `bgr` with the unevenness of `backdrop` (CV_8UC3, both of one size) taken out: bgr - backdrop +
// `level`, saturated.
cv::Mat Evened(const cv::Mat& bgr, const cv::Mat& backdrop, const cv::Scalar& level) {
  cv::Mat difference;
  cv::subtract(bgr, backdrop, difference, cv::noArray(), CV_16SC3);
  difference += level;
  cv::Mat out;
  difference.convertTo(out, CV_8UC3);
  return out;
}

// BGR (CV_8UC3) view of an 8-bit image with 1, 3 or 4 channels.
cv::Mat Bgr(const cv::Mat& image) {
  if (image.channels() == 3) return image;
  cv::Mat out;
  cv::cvtColor(image, out, image.channels() == 4 ? cv::COLOR_BGRA2BGR : cv::COLOR_GRAY2BGR);
  return out;
}

struct OtsuSplit {
  int threshold = 0;  // class 0: level <= threshold
  double low_mean = 0.0;
  double high_mean = 0.0;
  bool two_classes = false;
};

// Otsu's threshold over the pixels of `grey` (CV_8UC1) where `roi` is set (empty: all).
OtsuSplit Otsu(const cv::Mat& grey, const cv::Mat& roi) {
  // Four counts, pixels in turn, so that a run of one level does not wait on its own increments.
  std::array<std::array<std::int64_t, 256>, 4> counts{};
  for (int y = 0; y < grey.rows; ++y) {
    const auto* g = grey.ptr<std::uint8_t>(y);
    const auto* r = roi.empty() ? nullptr : roi.ptr<std::uint8_t>(y);
    int x = 0;
    if (r == nullptr) {
      for (; x + 4 <= grey.cols; x += 4) {
        for (int k = 0; k < 4; ++k) ++counts[k][g[x + k]];
      }
    }
    for (; x < grey.cols; ++x) {
      if (r == nullptr || r[x] != 0) ++counts[0][g[x]];
    }
  }
  std::array<double, 256> histogram{};
  for (int i = 0; i < 256; ++i) {
    histogram[i] = static_cast<double>(counts[0][i] + counts[1][i] + counts[2][i] + counts[3][i]);
  }
  double total = 0.0, sum = 0.0;
  for (int i = 0; i < 256; ++i) {
    total += histogram[i];
    sum += i * histogram[i];
  }
  OtsuSplit best;
  double best_variance = -1.0;
  double w0 = 0.0, sum0 = 0.0;
  for (int t = 0; t < 255; ++t) {
    w0 += histogram[t];
    sum0 += t * histogram[t];
    const double w1 = total - w0;
    if (w0 <= 0.0 || w1 <= 0.0) continue;
    const double m0 = sum0 / w0, m1 = (sum - sum0) / w1;
    const double variance = w0 * w1 * (m0 - m1) * (m0 - m1);
    if (variance > best_variance) {
      best_variance = variance;
      best = {t, m0, m1, true};
    }
  }
  return best;
}

class PipelineSegmenter final : public Segmenter {
 public:
  explicit PipelineSegmenter(const SegmentOptions& options) : options_(options) {}

  bool NeedsBackground() const override { return options_.method == "background"; }

  Expected<cv::Mat> Segment(const cv::Mat& image, const cv::Mat& background) const override {
    return Run(image, background, nullptr);
  }

  Expected<cv::Mat> SegmentWithFacts(const cv::Mat& image, const cv::Mat& background,
                                     const FrameFacts& facts) const override {
    return Run(image, background, &facts);
  }

  // The segmentation; `facts` (may be null): the set survey's, for `image`.
  Expected<cv::Mat> Run(const cv::Mat& image, const cv::Mat& background,
                        const FrameFacts* facts) const {
    if (auto ok = CheckImage(image, "image"); !ok) return std::unexpected(ok.error());
    const bool has_roi = !options_.roi_px.empty() || !options_.roi_polygon_px.empty() ||
                         !options_.exclude_px.empty();
    const cv::Mat roi = has_roi ? RegionOfInterestMask(options_, image.size()) : cv::Mat();
    std::string method = options_.method;
    if (method == "auto") method = AutoMethod(image, background, roi);
    const int factor = WorkFactor(image.size());
    if (method == "graphcut") {
      const cv::Mat bgr = Bgr(image);
      const cv::Scalar key = options_.backdrop_bgr.size() == 3
                                 ? cv::Scalar(options_.backdrop_bgr[0], options_.backdrop_bgr[1],
                                              options_.backdrop_bgr[2])
                                 : EstimateBackdropColour(bgr, roi);
      const bool shadows = Luma(key) >= kShadowModelMinLuma;
      // The survey's fit is the one over the whole frame: the region of interest's rectangle
      // without one.
      const cv::Mat uneven = facts != nullptr && roi.empty()
                                 ? UnevenBackdrop(facts->whole_outline, bgr.size())
                                 : UnevenBackdrop(bgr, roi);
      if (uneven.empty())
        return SegmentByCut(bgr, cv::Mat(1, 1, CV_8UC3, key), shadows, roi, factor);
      return SegmentByCut(bgr, uneven, shadows, roi, factor, &key);
    }
    if (method == "background") {
      if (auto ok = CheckBackground(image, background); !ok) return std::unexpected(ok.error());
      if (options_.refine || options_.method == "auto") {
        return SegmentByCut(Bgr(image), Bgr(background), false, roi, factor);
      }
    }
    // A score per pixel (higher: more like the object) and a level it must reach.
    Expected<cv::Mat> score =
        method == "otsu" || method == "fixed" ? ObjectLevels(image)
        : method == "background"
            ? Expected<cv::Mat>(BackdropDistance(Bgr(image), Bgr(background), false))
            : Chroma(image, roi);
    if (!score) return score;
    const cv::Mat score_w = Reduced(*score, factor);
    const cv::Mat roi_w = ReducedRoi(roi, factor);
    const std::optional<double> level = ObjectLevel(method, score_w, roi_w);
    if (!level) return cv::Mat(cv::Mat::zeros(image.size(), CV_8UC1));
    cv::Mat mask_w;
    cv::compare(score_w, *level, mask_w, cv::CMP_GE);
    mask_w = CleanUp(mask_w, roi_w, nullptr, factor);
    if (factor == 1) return mask_w;
    cv::Mat mask = Enlarged(mask_w, factor, score->size(), {*score, {}},
                            {cv::Mat(1, 1, CV_32FC1, cv::Scalar(*level)), {}});
    if (!roi.empty()) mask &= roi;
    return mask;
  }

  // The score and its levels a graph cut was seeded from.
  struct ScoredLevels {
    cv::Mat score;
    ScoreLevels levels;
  };

  // Segments with a graph cut seeded by the distance to `backdrop` (a 1x1 colour or a frame), at
  // the work size, then places the edge at full size. `even_to` (may be null): `backdrop` is a
  // smooth backdrop's surface (UnevenBackdrop), and the colour models see the frame evened out
  // to this colour (Evened): one backdrop colour, not a ramp whose bright end has the colours of
  // an object's dim parts.
  cv::Mat SegmentByCut(const cv::Mat& bgr, const cv::Mat& backdrop, bool shadows,
                       const cv::Mat& roi, int factor, const cv::Scalar* even_to = nullptr) const {
    const cv::Mat backdrop_w = backdrop.size() == bgr.size() ? Reduced(backdrop, factor) : backdrop;
    const cv::Mat bgr_w = Reduced(bgr, factor);
    const cv::Mat colours_w = even_to != nullptr ? Evened(bgr_w, backdrop_w, *even_to) : bgr_w;
    const cv::Mat roi_w = ReducedRoi(roi, factor);
    ScoredLevels scored;
    scored.score = BackdropDistance(bgr_w, backdrop_w, shadows);
    const OtsuSplit split = Otsu(scored.score, roi_w);
    if (!split.two_classes || split.high_mean - split.low_mean < options_.min_contrast) {
      return cv::Mat::zeros(bgr.size(), CV_8UC1);
    }
    const cv::Mat noise_score = NoiseScore(scored.score);
    scored.levels = {static_cast<double>(split.threshold), split.low_mean,
                     BackdropNoiseCeiling(noise_score, roi_w)};
    GraphCutOptions cut;
    cut.max_side_px = options_.refine_max_side_px;
    const cv::Mat cut_w = RefineWithGraphCut(
        colours_w, scored.score,
        TrimapFromScore(colours_w, scored.score, scored.levels, roi_w, cut, noise_score), cut);
    cv::Mat mask_w = CleanUp(cut_w, roi_w, &scored, factor);
    if (factor == 1) return mask_w;
    const MaskEdge edge = EdgeOf(mask_w);
    const EdgeLevelPart levels = EdgeLevels(mask_w, scored.score, 1);
    cv::Mat mask = Enlarged(mask_w, factor, bgr.size(),
                            DistanceAroundEdge(bgr, backdrop, shadows, edge, factor),
                            {levels.levels, levels.part.tl()}, &edge);
    if (!roi.empty()) mask &= roi;
    return mask;
  }

  // BackdropDistance(bgr, backdrop, shadows) where Enlarged(mask_w, factor, ...) reads it: the
  // full-size pixels of the work-size mask's edge (`edge`: EdgeOf(mask_w)), held over the
  // full-size pixels of the edge's part (zero where no edge is; an empty mask has no edge and no
  // part). The distance is a pixel's own: the same values as over the whole frame.
  static ImagePart DistanceAroundEdge(const cv::Mat& bgr, const cv::Mat& backdrop, bool shadows,
                                      const MaskEdge& mask_edge, int factor) {
    if (mask_edge.part.empty()) return {};
    const cv::Rect& part = mask_edge.part;
    const cv::Mat& edge = mask_edge.edge;
    const cv::Point origin(part.x * factor, part.y * factor);
    ImagePart held{cv::Mat::zeros(part.height * factor, part.width * factor, CV_8UC1), origin};
    cv::Mat& score = held.values;
    const bool per_pixel = backdrop.size() == bgr.size();
    for (int y = 0; y < edge.rows; ++y) {
      const std::uint8_t* e = edge.ptr<std::uint8_t>(y);
      for (int x = 0; x < edge.cols;) {
        if (!e[x]) {
          ++x;
          continue;
        }
        const int first = x;
        while (x < edge.cols && e[x]) ++x;
        const int column = (part.x + first) * factor;
        const int count = (x - first) * factor;
        for (int dy = 0; dy < factor; ++dy) {
          const int row = (part.y + y) * factor + dy;
          BackdropDistanceRow(
              bgr.ptr<std::uint8_t>(row) + 3 * static_cast<std::ptrdiff_t>(column),
              per_pixel ? backdrop.ptr<std::uint8_t>(row) + 3 * static_cast<std::ptrdiff_t>(column)
                        : backdrop.ptr<std::uint8_t>(0),
              per_pixel, shadows, count,
              score.ptr<std::uint8_t>(row - origin.y) + (column - origin.x));
        }
      }
    }
    return held;
  }

  // The clean-up every method ends with (see segmenter.h), at the work size: the radii and areas
  // are full-size pixels, scaled by `factor`.
  cv::Mat CleanUp(const cv::Mat& raw, const cv::Mat& roi, const ScoredLevels* scored,
                  int factor) const {
    const auto radius = [factor](int r) {
      return r > 0 ? std::max(1, (r + factor / 2) / factor) : 0;
    };
    const int area_scale = factor * factor;
    const cv::Mat whole = roi.empty() ? raw : cv::Mat(raw & roi);
    // Only around the object: the opening and closing reach at most 2 open + 2 close pixels past
    // the rectangle of its pixels, the components and holes are the same in a part of the frame
    // with a ring of backdrop around them (what the frame's border reaches), and the rest stays
    // backdrop: done on that part, the same mask for a fraction of the work.
    const int open_r = radius(options_.open_px);
    const int close_r = radius(options_.close_px);
    const cv::Rect object = MaskRect(whole);
    const int margin = 2 * open_r + 2 * close_r + 2;
    const cv::Rect part = object.empty()
                              ? cv::Rect(0, 0, whole.cols, whole.rows)
                              : cv::Rect(object.x - margin, object.y - margin,
                                         object.width + 2 * margin, object.height + 2 * margin) &
                                    cv::Rect(0, 0, whole.cols, whole.rows);
    cv::Mat mask = CloseMask(OpenMask(whole(part).clone(), open_r), close_r);
    if (options_.keep_largest) mask = KeepLargestComponent(mask);
    if (options_.fill_holes) {
      if (scored != nullptr && options_.max_hole_area_px == 0) {
        const double middle = 0.5 * (scored->levels.object + scored->levels.backdrop);
        mask =
            FillHolesUnlessBackdrop(mask, scored->score(part), middle, kMinOpenHolePx / area_scale);
      } else {
        mask = FillHolesUpTo(mask, (options_.max_hole_area_px + area_scale - 1) / area_scale);
      }
    }
    cv::Mat out = cv::Mat::zeros(whole.size(), CV_8UC1);
    mask.copyTo(out(part));
    return roi.empty() ? out : cv::Mat(out & roi);
  }

 private:
  static double Luma(const cv::Scalar& bgr) {
    return 0.299 * bgr[2] + 0.587 * bgr[1] + 0.114 * bgr[0];
  }

  // auto for one frame: background (refined) when a background frame is given, chroma on a
  // coloured backdrop, graphcut otherwise.
  static std::string AutoMethod(const cv::Mat& image, const cv::Mat& background,
                                const cv::Mat& roi) {
    if (!background.empty()) return "background";
    if (image.channels() == 1) return "graphcut";
    const cv::Scalar key = EstimateBackdropColour(Bgr(image), roi);
    return ChromaOf(key[0], key[1], key[2]).norm() >= kColouredBackdropChroma ? "chroma"
                                                                              : "graphcut";
  }

  static Expected<void> CheckBackground(const cv::Mat& image, const cv::Mat& background) {
    if (background.empty()) {
      return MakeError(ErrorCode::kBadInput,
                       "segmentation: [segment] method = \"background\" needs a frame of the "
                       "empty scene, and none was given");
    }
    if (auto ok = CheckImage(background, "background frame"); !ok) {
      return std::unexpected(ok.error());
    }
    if (background.size() != image.size()) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("segmentation: the background frame is {}x{} but the image is "
                                   "{}x{}; capture the empty scene again",
                                   background.cols, background.rows, image.cols, image.rows));
    }
    return {};
  }

  // otsu, fixed: the grey level, inverted on a light backdrop (object: higher).
  Expected<cv::Mat> ObjectLevels(const cv::Mat& image) const {
    cv::Mat grey = GreyLevels(image);
    if (options_.backdrop == "dark") return grey;
    cv::Mat inverted;
    cv::bitwise_not(grey, inverted);
    return inverted;
  }

  // The score an object pixel reaches (at the work size); none when an Otsu split finds no
  // object (an empty scene).
  std::optional<double> ObjectLevel(const std::string& method, const cv::Mat& score,
                                    const cv::Mat& roi) const {
    if (method == "chroma") return 128.0;  // the chroma score is 0 or 255
    if (method == "fixed") {
      // dark: grey > threshold; light: grey < threshold, i.e. 255 - grey > 255 - threshold.
      return options_.backdrop == "dark" ? options_.threshold + 1.0 : 256.0 - options_.threshold;
    }
    if (method == "background" && options_.difference_threshold > 0.0) {
      return std::floor(options_.difference_threshold) + 1.0;
    }
    const OtsuSplit split = Otsu(score, roi);
    if (method == "background") {
      return std::floor(std::max<double>(split.threshold, options_.min_contrast)) + 1.0;
    }
    if (!split.two_classes || split.high_mean - split.low_mean < options_.min_contrast) {
      return std::nullopt;
    }
    return split.threshold + 1.0;
  }

  static cv::Mat ReducedRoi(const cv::Mat& roi, int factor) {
    if (roi.empty() || factor == 1) return roi;
    cv::Mat out = Reduced(roi, factor) >= 128;
    return out;
  }

  Expected<cv::Mat> Chroma(const cv::Mat& image, const cv::Mat& roi) const {
    if (image.channels() == 1) {
      return MakeError(ErrorCode::kBadInput,
                       "segmentation: [segment] method = \"chroma\" needs a colour image, got a "
                       "grey one");
    }
    const cv::Mat bgr = Bgr(image);
    cv::Scalar key;
    if (options_.chroma_key_bgr.size() == 3) {
      key = cv::Scalar(options_.chroma_key_bgr[0], options_.chroma_key_bgr[1],
                       options_.chroma_key_bgr[2]);
    } else {
      key = EstimateBackdropColour(bgr, roi);
    }
    const Eigen::Vector2d key_chroma = ChromaOf(key[0], key[1], key[2]);
    const double key_norm2 = key_chroma.squaredNorm();
    if (key_norm2 < kMinKeyChroma * kMinKeyChroma) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("segmentation: the backdrop colour (B, G, R) = ({:.0f}, {:.0f}, "
                                   "{:.0f}) is too grey for a chroma key; use a green or blue "
                                   "backdrop, or method = \"otsu\"",
                                   key[0], key[1], key[2]));
    }
    cv::Mat mask(image.size(), CV_8UC1, cv::Scalar(0));
    // Share of the key's chroma in a pixel: 1 on the backdrop, ~0 on a neutral object, the
    // object's share of coverage on an anti-aliased edge in between. Chroma is linear in B G R,
    // so the share is w . (b, g, r) with w fixed by the key.
    const auto chroma_b = ChromaOf(1, 0, 0), chroma_g = ChromaOf(0, 1, 0),
               chroma_r = ChromaOf(0, 0, 1);
    const float wb = static_cast<float>(chroma_b.dot(key_chroma) / key_norm2);
    const float wg = static_cast<float>(chroma_g.dot(key_chroma) / key_norm2);
    const float wr = static_cast<float>(chroma_r.dot(key_chroma) / key_norm2);
    const float fraction = static_cast<float>(options_.chroma_fraction);
    for (int y = 0; y < bgr.rows; ++y) {
      const auto* p = bgr.ptr<cv::Vec3b>(y);
      auto* m = mask.ptr<std::uint8_t>(y);
      for (int x = 0; x < bgr.cols; ++x) {
        const float share = wb * p[x][0] + wg * p[x][1] + wr * p[x][2];
        m[x] = share < fraction ? 255 : 0;
      }
    }
    return mask;
  }

  static Eigen::Vector2d ChromaOf(double b, double g, double r) {
    const double luma = 0.299 * r + 0.587 * g + 0.114 * b;
    return {0.564 * (b - luma), 0.713 * (r - luma)};
  }

  SegmentOptions options_;
};

// An invalid option: its key and what is wrong with it.
struct Problem {
  std::string key;
  std::string what;
};

std::unexpected<Problem> Invalid(std::string_view key, std::string what) {
  return std::unexpected(Problem{std::string(key), std::move(what)});
}

std::expected<void, Problem> FindProblem(const SegmentOptions& options) {
  if (options.method != "otsu" && options.method != "fixed" && options.method != "background" &&
      options.method != "chroma" && options.method != "graphcut" && options.method != "auto") {
    return Invalid("method", fmt::format("\"{}\" is not one of \"otsu\", \"fixed\", "
                                         "\"background\", \"chroma\", \"graphcut\", \"auto\"",
                                         options.method));
  }
  if (!options.backdrop_bgr.empty()) {
    if (options.backdrop_bgr.size() != 3)
      return Invalid("backdrop_bgr", "needs three numbers, B G R");
    for (double c : options.backdrop_bgr) {
      if (!(c >= 0.0 && c <= 255.0)) {
        return Invalid("backdrop_bgr", "each value must lie in [0, 255]");
      }
    }
  }
  if (options.refine_max_side_px != 0 &&
      (options.refine_max_side_px < 32 || options.refine_max_side_px > 8192)) {
    return Invalid("refine_max_side_px",
                   fmt::format("{} is not 0 or in [32, 8192]", options.refine_max_side_px));
  }
  if (options.backdrop != "dark" && options.backdrop != "light") {
    return Invalid("backdrop",
                   fmt::format("\"{}\" is not one of \"dark\", \"light\"", options.backdrop));
  }
  if (options.threshold < 0 || options.threshold > 255) {
    return Invalid("threshold", fmt::format("{} is out of range [0, 255]", options.threshold));
  }
  if (!(options.min_contrast >= 0.0 && options.min_contrast <= 255.0)) {
    return Invalid("min_contrast", "out of range [0, 255]");
  }
  if (!(options.difference_threshold >= 0.0 && options.difference_threshold <= 442.0)) {
    return Invalid("difference_threshold", "out of range [0, 442]");
  }
  if (!options.chroma_key_bgr.empty()) {
    if (options.chroma_key_bgr.size() != 3) {
      return Invalid("chroma_key_bgr", "needs three numbers, B G R");
    }
    for (double c : options.chroma_key_bgr) {
      if (!(c >= 0.0 && c <= 255.0)) {
        return Invalid("chroma_key_bgr", "each value must lie in [0, 255]");
      }
    }
  }
  if (!(options.chroma_fraction > 0.0 && options.chroma_fraction < 1.0)) {
    return Invalid("chroma_fraction", "out of range (0, 1)");
  }
  if (!options.roi_px.empty()) {
    if (options.roi_px.size() != 4) {
      return Invalid("roi_px", "needs four numbers: left, top, right, bottom");
    }
    if (options.roi_px[2] <= options.roi_px[0] || options.roi_px[3] <= options.roi_px[1]) {
      return Invalid("roi_px", "right must exceed left and bottom must exceed top");
    }
  }
  if (!options.roi_polygon_px.empty() &&
      (options.roi_polygon_px.size() % 2 != 0 || options.roi_polygon_px.size() < 6)) {
    return Invalid("roi_polygon_px", "needs at least three x y pairs");
  }
  if (options.exclude_px.size() % 4 != 0) {
    return Invalid("exclude_px", "needs groups of four numbers: left, top, right, bottom");
  }
  for (const auto& [key, radius] :
       {std::pair{"open_px", options.open_px}, std::pair{"close_px", options.close_px}}) {
    if (radius < 0 || radius > kMaxMorphologyRadiusPx) {
      return Invalid(key,
                     fmt::format("{} is out of range [0, {}]", radius, kMaxMorphologyRadiusPx));
    }
  }
  if (options.max_hole_area_px < 0) return Invalid("max_hole_area_px", "must not be negative");
  return {};
}

// Reads an array of integers (given as TOML numbers) within [min, max].
Expected<std::vector<int>> Integers(const config::Section& section, std::string_view key,
                                    std::size_t count_multiple) {
  auto values = section.Numbers(key, {});
  if (!values) return std::unexpected(values.error());
  if (values->size() % count_multiple != 0) {
    return std::unexpected(section.BadValue(
        key, fmt::format("needs groups of {} numbers, got {}", count_multiple, values->size())));
  }
  std::vector<int> out;
  for (double v : *values) {
    if (v != std::floor(v) || std::abs(v) > kMaxCoordinatePx) {
      return std::unexpected(section.BadValue(key, fmt::format("{} is not a pixel coordinate", v)));
    }
    out.push_back(static_cast<int>(v));
  }
  return out;
}

}  // namespace

cv::Mat RegionOfInterestMask(const SegmentOptions& options, cv::Size size) {
  const cv::Rect image(0, 0, size.width, size.height);
  cv::Mat roi(size, CV_8UC1, cv::Scalar(0));
  cv::Rect inside = image;
  if (options.roi_px.size() == 4) {
    inside = cv::Rect(cv::Point(options.roi_px[0], options.roi_px[1]),
                      cv::Point(options.roi_px[2], options.roi_px[3])) &
             image;
  }
  roi(inside).setTo(255);
  if (options.roi_polygon_px.size() >= 6) {
    std::vector<cv::Point> polygon;
    for (std::size_t i = 0; i + 1 < options.roi_polygon_px.size(); i += 2) {
      polygon.emplace_back(options.roi_polygon_px[i], options.roi_polygon_px[i + 1]);
    }
    cv::Mat inside_polygon(size, CV_8UC1, cv::Scalar(0));
    cv::fillPoly(inside_polygon, std::vector<std::vector<cv::Point>>{polygon}, cv::Scalar(255));
    roi &= inside_polygon;
  }
  for (std::size_t i = 0; i + 3 < options.exclude_px.size(); i += 4) {
    const cv::Rect excluded =
        cv::Rect(cv::Point(options.exclude_px[i], options.exclude_px[i + 1]),
                 cv::Point(options.exclude_px[i + 2], options.exclude_px[i + 3])) &
        image;
    if (excluded.area() > 0) roi(excluded).setTo(0);
  }
  return roi;
}

// The shadow model's allowance for noise in a clipped channel (BackdropDistance).
constexpr int kClippedSlackLevels = 12;

namespace {

// sqrt(i) rounded and saturated, for the squared distances that stay below 255^2: for the shadow
// model's pixels, one at a time, where a look-up is faster than RoundedRoot (below), which the
// common case computes on vectors instead (the same values).
const std::vector<std::uint8_t>& RootTable() {
  static const std::vector<std::uint8_t> root = [] {
    std::vector<std::uint8_t> table(255 * 255 + 1);
    for (std::size_t i = 0; i < table.size(); ++i) {
      table[i] = cv::saturate_cast<std::uint8_t>(std::sqrt(static_cast<double>(i)));
    }
    return table;
  }();
  return root;
}

}  // namespace

namespace {

// The root table's value for a squared distance `square` <= 255^2, computed without the table
// (so that a row of them runs on vectors): the root of a whole number is never within
// 1 / (4 (2n + 1)) > 4.8e-4 of a half n + 1/2 ((n + 1/2)^2 is no whole number), and a float's
// square root of a whole number below 2^24, plus 1/2, is within 1.6e-5 of it there, so that
// truncating it rounds as the table does. segmenter_test checks every square.
[[gnu::always_inline]] inline std::uint8_t RoundedRoot(int square) {
  // NOLINTNEXTLINE(bugprone-incorrect-roundings): the root is never near a half (above).
  return static_cast<std::uint8_t>(static_cast<int>(std::sqrt(static_cast<float>(square)) + 0.5f));
}

// BackdropDistanceRow without the shadow model (the common case): against the one backdrop colour
// `b` points at, or (per_pixel) the backdrop's own pixels there; on vectors (built for AVX2 too
// where the processor has it).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
void BackdropDistanceRowNoShadows(const std::uint8_t* __restrict p,
                                  const std::uint8_t* __restrict b, bool per_pixel,
                                  std::ptrdiff_t count, std::uint8_t* __restrict o) {
  constexpr int kMaxSquare = 255 * 255;
  if (per_pixel) {
    for (std::ptrdiff_t x = 0; x < count; ++x) {
      const int d0 = p[3 * x] - b[3 * x], d1 = p[3 * x + 1] - b[3 * x + 1],
                d2 = p[3 * x + 2] - b[3 * x + 2];
      o[x] = RoundedRoot(std::min(d0 * d0 + d1 * d1 + d2 * d2, kMaxSquare));
    }
    return;
  }
  const int k0 = b[0], k1 = b[1], k2 = b[2];
  for (std::ptrdiff_t x = 0; x < count; ++x) {
    const int d0 = p[3 * x] - k0, d1 = p[3 * x + 1] - k1, d2 = p[3 * x + 2] - k2;
    o[x] = RoundedRoot(std::min(d0 * d0 + d1 * d1 + d2 * d2, kMaxSquare));
  }
}

void BackdropDistanceRow(const std::uint8_t* p, const std::uint8_t* b, bool per_pixel, bool shadows,
                         int count, std::uint8_t* o) {
  if (!shadows) {  // the common case
    BackdropDistanceRowNoShadows(p, b, per_pixel, count, o);
    return;
  }
  const std::uint8_t* root = RootTable().data();
  constexpr int kMaxSquare = 255 * 255;
  for (std::ptrdiff_t x = 0; x < count; ++x) {
    const std::uint8_t* c = p + 3 * x;
    const std::uint8_t* k = b + (per_pixel ? 3 * x : 0);
    const int d0 = c[0] - k[0], d1 = c[1] - k[1], d2 = c[2] - k[2];
    const int dist2 = d0 * d0 + d1 * d1 + d2 * d2;
    std::uint8_t score = root[static_cast<std::size_t>(std::min(dist2, kMaxSquare))];
    // A shadow: the backdrop's colour scaled by a (0.35..1.1); only its chroma counts, twice
    // |c - a k| = 2 sqrt(|c|^2 - (c.k)^2 / |k|^2). One channel of the backdrop at 255 and the
    // others below is clipped (a white blown out in red under warm light): its true level is
    // 255 or more, so a and the chroma come from the other two, and the pixel's level there
    // need only be at least a 255 (less a noise allowance). (Every channel at 255 is a white
    // blown out evenly, and its shadows are grey: the key as it is.)
    int known[3] = {k[0] < 255, k[1] < 255, k[2] < 255};
    if (known[0] + known[1] + known[2] != 2) known[0] = known[1] = known[2] = 1;
    const int norm2 = known[0] * k[0] * k[0] + known[1] * k[1] * k[1] + known[2] * k[2] * k[2];
    if (norm2 > 900) {
      const int dot = known[0] * c[0] * k[0] + known[1] * c[1] * k[1] + known[2] * c[2] * k[2];
      bool consistent = true;
      for (int i = 0; i < 3; ++i) {
        if (!known[i]) consistent &= (c[i] + kClippedSlackLevels) * norm2 >= 255 * dot;
      }
      if (consistent && 20 * dot >= 7 * norm2 && 10 * dot <= 11 * norm2) {
        const int c2 = known[0] * c[0] * c[0] + known[1] * c[1] * c[1] + known[2] * c[2] * c[2];
        const float off2 = std::max(0.0f, static_cast<float>(c2) - static_cast<float>(dot) *
                                                                       static_cast<float>(dot) /
                                                                       static_cast<float>(norm2));
        const int four_off2 = static_cast<int>(std::min(4.0f * off2 + 0.5f, float(kMaxSquare)));
        score = std::min(score, root[static_cast<std::size_t>(four_off2)]);
      }
    }
    o[x] = score;
  }
}

}  // namespace

cv::Mat BackdropDistance(const cv::Mat& bgr, const cv::Mat& backdrop_bgr, bool shadows) {
  const bool per_pixel = backdrop_bgr.size() == bgr.size();
  cv::Mat out(bgr.size(), CV_8UC1);
  for (int y = 0; y < bgr.rows; ++y) {
    BackdropDistanceRow(bgr.ptr<std::uint8_t>(y), backdrop_bgr.ptr<std::uint8_t>(per_pixel ? y : 0),
                        per_pixel, shadows, bgr.cols, out.ptr<std::uint8_t>(y));
  }
  return out;
}

cv::Scalar EstimateBackdropColour(const cv::Mat& image, const cv::Mat& roi) {
  // Each channel's median over the outline (the level at index n / 2 in order) from its counts.
  std::array<std::array<int, 256>, 3> counts{};
  const std::vector<cv::Point> outline = RectOutline(RoiBox(image.size(), roi));
  for (const cv::Point& p : outline) {
    const cv::Vec3b& c = image.at<cv::Vec3b>(p);
    for (int k = 0; k < 3; ++k) ++counts[k][c[k]];
  }
  cv::Scalar out;
  const std::size_t middle = outline.size() / 2;
  for (int c = 0; c < 3; ++c) {
    std::size_t below = 0;
    int level = 0;
    while (level < 255 && below + static_cast<std::size_t>(counts[c][level]) <= middle) {
      below += static_cast<std::size_t>(counts[c][level++]);
    }
    out[c] = level;
  }
  return out;
}

Expected<SegmentOptions> ParseSegmentOptions(const config::Section& section) {
  SegmentOptions options;
  auto method = section.String("method", options.method,
                               {"otsu", "fixed", "background", "chroma", "graphcut", "auto"});
  if (!method) return std::unexpected(method.error());
  auto backdrop = section.String("backdrop", options.backdrop, {"dark", "light"});
  if (!backdrop) return std::unexpected(backdrop.error());
  auto threshold = section.Integer("threshold", options.threshold, 0, 255);
  if (!threshold) return std::unexpected(threshold.error());
  auto min_contrast = section.Number("min_contrast", options.min_contrast, 0.0, 255.0);
  if (!min_contrast) return std::unexpected(min_contrast.error());
  auto difference =
      section.Number("difference_threshold", options.difference_threshold, 0.0, 442.0);
  if (!difference) return std::unexpected(difference.error());
  auto background_file = section.Path("background_file");
  if (!background_file) return std::unexpected(background_file.error());
  auto key = section.Numbers("chroma_key_bgr", {});
  if (!key) return std::unexpected(key.error());
  if (!key->empty() && key->size() != 3) {
    return std::unexpected(section.BadValue("chroma_key_bgr", "needs three numbers, B G R"));
  }
  for (double c : *key) {
    if (!(c >= 0.0 && c <= 255.0)) {
      return std::unexpected(section.BadValue("chroma_key_bgr", "each value must lie in [0, 255]"));
    }
  }
  auto fraction = section.Number("chroma_fraction", options.chroma_fraction, 0.01, 0.99);
  if (!fraction) return std::unexpected(fraction.error());
  auto roi = Integers(section, "roi_px", 4);
  if (!roi) return std::unexpected(roi.error());
  if (roi->size() > 4) {
    return std::unexpected(
        section.BadValue("roi_px", "needs four numbers: left, top, right, bottom"));
  }
  auto polygon = Integers(section, "roi_polygon_px", 2);
  if (!polygon) return std::unexpected(polygon.error());
  auto exclude = Integers(section, "exclude_px", 4);
  if (!exclude) return std::unexpected(exclude.error());
  auto open_px = section.Integer("open_px", options.open_px, 0, kMaxMorphologyRadiusPx);
  if (!open_px) return std::unexpected(open_px.error());
  auto close_px = section.Integer("close_px", options.close_px, 0, kMaxMorphologyRadiusPx);
  if (!close_px) return std::unexpected(close_px.error());
  auto keep_largest = section.Boolean("keep_largest", options.keep_largest);
  if (!keep_largest) return std::unexpected(keep_largest.error());
  auto fill_holes = section.Boolean("fill_holes", options.fill_holes);
  if (!fill_holes) return std::unexpected(fill_holes.error());
  auto max_hole = section.Integer("max_hole_area_px", options.max_hole_area_px, 0, 1 << 30);
  if (!max_hole) return std::unexpected(max_hole.error());
  auto backdrop_bgr = section.Numbers("backdrop_bgr", {});
  if (!backdrop_bgr) return std::unexpected(backdrop_bgr.error());
  options.backdrop_bgr = *backdrop_bgr;
  auto refine = section.Boolean("refine", options.refine);
  if (!refine) return std::unexpected(refine.error());
  auto refine_side = section.Integer("refine_max_side_px", options.refine_max_side_px, 0, 8192);
  if (!refine_side) return std::unexpected(refine_side.error());
  if (auto ok = section.CheckNoUnknownKeys(); !ok) return std::unexpected(ok.error());
  options.refine = *refine;
  options.refine_max_side_px = static_cast<int>(*refine_side);
  options.method = *method;
  options.backdrop = *backdrop;
  options.threshold = static_cast<int>(*threshold);
  options.min_contrast = *min_contrast;
  options.difference_threshold = *difference;
  options.background_file = *background_file;
  options.chroma_key_bgr = *key;
  options.chroma_fraction = *fraction;
  options.roi_px = *roi;
  options.roi_polygon_px = *polygon;
  options.exclude_px = *exclude;
  options.open_px = static_cast<int>(*open_px);
  options.close_px = static_cast<int>(*close_px);
  options.keep_largest = *keep_largest;
  options.fill_holes = *fill_holes;
  options.max_hole_area_px = static_cast<int>(*max_hole);
  if (auto ok = FindProblem(options); !ok) {
    return std::unexpected(section.BadValue(ok.error().key, ok.error().what));
  }
  return options;
}

Expected<cv::Mat> Segmenter::SegmentWithFacts(const cv::Mat& image, const cv::Mat& background,
                                              const FrameFacts& /*facts*/) const {
  return Segment(image, background);
}

Expected<std::unique_ptr<Segmenter>> CreateSegmenter(const SegmentOptions& options) {
  if (auto ok = FindProblem(options); !ok) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("[segment] {}: {}", ok.error().key, ok.error().what));
  }
  return std::unique_ptr<Segmenter>(std::make_unique<PipelineSegmenter>(options));
}

}  // namespace revolve::capture
