#include "capture/segment/set_segmentation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>
#include <optional>

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "base/image_read.h"
#include "capture/segment/backdrop_surface.h"

namespace revolve::capture {
namespace {

constexpr double kDarkLuma = 80.0;
constexpr double kLightLuma = 170.0;
// As kColouredBackdropChroma (capture/segment/segmenter.cc): a green or blue screen, not a cream.
constexpr double kColouredChroma = 40.0;
constexpr int kStillLevels = 12;
constexpr double kStillOutline = 0.9;
constexpr double kStillGain = 0.1;
constexpr int kMinStillFrames = 4;
constexpr int kLearnMarginPx = 4;
// FrameByFrameSegmentation (auto): a frame whose own outline is this even is cut to its window
// at once (the set will most likely be cut by graphcut); a less even one is kept whole.
constexpr double kLikelyEvenShare = 0.95;
constexpr double kMaxObjectShare = 0.6;
constexpr std::size_t kMinViewsForAreaCheck = 3;
constexpr double kMinAreaShare = 0.2;

template <class T>
T Median(std::vector<T>& values) {
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2),
                   values.end());
  return values[values.size() / 2];
}

// The outline ring's pixel positions, every `step`-th.
std::vector<cv::Point> OutlinePoints(cv::Size size, int step) {
  std::vector<cv::Point> points;
  for (int x = 0; x < size.width; x += step) {
    points.emplace_back(x, 0);
    points.emplace_back(x, size.height - 1);
  }
  for (int y = 1; y + 1 < size.height; y += step) {
    points.emplace_back(0, y);
    points.emplace_back(size.width - 1, y);
  }
  return points;
}

// Share of the mask's outline ring that is object.
double OutlineObjectShare(const cv::Mat& mask) {
  const std::vector<cv::Point> points = OutlinePoints(mask.size(), 1);
  std::size_t set = 0;
  for (const cv::Point& p : points) set += mask.at<std::uint8_t>(p) != 0;
  return points.empty() ? 0.0 : double(set) / double(points.size());
}

std::string ProblemOf(const cv::Mat& mask) {
  const double area = cv::countNonZero(mask);
  if (area == 0) return "no object found (the frame looks like the backdrop everywhere)";
  const double share = area / static_cast<double>(mask.total());
  if (share > kMaxObjectShare) {
    return fmt::format(
        "the object covers {:.0f} % of the frame: the backdrop was probably taken "
        "for object",
        100.0 * share);
  }
  const double outline = OutlineObjectShare(mask);
  if (outline > 0.5) {
    return fmt::format(
        "the mask touches {:.0f} % of the frame's edge: the backdrop was probably "
        "taken for object",
        100.0 * outline);
  }
  return {};
}

// A mask far smaller than the set's others (a fold of the cloth in a frame without the object,
// or a piece of the object) carves the whole model down to itself: it is named, and left out.
void FlagSmallMasks(const std::vector<cv::Mat>& masks, std::vector<std::string>& problems) {
  std::vector<int> areas;
  for (std::size_t i = 0; i < masks.size(); ++i) {
    if (problems[i].empty()) areas.push_back(cv::countNonZero(masks[i]));
  }
  if (areas.size() < kMinViewsForAreaCheck) return;
  const double median = Median(areas);
  for (std::size_t i = 0; i < masks.size(); ++i) {
    const int area = cv::countNonZero(masks[i]);
    if (!problems[i].empty() || area >= kMinAreaShare * median) continue;
    problems[i] = fmt::format(
        "its mask holds {} px, {:.0f} % of the median view's {:.0f} px: probably a patch of the "
        "backdrop or only a part of the object",
        area, 100.0 * area / median, median);
  }
}

Expected<cv::Mat> ReadBackground(const SegmentOptions& options, cv::Size size) {
  if (options.background_file.empty()) return cv::Mat();
  ImageReadOptions read_options;
  read_options.imread_flags = cv::IMREAD_COLOR;
  Expected<cv::Mat> read = ReadImageFile(options.background_file, read_options);
  if (!read) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("[segment] background_file: cannot read it as an image: {}",
                                 read.error().message));
  }
  cv::Mat frame = std::move(*read);
  if (frame.size() != size) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("[segment] background_file: {} is {}x{} but the images are {}x{}",
                                 options.background_file.string(), frame.cols, frame.rows,
                                 size.width, size.height));
  }
  return frame;
}

