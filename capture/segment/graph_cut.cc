#include "capture/segment/graph_cut.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "base/mask_rect.h"
#include "capture/segment/backdrop_surface.h"
#include "capture/segment/colour_cut.h"
#include "capture/segment/mask_ops.h"

namespace revolve::capture {
namespace {

// The edge is placed where the score has risen this fraction of the way from the local backdrop
// level to the local object level: below half, so pixels the object partly covers count as
// object (a hull carved from masks must not lose the object's rim).
constexpr float kEdgeFraction = 0.35f;
// The trimap's "probably object" starts this fraction of the way from the backdrop level to the
// object level: deep shadows on the object (a fifth of its brightness) start as object, and the
// colour models decide.
constexpr double kProbableFraction = 0.3;

cv::Mat Disc(int radius_px) {
  return cv::getStructuringElement(cv::MORPH_ELLIPSE,
                                   cv::Size(2 * radius_px + 1, 2 * radius_px + 1));
}

cv::Mat Eroded(const cv::Mat& mask, int radius_px) {
  cv::Mat out;
  cv::erode(mask, out, Disc(radius_px));
  return out;
}

cv::Mat Dilated(const cv::Mat& mask, int radius_px) {
  cv::Mat out;
  cv::dilate(mask, out, Disc(radius_px));
  return out;
}

// Scales a trimap down without promoting any pixel to "sure": a reduced pixel is sure object
// (backdrop) only when every full-size pixel it covers is.
cv::Mat ReduceTrimap(const cv::Mat& trimap, cv::Size size, int radius_px) {
  const cv::Mat sure_fg = Eroded(trimap == cv::GC_FGD, radius_px);
  const cv::Mat sure_bg = Eroded(trimap == cv::GC_BGD, radius_px);
  const cv::Mat probable_fg = trimap == cv::GC_PR_FGD;
  cv::Mat labels(trimap.size(), CV_8UC1, cv::Scalar(cv::GC_PR_BGD));
  labels.setTo(cv::GC_PR_FGD, probable_fg | (trimap == cv::GC_FGD));
  labels.setTo(cv::GC_FGD, sure_fg);
  labels.setTo(cv::GC_BGD, sure_bg);
  cv::Mat small;
  cv::resize(labels, small, size, 0.0, 0.0, cv::INTER_NEAREST);
  return small;
}

// Undecided pixels farther than `reach_px` from every sure object pixel become sure backdrop,
// except those of `kept` (CV_8UC1, may be empty: what the noise hysteresis brought in): the
// object is what its sure core reaches. A cloth's fold or a stand far from the object is not cut
// (the max-flow's slow case: a wide region both colour models explain alike).
// Done within the rectangle of the labels other than GC_BGD, which holds every sure object pixel
// and every pixel it may change: OpenCV's 3x3 distance is a whole number of fixed-point steps, the
// cheapest path's from the nearest sure object pixel, and such a path stays within the rectangle
// of its two ends. So each distance there is the whole frame's.
void LimitReach(cv::Mat& labels, const cv::Mat& kept, double reach_px) {
  if (reach_px <= 0.0) return;
  const cv::Rect part = MaskRect(cv::Mat(labels != cv::GC_BGD));
  if (part.empty()) return;
  const cv::Mat sure_object = labels(part) == cv::GC_FGD;
  if (cv::countNonZero(sure_object) == 0) return;
  cv::Mat distance;
  cv::distanceTransform(~sure_object, distance, cv::DIST_L2, 3);
  cv::Mat beyond = distance > reach_px;
  if (!kept.empty()) beyond &= ~kept(part);
  labels(part).setTo(cv::GC_BGD, beyond);
}

constexpr int kColourLevels = 16;

// Colour level (0..15) of an 8-bit value on a square-root scale (finer in the dark).
int ColourLevel(std::uint8_t v) {
  static const std::array<std::uint8_t, 256> table = [] {
    std::array<std::uint8_t, 256> t{};
    for (int i = 0; i < 256; ++i) {
      t[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(
          std::min(kColourLevels - 1, static_cast<int>(std::sqrt(i / 255.0) * kColourLevels)));
    }
    return t;
  }();
  return table[v];
}

int ColourBin(const cv::Vec3b& c) {
  return (ColourLevel(c[0]) * kColourLevels + ColourLevel(c[1])) * kColourLevels +
         ColourLevel(c[2]);
}

// The colour bins common among the pixels of `edge` (CV_8UC1): a bin holding at least 8 of them
// and 0.5 % of `ring_px`, widened by one level each way; empty when no bin is. What touches the
// frame's edge above the backdrop's noise (a stand's foot, a cloth) has these colours.
std::vector<std::uint8_t> EdgeColours(const cv::Mat& bgr, const cv::Mat& edge, int ring_px) {
  constexpr int kBins = kColourLevels * kColourLevels * kColourLevels;
  std::vector<int> counts(kBins, 0);
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* p = bgr.ptr<cv::Vec3b>(y);
    const auto* e = edge.ptr<std::uint8_t>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      if (e[x]) ++counts[static_cast<std::size_t>(ColourBin(p[x]))];
    }
  }
  const int least = std::max(8, ring_px / 200);
  std::vector<std::uint8_t> common(kBins, 0);
  bool any = false;
  for (int b = 0; b < kBins; ++b) {
    if (counts[static_cast<std::size_t>(b)] < least) continue;
    any = true;
    const int l0 = b / (kColourLevels * kColourLevels), l1 = (b / kColourLevels) % kColourLevels,
              l2 = b % kColourLevels;
    for (int a0 = std::max(0, l0 - 1); a0 <= std::min(kColourLevels - 1, l0 + 1); ++a0) {
      for (int a1 = std::max(0, l1 - 1); a1 <= std::min(kColourLevels - 1, l1 + 1); ++a1) {
        for (int a2 = std::max(0, l2 - 1); a2 <= std::min(kColourLevels - 1, l2 + 1); ++a2) {
          const int bin = (a0 * kColourLevels + a1) * kColourLevels + a2;
          common[static_cast<std::size_t>(bin)] = 1;
        }
      }
    }
  }
  if (!any) common.clear();
  return common;
}

// `candidates` (CV_8UC1) without the pixels whose colour is one of `colours` (EdgeColours).
cv::Mat Without(const cv::Mat& candidates, const cv::Mat& bgr,
                const std::vector<std::uint8_t>& colours) {
  if (colours.empty()) return candidates;
  cv::Mat out = candidates.clone();
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* p = bgr.ptr<cv::Vec3b>(y);
    auto* o = out.ptr<std::uint8_t>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      if (o[x] && colours[static_cast<std::size_t>(ColourBin(p[x]))]) o[x] = 0;
    }
  }
  return out;
}

