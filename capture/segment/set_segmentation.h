// Segmentation of a whole set of photos of one object (`revolve reconstruct --images`): the
// method picked for the set (auto), the backdrop learned from the sequence where the camera
// stands still, and a reason for every view whose mask looks wrong.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "capture/segment/backdrop_surface.h"
#include "capture/segmenter.h"

namespace revolve::capture {

// What the frames show behind the object, from their outlines (the one-pixel ring of each frame,
// the object assumed to cover less than half of it).
struct BackdropSurvey {
  cv::Scalar bgr;       // median outline colour over all frames
  double luma = 0.0;    // its luma, 0..255
  double chroma = 0.0;  // its chroma |Cb, Cr| (8-bit units)
  // Share of the outline pixels that keep their colour (within 12 levels of their median across
  // the frames) in the median frame: near 1 when the camera stands still and the backdrop stays
  // (a turntable), low when the camera moves (a gantry, a hand-held camera).
  double outline_stillness = 0.0;
  // Share of the outline samples within 12 levels of the smooth surface fitted to their frame's
  // outline (BackdropSurface; the median colour where none fits): near 1 on an even backdrop,
  // also lit from one side or vignetted, where learning it per pixel gains nothing (graphcut cuts
  // against the surface).
  double outline_uniformity = 0.0;
  std::string kind;  // "dark" (luma < 80), "light" (> 170), "grey", or "coloured"
};

// Contract: at least one frame; all CV_8UC3 of one size. `facts` (may be null): what it found
// of each frame, for Segmenter::SegmentWithFacts (resized to the frames' count).
BackdropSurvey SurveyBackdrop(const std::vector<cv::Mat>& frames,
                              std::vector<FrameFacts>* facts = nullptr);

// Whether a backdrop is worth learning per pixel: a still camera (outline_stillness >= 0.9) over
// an uneven backdrop (stillness at least 0.1 above outline_uniformity), from 4 frames or more.
bool BackdropWorthLearning(const BackdropSurvey& survey, std::size_t frames);

// The backdrop learned from the sequence: per pixel, the median colour of the frames whose
// `masks` (CV_8UC1, non-zero = object, dilated by `margin_px`) leave the pixel uncovered; pixels
// covered in every frame take `fallback`. Contract: frames CV_8UC3, masks CV_8UC1, same sizes.
cv::Mat LearnBackdrop(const std::vector<cv::Mat>& frames, const std::vector<cv::Mat>& masks,
                      int margin_px, const cv::Scalar& fallback);

struct SetSegmentation {
  std::string method;  // the method that made the masks (never "auto")
  std::string reason;  // why it was picked (auto), or "given"
  BackdropSurvey survey;
  std::vector<cv::Mat> masks;         // one per frame, CV_8UC1 0/255
  std::vector<std::string> problems;  // one per frame: empty, or what is wrong with its mask
};

// Segments every frame. method = auto picks, from the survey: a coloured backdrop: chroma; a
// still camera over an uneven backdrop (outline_stillness >= 0.9 and at least 0.1 above
// outline_uniformity, at least 4 frames): graphcut, then the backdrop
// learned from those masks (LearnBackdrop) and background with refinement; otherwise graphcut.
// Any other method runs as configured (background without background_file learns the backdrop
// as auto does). A frame's problem: no object found; the object covers over 60 % of the frame;
// the object touches the frame's edge on more than half of its outline; the mask is under 20 %
// of the median area of the set's other masks (3 or more). `graphcut_masks` (may be null): the
// frames' masks by graphcut when they were made already (FrameByFrameSegmentation), for auto to
// learn the backdrop from. Errors: bad_input for invalid options or frames, or background_file
// unreadable or of another size (naming it).
Expected<SetSegmentation> SegmentImageSet(const std::vector<cv::Mat>& frames,
                                          const SegmentOptions& options,
                                          const std::vector<cv::Mat>* graphcut_masks = nullptr);

// SegmentImageSet's work done frame by frame as the frames come, so that a caller need not hold
// the set's frames whole (`revolve reconstruct --images` cuts each photo to its object's window
// as soon as it is decoded): each frame's part of the survey, and its mask by graphcut, which is
// the set's mask whenever SegmentImageSet would use graphcut (asked for, or picked by auto on an
// even backdrop or with a moving camera) and the rough mask auto learns a still camera's backdrop
// from. The result is SegmentImageSet's to the bit.
class FrameByFrameSegmentation {
 public:
  // Errors: bad_input for invalid options (as SegmentImageSet).
  static Expected<FrameByFrameSegmentation> Create(const SegmentOptions& options);
  FrameByFrameSegmentation(FrameByFrameSegmentation&&) noexcept;
  FrameByFrameSegmentation& operator=(FrameByFrameSegmentation&&) noexcept;
  ~FrameByFrameSegmentation();