Expected<std::vector<cv::Mat>> SegmentAll(const std::vector<cv::Mat>& frames,
                                          const SegmentOptions& options, const cv::Mat& background,
                                          const std::vector<FrameFacts>& facts) {
  Expected<std::unique_ptr<Segmenter>> segmenter = CreateSegmenter(options);
  if (!segmenter) return std::unexpected(segmenter.error());
  // The frames on all cores, each into its slot (a segmenter is const: Segment shares nothing
  // between frames); the first error in frame order is returned.
  std::vector<Expected<cv::Mat>> results(frames.size(), cv::Mat());
  tbb::parallel_for(std::size_t{0}, frames.size(), [&](std::size_t i) {
    results[i] = (*segmenter)->SegmentWithFacts(frames[i], background, facts[i]);
  });
  std::vector<cv::Mat> masks;
  masks.reserve(frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (!results[i]) {
      return std::unexpected(WithContext(results[i].error(), fmt::format("image {}", i + 1)));
    }
    masks.push_back(std::move(*results[i]));
  }
  return masks;
}

// What the survey finds of one frame on its own (SurveyFrame).
struct FrameOutline {
  std::vector<std::array<std::uint8_t, 3>> colours;  // at the outline points, in their order
  std::optional<BackdropSurface> surface;            // fitted to the whole outline
  std::size_t uniform = 0;  // colours within kStillLevels of the surface (when one fits)
};

// A frame's outline colours at `points`, and its count of them within kStillLevels of the smooth
// surface fitted to its outline (even light, light from one side and vignetting are even; a
// cloth's folds and texture are not). Where no surface fits, CombineOutlines counts them against
// the set's median colour.
FrameOutline SurveyFrame(const cv::Mat& frame, const std::vector<cv::Point>& points) {
  FrameOutline outline;
  outline.colours.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const cv::Vec3b& c = frame.at<cv::Vec3b>(points[i]);
    outline.colours[i] = {c[0], c[1], c[2]};
  }
  outline.surface = BackdropSurface::FitToOutline(frame, cv::Rect(0, 0, frame.cols, frame.rows));
  if (!outline.surface) return outline;
  for (const cv::Point& p : points) {
    const cv::Vec3b& c = frame.at<cv::Vec3b>(p);
    const cv::Vec3d expected = outline.surface->At(p.x, p.y);
    double worst = 0.0;
    for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(c[k] - expected[k]));
    outline.uniform += worst <= kStillLevels;
  }
  return outline;
}