// The object's body: the largest 8-connected component of `mask` (CV_8UC1) opened by a disc of
// half its greatest depth (the frame's edge does not count as outline). What a stand's post or
// foot adds to it is thinner than the object it holds and is not body; an object that crosses
// the frame's edge is body up to the edge. Found on a copy of at most 320 px a side (the body's
// outline is a few pixels coarse). Empty mask when `mask` is.
cv::Mat Body(const cv::Mat& full) {
  constexpr int kMaxSidePx = 320;
  const int side = std::max(full.cols, full.rows);
  cv::Mat mask = full;
  if (side > kMaxSidePx) {
    const double scale = double(kMaxSidePx) / side;
    cv::resize(full, mask, cv::Size(), scale, scale, cv::INTER_NEAREST);
  }
  const cv::Mat component = KeepLargestComponent(mask);
  if (cv::countNonZero(component) == 0) return cv::Mat(full.size(), CV_8UC1, cv::Scalar(0));
  cv::Mat depth;
  cv::distanceTransform(component, depth, cv::DIST_L2, 3);
  double deepest = 0.0;
  cv::minMaxLoc(depth, nullptr, &deepest);
  const double radius = 0.5 * deepest;
  cv::Mat from_core;
  cv::distanceTransform(depth <= radius, from_core, cv::DIST_L2, 3);
  cv::Mat body = component & (from_core <= radius);
  if (body.size() == full.size()) return body;
  cv::Mat up;
  cv::resize(body, up, full.size(), 0.0, 0.0, cv::INTER_NEAREST);
  return up;
}