  // Frame `index` of the set (CV_8UC3, the first frame's size): surveyed and cut by graphcut,
  // unless the options rule graphcut out (another method, or a background_file: nothing is done)
  // or, for auto, its own outline shows a coloured backdrop (surveyed only). Returns the mask
  // (CV_8UC1 0/255, the frame's size) when the set will most likely keep it, so that the caller may
  // let go of all but the object's window now: graphcut asked for, or auto and an outline within 12
  // levels of its smooth fit for 95 % of it. Otherwise an empty Mat: keep the frame whole for
  // Finish's nullopt. Thread-safe for distinct indexes; each index from 0 to the set's count once,
  // in any order.
  cv::Mat Add(std::size_t index, const cv::Mat& frame);

  // After every frame was added: SegmentImageSet(frames, options) when graphcut's masks are the
  // set's; nullopt when they are not, or a frame was missing or not of the set's kind or size:
  // the caller then gives the frames to SegmentImageSet, with graphcut_masks(). Errors: a
  // frame's, as SegmentImageSet's.
  Expected<std::optional<SetSegmentation>> Finish();

  // After Finish gave nullopt: every frame's graphcut mask, or none when not all were cut.
  const std::vector<cv::Mat>& graphcut_masks() const { return masks_; }

 private:
  struct State;
  FrameByFrameSegmentation();

  std::unique_ptr<State> state_;
  std::vector<cv::Mat> masks_;
};

// A scan's stops segmented as they arrive, with the backdrop learned from the first ones (a live
// scan has no sequence to survey beforehand). Used without a frame of the empty scene, for
// method "background" (the camera cannot capture the empty scene) and "auto":
// - the first kLearnStops stops kept with an object are cut by graphcut (auto: chroma on a
//   coloured backdrop), against the backdrop's colour per frame;
// - then the backdrop is learned from them (LearnBackdrop), for "auto" only when their survey
//   finds a still camera over an uneven backdrop (BackdropWorthLearning), and the later stops are
//   cut against it: "background", refined by the graph cut for "auto" or refine = true.
// Pixels the object covers in all those stops take the outline's median colour.
class StopBackdropLearner {
 public:
  static constexpr int kLearnStops = 4;

  // Errors: bad_input for a method other than background or auto, or invalid options.
  static Expected<StopBackdropLearner> Create(const SegmentOptions& options);

  // The frame's mask (CV_8UC1 0/255) by the current method. Errors: as Segmenter::Segment.
  Expected<cv::Mat> Segment(const cv::Mat& frame) const;

  // A kept stop (after the quality gates): learned from until kLearnStops are in. Returns true
  // when the backdrop has just been learned (the method changes to background). Frames that are
  // not 8-bit BGR or not of the first frame's size are not learned from.
  bool Add(const cv::Mat& frame, const cv::Mat& mask);

  const std::string& method() const { return method_; }  // graphcut/auto, then background
  const std::string& reason() const { return reason_; }  // why, for the log and report
  const cv::Mat& backdrop() const { return backdrop_; }  // empty until learned

 private:
  StopBackdropLearner() = default;

  bool always_ = false;  // method background: learn whatever the survey says
  bool decided_ = false;
  std::unique_ptr<Segmenter> rough_;
  std::unique_ptr<Segmenter> learned_;
  std::vector<cv::Mat> frames_;
  std::vector<cv::Mat> masks_;
  cv::Mat backdrop_;
  std::string method_;
  std::string reason_;
};

}  // namespace revolve::capture