// The set's survey from its frames' outlines (each of `point_count` colours).
BackdropSurvey CombineOutlines(const std::vector<FrameOutline>& outlines, std::size_t point_count) {
  BackdropSurvey survey;
  const std::size_t frame_count = outlines.size();
  // Still: a point's colour within kStillLevels of its median across the frames (with 3 frames
  // or more). The points on all cores in blocks; whole-number counts, summed in block order.
  constexpr std::size_t kBlock = 256;
  const std::size_t blocks = (point_count + kBlock - 1) / kBlock;
  std::vector<std::array<std::array<std::size_t, 256>, 3>> histograms(blocks);
  std::vector<std::size_t> still_in(blocks, 0);
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t block) {
    std::array<std::array<std::size_t, 256>, 3>& histogram = histograms[block];
    for (auto& channel : histogram) channel.fill(0);
    std::array<std::vector<std::uint8_t>, 3> across;
    for (auto& v : across) v.resize(frame_count);
    const std::size_t end = std::min(point_count, (block + 1) * kBlock);
    for (std::size_t i = block * kBlock; i < end; ++i) {
      for (std::size_t f = 0; f < frame_count; ++f) {
        const std::array<std::uint8_t, 3>& colour = outlines[f].colours[i];
        for (int k = 0; k < 3; ++k) {
          across[k][f] = colour[k];
          ++histogram[k][colour[k]];
        }
      }
      if (frame_count < 3) continue;
      std::array<int, 3> median{};
      for (int k = 0; k < 3; ++k) median[k] = Median(across[k]);
      for (std::size_t f = 0; f < frame_count; ++f) {
        const std::array<std::uint8_t, 3>& colour = outlines[f].colours[i];
        int worst = 0;
        for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(int(colour[k]) - median[k]));
        still_in[block] += worst <= kStillLevels;
      }
    }
  });
  // The median of every outline colour (Median's: the value at index n / 2 in order).
  const std::size_t samples = point_count * frame_count;
  for (int k = 0; k < 3; ++k) {
    std::size_t below = 0;
    for (int level = 0; level < 256; ++level) {
      for (const auto& histogram : histograms) below += histogram[k][level];
      if (below > samples / 2) {
        survey.bgr[k] = level;
        break;
      }
    }
  }
  std::size_t uniform = 0;
  for (const FrameOutline& outline : outlines) {
    uniform += outline.uniform;
    if (outline.surface) continue;
    for (const std::array<std::uint8_t, 3>& c : outline.colours) {
      double worst = 0.0;
      for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(c[k] - survey.bgr[k]));
      uniform += worst <= kStillLevels;
    }
  }
  std::size_t still = 0;
  for (const std::size_t count : still_in) still += count;
  survey.outline_uniformity = samples == 0 ? 0.0 : double(uniform) / double(samples);
  const double b = survey.bgr[0], g = survey.bgr[1], r = survey.bgr[2];
  survey.luma = 0.299 * r + 0.587 * g + 0.114 * b;
  survey.chroma = std::hypot(0.564 * (b - survey.luma), 0.713 * (r - survey.luma));
  survey.outline_stillness =
      frame_count >= 3 && samples > 0 ? double(still) / double(samples) : 0.0;
  survey.kind = survey.chroma >= kColouredChroma ? "coloured"
                : survey.luma < kDarkLuma        ? "dark"
                : survey.luma > kLightLuma       ? "light"
                                                 : "grey";
  return survey;
}

// The method SegmentImageSet uses, and why, from result.survey (see SegmentImageSet).
void PickMethod(const SegmentOptions& options, std::size_t frame_count, SetSegmentation& result) {
  const BackdropSurvey& survey = result.survey;
  result.method = options.method;
  result.reason = "given";
  if (options.method != "auto") return;
  const std::string seen = fmt::format(
      "a {} backdrop (outline median B G R {:.0f} {:.0f} {:.0f}, luma {:.0f}, chroma {:.0f}); "
      "{:.0f} % of the outline keeps its colour across the frames, {:.0f} % is within 12 "
      "levels of a smooth fit to its frame's outline",
      survey.kind, survey.bgr[0], survey.bgr[1], survey.bgr[2], survey.luma, survey.chroma,
      100.0 * survey.outline_stillness, 100.0 * survey.outline_uniformity);
  if (survey.kind == "coloured") {
    result.method = "chroma";
    result.reason = seen + ": a coloured backdrop, keyed out by its chroma";
  } else if (BackdropWorthLearning(survey, frame_count)) {
    result.method = "background";
    result.reason = seen +
                    ": the camera stands still, so the backdrop is learned from the "
                    "sequence (per-pixel median of the frames where graphcut saw no "
                    "object) and the difference refined by a graph cut";
  } else {
    result.method = "graphcut";
    result.reason =
        seen + ": " +
        (survey.outline_stillness >= kStillOutline ? "an even backdrop" : "the camera moves") +
        ", so each frame is cut against the backdrop's colour (graph cut seeded by "
        "the colour distance)";
  }
}

// Each mask's problem (ProblemOf, then FlagSmallMasks).
void JudgeMasks(SetSegmentation& result) {
  result.problems.clear();
  for (const cv::Mat& mask : result.masks) result.problems.push_back(ProblemOf(mask));
  FlagSmallMasks(result.masks, result.problems);
}
}  // namespace