double ProbableLevel(const ScoreLevels& levels) {
  return levels.backdrop + kProbableFraction * (levels.object - levels.backdrop);
}

}  // namespace

cv::Mat NoiseScore(const cv::Mat& score) {
  // cv::blur(score, out, 5x5, BORDER_REPLICATE) to the bit, in 16-bit whole numbers (so that
  // the loops vectorise): the 25 pixels' sum s (at most 6375) gives s / 25 rounded to nearest
  // (no sum lies half-way), i.e. (s + 12) / 25 rounded down, which is ((s + 12) * 5243) >> 17
  // for every such s (5243 / 2^17 exceeds 1 / 25 by less than 1 / (25 * 6387)). Each row's
  // column sums over its 5 rows (the edge rows repeated), padded by 2 repeated columns each
  // side, then 5 of them.
  constexpr int kRadius = 2;
  const int rows = score.rows;
  const int cols = score.cols;
  cv::Mat out(score.size(), CV_8UC1);
  std::vector<std::uint16_t> padded(static_cast<std::size_t>(cols + 2 * kRadius));
  for (int y = 0; y < rows; ++y) {
    const std::uint8_t* r[2 * kRadius + 1];
    for (int dy = -kRadius; dy <= kRadius; ++dy) {
      r[dy + kRadius] = score.ptr<std::uint8_t>(std::clamp(y + dy, 0, rows - 1));
    }
    std::uint16_t* column = padded.data() + kRadius;
    for (int x = 0; x < cols; ++x) {
      column[x] = static_cast<std::uint16_t>(r[0][x] + r[1][x] + r[2][x] + r[3][x] + r[4][x]);
    }
    for (int k = 1; k <= kRadius; ++k) {
      column[-k] = column[0];
      column[cols - 1 + k] = column[cols - 1];
    }
    std::uint8_t* o = out.ptr<std::uint8_t>(y);
    for (int x = 0; x < cols; ++x) {
      const auto sum = static_cast<std::uint16_t>(column[x - 2] + column[x - 1] + column[x] +
                                                  column[x + 1] + column[x + 2] + 12);
      const auto high = static_cast<std::uint16_t>((std::uint32_t{sum} * 5243u) >> 16);
      o[x] = static_cast<std::uint8_t>(high >> 1);
    }
  }
  return out;
}

double BackdropNoiseCeiling(const cv::Mat& score, const cv::Mat& roi) {
  std::vector<int> values;
  for (const cv::Point& p : RectOutline(RoiBox(score.size(), roi))) {
    values.push_back(score.at<std::uint8_t>(p));
  }
  const auto median_of = [](std::vector<int> v) {
    const auto middle = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), middle, v.end());
    return static_cast<double>(*middle);
  };
  const double median = median_of(values);
  for (int& v : values) v = static_cast<int>(std::lround(std::abs(v - median)));
  const double mad = median_of(values);
  return median + std::max(3.0, 5.0 * 1.4826 * mad);
}

bool UsesNoiseHysteresis(const ScoreLevels& levels) {
  return levels.noise >= 0.0 && levels.noise < ProbableLevel(levels);
}

