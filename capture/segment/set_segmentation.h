// Segmentation of a whole set of photos of one object (`revolve reconstruct --images`): the
// method picked for the set (auto), the backdrop learned from the sequence where the camera
// stands still, and a reason for every view whose mask looks wrong.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "base/error.h"
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
  // Share of the outline samples within 12 levels of the median outline colour: near 1 on an
  // even backdrop, where learning it per pixel gains nothing.
  double outline_uniformity = 0.0;
  std::string kind;  // "dark" (luma < 80), "light" (> 170), "grey", or "coloured"
};

// Contract: at least one frame; all CV_8UC3 of one size.
BackdropSurvey SurveyBackdrop(const std::vector<cv::Mat>& frames);

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
// of the median area of the set's other masks (3 or more). Errors: bad_input for
// invalid options or frames, or background_file unreadable or of another size (naming it).
Expected<SetSegmentation> SegmentImageSet(const std::vector<cv::Mat>& frames,
                                          const SegmentOptions& options);

}  // namespace revolve::capture