BackdropSurvey SurveyBackdrop(const std::vector<cv::Mat>& frames, std::vector<FrameFacts>* facts) {
  const std::vector<cv::Point> points = OutlinePoints(frames.front().size(), 2);
  std::vector<FrameOutline> outlines(frames.size());
  tbb::parallel_for(std::size_t{0}, frames.size(),
                    [&](std::size_t f) { outlines[f] = SurveyFrame(frames[f], points); });
  if (facts != nullptr) {
    facts->assign(frames.size(), FrameFacts{});
    for (std::size_t f = 0; f < frames.size(); ++f) (*facts)[f].whole_outline = outlines[f].surface;
  }
  return CombineOutlines(outlines, points.size());
}

bool BackdropWorthLearning(const BackdropSurvey& survey, std::size_t frames) {
  return frames >= kMinStillFrames && survey.outline_stillness >= kStillOutline &&
         survey.outline_stillness - survey.outline_uniformity >= kStillGain;
}

cv::Mat LearnBackdrop(const std::vector<cv::Mat>& frames, const std::vector<cv::Mat>& masks,
                      int margin_px, const cv::Scalar& fallback) {
  const cv::Size size = frames.front().size();
  std::vector<cv::Mat> free;
  const cv::Mat kernel =
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * margin_px + 1, 2 * margin_px + 1));
  for (const cv::Mat& mask : masks) {
    cv::Mat grown;
    cv::dilate(mask, grown, kernel);
    free.push_back(grown == 0);
  }
  cv::Mat out(size, CV_8UC3);
  // The rows on all cores, each pixel's median its own.
  tbb::parallel_for(0, size.height, [&](int y) {
    std::array<std::vector<std::uint8_t>, 3> values;
    auto* o = out.ptr<cv::Vec3b>(y);
    for (int x = 0; x < size.width; ++x) {
      for (auto& v : values) v.clear();
      for (std::size_t f = 0; f < frames.size(); ++f) {
        if (!free[f].ptr<std::uint8_t>(y)[x]) continue;
        const cv::Vec3b c = frames[f].ptr<cv::Vec3b>(y)[x];
        for (int k = 0; k < 3; ++k) values[k].push_back(c[k]);
      }
      for (int k = 0; k < 3; ++k) {
        o[x][k] =
            values[k].empty() ? cv::saturate_cast<std::uint8_t>(fallback[k]) : Median(values[k]);
      }
    }
  });
  return out;
}

Expected<SetSegmentation> SegmentImageSet(const std::vector<cv::Mat>& frames,
                                          const SegmentOptions& options,
                                          const std::vector<cv::Mat>* graphcut_masks) {
  if (frames.empty()) return MakeError(ErrorCode::kBadInput, "segmentation: no image");
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].type() != CV_8UC3 || frames[i].size() != frames.front().size()) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("segmentation: image {} is not 8-bit BGR of the set's size", i + 1));
    }
  }
  if (Expected<std::unique_ptr<Segmenter>> check = CreateSegmenter(options); !check) {
    return std::unexpected(check.error());
  }
  SetSegmentation result;
  std::vector<FrameFacts> facts;
  result.survey = SurveyBackdrop(frames, &facts);
  PickMethod(options, frames.size(), result);
  SegmentOptions run = options;
  run.method = result.method;
  Expected<cv::Mat> background = ReadBackground(options, frames.front().size());
  if (!background) return std::unexpected(background.error());
  if (run.method == "background" && background->empty()) {
    // No frame of the empty scene: learn it from graphcut's masks.
    Expected<std::vector<cv::Mat>> rough = std::vector<cv::Mat>();
    if (graphcut_masks != nullptr && graphcut_masks->size() == frames.size()) {
      *rough = *graphcut_masks;
    } else {
      SegmentOptions first = run;
      first.method = "graphcut";
      rough = SegmentAll(frames, first, cv::Mat(), facts);
      if (!rough) return std::unexpected(rough.error());
    }
    *background = LearnBackdrop(frames, *rough, kLearnMarginPx, result.survey.bgr);
    if (options.method == "auto") run.refine = true;
  }
  Expected<std::vector<cv::Mat>> masks = SegmentAll(frames, run, *background, facts);
  if (!masks) return std::unexpected(masks.error());
  result.masks = std::move(*masks);
  JudgeMasks(result);
  return result;
}

// ---- FrameByFrameSegmentation ------------------------------------------------------------------