EdgeLevelPart EdgeLevels(const cv::Mat& full_mask, const cv::Mat& full_score, int radius_px) {
  // Only around the object: the band lies within radius_px of its rectangle, and a band pixel's
  // window reaches 2 radius_px + 1 further. The work is done on views of that part of the frame
  // (morphology reads the frame's own pixels past a view's edge, as on the whole frame), and the
  // window sums are of whole numbers (scores of 0..255, counts), exact in any order: the same
  // levels as over the whole frame, for the part of the work the object's surroundings take.
  EdgeLevelPart found;
  const cv::Rect object = MaskRect(full_mask);
  if (object.empty()) return found;
  const int margin = 3 * radius_px + 3;
  const cv::Rect part = cv::Rect(object.x - margin, object.y - margin, object.width + 2 * margin,
                                 object.height + 2 * margin) &
                        cv::Rect(0, 0, full_mask.cols, full_mask.rows);
  found.part = part;
  found.levels = cv::Mat(part.size(), CV_32FC1, cv::Scalar(-1.0f));
  cv::Mat& levels = found.levels;
  const cv::Mat mask = full_mask(part);
  const cv::Mat score = full_score(part);
  const cv::Mat inside = Eroded(mask, radius_px + 1);
  const cv::Mat outside = ~Dilated(mask, radius_px + 1);
  const cv::Mat band = Dilated(mask, radius_px) & ~Eroded(mask, radius_px);
  // Whole-number window sums of the inside's and the outside's scores, and of their pixels
  // (255 each): exact in 32 bits (the float sums they replace were the same values).
  const cv::Size window(4 * radius_px + 3, 4 * radius_px + 3);
  cv::Mat in_sum, in_count, out_sum, out_count;
  cv::boxFilter(score & inside, in_sum, CV_32S, window, {-1, -1}, false);
  cv::boxFilter(inside, in_count, CV_32S, window, {-1, -1}, false);
  cv::boxFilter(score & outside, out_sum, CV_32S, window, {-1, -1}, false);
  cv::boxFilter(outside, out_count, CV_32S, window, {-1, -1}, false);
  for (int y = 0; y < mask.rows; ++y) {
    const auto* b = band.ptr<std::uint8_t>(y);
    const auto* is = in_sum.ptr<std::int32_t>(y);
    const auto* ic = in_count.ptr<std::int32_t>(y);
    const auto* os = out_sum.ptr<std::int32_t>(y);
    const auto* oc = out_count.ptr<std::int32_t>(y);
    auto* l = levels.ptr<float>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (!b[x] || ic[x] == 0 || oc[x] == 0) continue;
      const int inside_count = ic[x] / 255;  // exact: 255 per pixel
      const int outside_count = oc[x] / 255;
      const float outside_level = static_cast<float>(os[x]) / static_cast<float>(outside_count);
      l[x] = outside_level +
             kEdgeFraction *
                 (static_cast<float>(is[x]) / static_cast<float>(inside_count) - outside_level);
    }
  }
  return found;
}

cv::Mat PlaceEdge(const cv::Mat& mask, const cv::Mat& score, int radius_px) {
  const EdgeLevelPart found = EdgeLevels(mask, score, radius_px);
  cv::Mat out = mask.clone();
  const cv::Rect& part = found.part;
  for (int y = 0; y < part.height; ++y) {
    const auto* l = found.levels.ptr<float>(y);
    const auto* s = score.ptr<std::uint8_t>(part.y + y) + part.x;
    auto* o = out.ptr<std::uint8_t>(part.y + y) + part.x;
    for (int x = 0; x < part.width; ++x) {
      if (l[x] >= 0.0f) o[x] = s[x] >= l[x] ? 255 : 0;
    }
  }
  return out;
}