struct FrameByFrameSegmentation::State {
  // What was found of one frame.
  struct Frame {
    bool added = false;
    bool usable = false;  // 8-bit BGR of the first frame's size
    bool cut = false;     // by graphcut: `mask` is its mask or error
    FrameOutline outline;
    Expected<cv::Mat> mask = cv::Mat();
  };
  SegmentOptions options;
  std::unique_ptr<Segmenter> graphcut;  // null: no frame is cut as it comes
  std::mutex mutex;                     // guards frames and size
  std::vector<Frame> frames;
  std::optional<cv::Size> size;
};

FrameByFrameSegmentation::FrameByFrameSegmentation() = default;
FrameByFrameSegmentation::~FrameByFrameSegmentation() = default;
FrameByFrameSegmentation::FrameByFrameSegmentation(FrameByFrameSegmentation&&) noexcept = default;
FrameByFrameSegmentation& FrameByFrameSegmentation::operator=(FrameByFrameSegmentation&&) noexcept =
    default;

Expected<FrameByFrameSegmentation> FrameByFrameSegmentation::Create(const SegmentOptions& options) {
  if (Expected<std::unique_ptr<Segmenter>> check = CreateSegmenter(options); !check) {
    return std::unexpected(check.error());
  }
  FrameByFrameSegmentation made;
  made.state_ = std::make_unique<State>();
  made.state_->options = options;
  // graphcut's masks are the set's when it is asked for, and when auto picks it; auto learns the
  // backdrop from them when it picks background. A background file changes both.
  if ((options.method == "graphcut" || options.method == "auto") &&
      options.background_file.empty()) {
    SegmentOptions graphcut = options;
    graphcut.method = "graphcut";
    Expected<std::unique_ptr<Segmenter>> segmenter = CreateSegmenter(graphcut);
    if (!segmenter) return std::unexpected(segmenter.error());
    made.state_->graphcut = std::move(*segmenter);
  }
  return made;
}

cv::Mat FrameByFrameSegmentation::Add(std::size_t index, const cv::Mat& frame) {
  State::Frame found;
  found.added = true;
  {
    const std::lock_guard lock(state_->mutex);
    if (!state_->size) state_->size = frame.size();
    found.usable = frame.type() == CV_8UC3 && frame.size() == *state_->size;
  }
  bool final = false;
  // Without graphcut the set is segmented by SegmentImageSet, which surveys it itself.
  if (found.usable && state_->graphcut) {
    found.outline = SurveyFrame(frame, OutlinePoints(frame.size(), 2));
    // For auto, what the frame's own outline says of the set's method: a coloured backdrop
    // (chroma: not cut here), or an uneven one (likely learned: cut, as auto learns it from
    // graphcut's masks, but kept whole for the learning).
    found.cut = true;
    final = true;
    if (state_->options.method == "auto") {
      const BackdropSurvey alone = CombineOutlines({found.outline}, found.outline.colours.size());
      found.cut = alone.kind != "coloured";
      final = found.cut && alone.outline_uniformity >= kLikelyEvenShare;
    }
    if (found.cut) {
      FrameFacts facts;
      facts.whole_outline = found.outline.surface;
      found.mask = state_->graphcut->SegmentWithFacts(frame, cv::Mat(), facts);
    }
  }
  cv::Mat mask = final && found.mask ? *found.mask : cv::Mat();
  const std::lock_guard lock(state_->mutex);
  if (state_->frames.size() <= index) state_->frames.resize(index + 1);
  state_->frames[index] = std::move(found);
  return mask;
}