Trimap TrimapFromScore(const cv::Mat& bgr, const cv::Mat& score, const ScoreLevels& levels,
                       const cv::Mat& roi, const GraphCutOptions& options,
                       const cv::Mat& noise_score) {
  Trimap trimap;
  cv::Mat& labels = trimap.labels;
  labels = cv::Mat(score.size(), CV_8UC1, cv::Scalar(cv::GC_PR_BGD));
  labels.setTo(cv::GC_PR_FGD, score > ProbableLevel(levels));
  const int ring = std::max(
      1, static_cast<int>(std::lround(options.border_fraction * std::min(score.cols, score.rows))));
  cv::Mat border(score.size(), CV_8UC1, cv::Scalar(255));
  if (score.cols > 2 * ring && score.rows > 2 * ring) {
    border(cv::Rect(ring, ring, score.cols - 2 * ring, score.rows - 2 * ring)).setTo(0);
  }
  const bool hysteresis = UsesNoiseHysteresis(levels);
  const cv::Mat above_noise =
      hysteresis ? cv::Mat((noise_score.empty() ? NoiseScore(score) : noise_score) > levels.noise)
                 : cv::Mat();
  // With the hysteresis: the colours of what rises above the noise on the frame's edge (a
  // stand's foot, a cloth) are never object for sure nor brought in; the object's own body where
  // it crosses the frame's edge (a vase cropped at the top, an object on the bottom edge) does not
  // count.
  const cv::Mat above_object = score > levels.object;
  // (The object's body only where something rises above the noise on the frame's edge: most
  // objects stand clear of it.)
  std::vector<std::uint8_t> edge_colours;
  if (hysteresis) {
    const cv::Mat noise_on_edge = border & above_noise;
    if (cv::countNonZero(noise_on_edge) > 0) {
      edge_colours =
          EdgeColours(bgr, noise_on_edge & ~Body(above_object), cv::countNonZero(border));
    }
  }
  const cv::Mat above = Without(above_object, bgr, edge_colours);
  const cv::Mat sure_object = Eroded(above, 2);
  if (hysteresis) {
    const cv::Mat brought = Without(ConnectedThrough(above_noise, sure_object), bgr, edge_colours);
    labels.setTo(cv::GC_PR_FGD, brought);
    labels.setTo(cv::GC_BGD, Eroded(~above_noise, 2));
    trimap.kept = brought & ~sure_object;
  } else {
    labels.setTo(cv::GC_BGD, Eroded(score <= levels.backdrop, 2));
  }
  labels.setTo(cv::GC_FGD, sure_object);
  labels.setTo(cv::GC_BGD, border & ~above);
  if (!roi.empty()) labels.setTo(cv::GC_BGD, roi == 0);
  if (!trimap.kept.empty()) trimap.kept &= labels == cv::GC_PR_FGD;
  return trimap;
}