Expected<std::optional<SetSegmentation>> FrameByFrameSegmentation::Finish() {
  const std::lock_guard lock(state_->mutex);
  std::vector<State::Frame>& frames = state_->frames;
  const bool all = !frames.empty() && std::all_of(frames.begin(), frames.end(), [](const auto& f) {
    return f.added && f.usable;
  });
  if (!all || !state_->graphcut) return std::nullopt;
  std::vector<FrameOutline> outlines;
  outlines.reserve(frames.size());
  for (State::Frame& frame : frames) outlines.push_back(std::move(frame.outline));
  SetSegmentation result;
  result.survey = CombineOutlines(outlines, outlines.front().colours.size());
  PickMethod(state_->options, frames.size(), result);
  const bool cut = std::all_of(frames.begin(), frames.end(), [](const auto& f) { return f.cut; });
  if (result.method != "graphcut" || !cut) {
    // Not the set's masks; those SegmentImageSet learns the backdrop from, when all were cut.
    if (cut && std::all_of(frames.begin(), frames.end(), [](const auto& f) { return f.mask; })) {
      for (State::Frame& frame : frames) masks_.push_back(*frame.mask);
    }
    return std::nullopt;
  }
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (!frames[i].mask) {
      // As SegmentAll says it.
      return std::unexpected(WithContext(frames[i].mask.error(), fmt::format("image {}", i + 1)));
    }
    result.masks.push_back(*frames[i].mask);
  }
  JudgeMasks(result);
  return result;
}

Expected<StopBackdropLearner> StopBackdropLearner::Create(const SegmentOptions& options) {
  if (options.method != "background" && options.method != "auto") {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("segmentation: the backdrop is learned for method \"background\" "
                                 "or \"auto\", not \"{}\"",
                                 options.method));
  }
  // auto, per frame without a background: chroma on a coloured backdrop, else graphcut.
  SegmentOptions rough = options;
  rough.method = options.method == "auto" ? "auto" : "graphcut";
  SegmentOptions learned = options;
  learned.method = "background";
  learned.refine = options.refine || options.method == "auto";
  Expected<std::unique_ptr<Segmenter>> rough_segmenter = CreateSegmenter(rough);
  if (!rough_segmenter) return std::unexpected(rough_segmenter.error());
  Expected<std::unique_ptr<Segmenter>> learned_segmenter = CreateSegmenter(learned);
  if (!learned_segmenter) return std::unexpected(learned_segmenter.error());
  StopBackdropLearner learner;
  learner.always_ = options.method == "background";
  learner.rough_ = std::move(*rough_segmenter);
  learner.learned_ = std::move(*learned_segmenter);
  learner.method_ = rough.method;
  learner.reason_ = fmt::format(
      "no frame of the empty scene: the first {} stops are cut by {} and the backdrop "
      "learned from them{}",
      kLearnStops, rough.method == "auto" ? "graphcut (chroma on a coloured backdrop)" : "graphcut",
      learner.always_ ? "" : " if the camera stands still over an uneven backdrop");
  return learner;
}

Expected<cv::Mat> StopBackdropLearner::Segment(const cv::Mat& frame) const {
  return backdrop_.empty() ? rough_->Segment(frame, cv::Mat())
                           : learned_->Segment(frame, backdrop_);
}

bool StopBackdropLearner::Add(const cv::Mat& frame, const cv::Mat& mask) {
  if (decided_ || frame.type() != CV_8UC3 || cv::countNonZero(mask) == 0) return false;
  if (!frames_.empty() && frame.size() != frames_.front().size()) return false;
  frames_.push_back(frame.clone());
  masks_.push_back(mask.clone());
  if (frames_.size() < static_cast<std::size_t>(kLearnStops)) return false;
  decided_ = true;
  const BackdropSurvey survey = SurveyBackdrop(frames_);
  const std::string seen = fmt::format(
      "{} stops: a {} backdrop, {:.0f} % of the outline keeps its colour, {:.0f} % is within 12 "
      "levels of a smooth fit to its frame's outline",
      frames_.size(), survey.kind, 100.0 * survey.outline_stillness,
      100.0 * survey.outline_uniformity);
  const bool learn = always_ || BackdropWorthLearning(survey, frames_.size());
  if (learn) {
    backdrop_ = LearnBackdrop(frames_, masks_, kLearnMarginPx, survey.bgr);
    method_ = "background";
    reason_ = seen +
              ": the backdrop learned from them (per-pixel median where graphcut saw no "
              "object); the later stops are cut against it";
  } else {
    reason_ = seen + ": an even backdrop or a moving camera, so every stop is cut by its colour";
  }
  frames_.clear();
  masks_.clear();
  return learn;
}

}  // namespace revolve::capture