cv::Mat RefineWithGraphCut(const cv::Mat& bgr, const cv::Mat& score, const Trimap& full,
                           const GraphCutOptions& options) {
  const cv::Mat& trimap = full.labels;
  // What is returned when no cut can be made: the trimap's object labels.
  const auto fallback = [&] { return cv::Mat((trimap == cv::GC_FGD) | (trimap == cv::GC_PR_FGD)); };
  const int side = std::max(bgr.cols, bgr.rows);
  const double scale = options.max_side_px > 0 && side > options.max_side_px
                           ? double(options.max_side_px) / side
                           : 1.0;
  const int radius = scale < 1.0 ? static_cast<int>(std::ceil(1.0 / scale)) : 0;
  cv::Mat small_bgr = bgr;
  cv::Mat labels = scale < 1.0 ? cv::Mat() : trimap.clone();
  cv::Mat kept = full.kept;
  if (scale < 1.0) {
    const cv::Size size(std::max(1, static_cast<int>(std::lround(bgr.cols * scale))),
                        std::max(1, static_cast<int>(std::lround(bgr.rows * scale))));
    cv::resize(bgr, small_bgr, size, 0.0, 0.0, cv::INTER_AREA);
    labels = ReduceTrimap(trimap, size, radius);
    if (!kept.empty()) cv::resize(full.kept, kept, size, 0.0, 0.0, cv::INTER_NEAREST);
  }
  if (!kept.empty()) kept &= labels == cv::GC_PR_FGD;
  LimitReach(labels, kept, options.reach_fraction * std::max(labels.cols, labels.rows));
  const bool has_fg = cv::countNonZero((labels == cv::GC_FGD) | (labels == cv::GC_PR_FGD)) > 0;
  const bool has_bg = cv::countNonZero((labels == cv::GC_BGD) | (labels == cv::GC_PR_BGD)) > 0;
  if (!has_fg || !has_bg) return fallback();
  // Only the rectangle around the undecided and object labels (with a margin of backdrop for
  // its colour model) goes through the cut; the rest is backdrop for sure.
  const cv::Rect undecided = MaskRect(cv::Mat(labels != cv::GC_BGD));
  const int margin = std::max(8, std::max(undecided.width, undecided.height) / 8);
  const cv::Rect crop = cv::Rect(undecided.x - margin, undecided.y - margin,
                                 undecided.width + 2 * margin, undecided.height + 2 * margin) &
                        cv::Rect(0, 0, labels.cols, labels.rows);
  cv::Mat cropped_labels = labels(crop).clone();
  ColourCutOptions cut;
  cut.iterations = options.iterations;
  if (!CutByColour(small_bgr(crop), cropped_labels, cut, kept.empty() ? cv::Mat() : kept(crop))) {
    return fallback();
  }
  cropped_labels.copyTo(labels(crop));
  cv::Mat object = (labels == cv::GC_FGD) | (labels == cv::GC_PR_FGD);
  if (scale == 1.0) return object;
  cv::Mat up;
  cv::resize(object, up, bgr.size(), 0.0, 0.0, cv::INTER_LINEAR);
  cv::Mat mask = up >= 128;
  // The sure labels hold at full size whatever the reduced cut did.
  mask.setTo(255, trimap == cv::GC_FGD);
  mask.setTo(0, trimap == cv::GC_BGD);
  return PlaceEdge(mask, score, radius);
}

cv::Mat FillHolesUnlessBackdrop(const cv::Mat& mask, const cv::Mat& score, double backdrop_level,
                                int min_open_px) {
  cv::Mat padded;
  cv::copyMakeBorder(mask, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::Mat flood = padded.clone();
  cv::floodFill(flood, cv::Point(0, 0), cv::Scalar(255), nullptr, cv::Scalar(), cv::Scalar(), 4);
  const cv::Mat holes = ~flood(cv::Rect(1, 1, mask.cols, mask.rows));
  cv::Mat labels;
  const int count = cv::connectedComponents(holes, labels, 4, CV_32S);
  if (count <= 1) return mask;
  std::vector<std::vector<std::uint8_t>> scores(static_cast<std::size_t>(count));
  for (int y = 0; y < mask.rows; ++y) {
    const int* l = labels.ptr<int>(y);
    const auto* s = score.ptr<std::uint8_t>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (l[x] > 0) scores[static_cast<std::size_t>(l[x])].push_back(s[x]);
    }
  }
  std::vector<std::uint8_t> fill(static_cast<std::size_t>(count), 0);
  for (int i = 1; i < count; ++i) {
    auto& v = scores[static_cast<std::size_t>(i)];
    if (static_cast<int>(v.size()) <= min_open_px) {
      fill[static_cast<std::size_t>(i)] = 1;
      continue;
    }
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    fill[static_cast<std::size_t>(i)] = v[v.size() / 2] > backdrop_level ? 1 : 0;
  }
  cv::Mat out = mask.clone();
  for (int y = 0; y < mask.rows; ++y) {
    const int* l = labels.ptr<int>(y);
    auto* o = out.ptr<std::uint8_t>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (l[x] > 0 && fill[static_cast<std::size_t>(l[x])]) o[x] = 255;
    }
  }
  return out;
}

}  // namespace revolve::capture
