// Graph-cut refinement of a silhouette: a trimap from an "objectness" score (how unlike the
// backdrop each pixel is), a graph cut by colour (capture/segment/colour_cut.h: colour models of
// object and backdrop, a cut along the image's edges) on a reduced copy, and the edge placed
// again at full size.
//
// Why: a threshold cannot tell a dark stand or a dark, uneven cloth from the shadowed parts of an
// object, because their levels overlap; their colours and the image's edges usually differ.
#pragma once

#include <opencv2/core.hpp>

namespace revolve::capture {

// Levels of a score image (CV_8UC1, higher = less like the backdrop) that seed the graph cut.
struct ScoreLevels {
  double object = 0.0;    // above: object for sure (the score's Otsu threshold)
  double backdrop = 0.0;  // at or below: backdrop for sure (the backdrop class's mean)
  // The backdrop's noise ceiling (BackdropNoiseCeiling), or negative when unknown. When it lies
  // below the probable-object level (an even backdrop: black, grey, white), the trimap is a
  // hysteresis instead: backdrop for sure is only what lies within the noise, and everything
  // above it that is connected to the sure object is probably object (the deep shadows on an
  // object over black, far from its lit part).
  double noise = -1.0;
};

// The score as the noise hysteresis reads it: averaged over 5 x 5 pixels, so that the backdrop's
// noise (a fifth of it left) and a dim region of the object (its level kept) stand apart where
// pixel by pixel they overlap (sensor noise of sigma 8 against a deep shadow 20 levels above a
// black backdrop). BackdropNoiseCeiling is measured on it and the trimap's "above the noise" read
// from it.
cv::Mat NoiseScore(const cv::Mat& score);

// The highest score the backdrop's own pixels reach: over the outline of the region of
// interest's bounding rectangle (`roi` CV_8UC1, may be empty = the whole frame), the median
// score plus 5 scaled median absolute deviations (1.4826 MAD, a robust sigma), at least 3 levels
// above the median. The object may cover part of the outline (a stand, a large object): the
// median and the MAD ignore it up to half of the outline.
double BackdropNoiseCeiling(const cv::Mat& score, const cv::Mat& roi);

// Whether the trimap uses the hysteresis (ScoreLevels::noise): a known noise ceiling below the
// probable-object level.
bool UsesNoiseHysteresis(const ScoreLevels& levels);

struct GraphCutOptions {
  // The graph cut runs on a copy whose longer side is at most this (speed: the cut's cost grows
  // with the pixel count); the edge is then placed at full size. 0: full size.
  int max_side_px = 320;
  int iterations = 3;  // of the colour cut (capture/segment/colour_cut.h)
  // Pixels of the image's outline ring (this fraction of the shorter side) that are not
  // object for sure seed the backdrop: whatever touches the frame's edge below the object level
  // (a stand, a cloth) teaches the backdrop model its colour.
  double border_fraction = 0.02;
  // Undecided pixels farther than this fraction of the reduced copy's longer side from every
  // sure object pixel are backdrop (the object is what its sure core reaches; 24 px at 320).
  double reach_fraction = 0.075;
};

struct Trimap {
  // GrabCut's labels (cv::GC_BGD, GC_FGD, GC_PR_BGD, GC_PR_FGD), CV_8UC1 of the score's size.
  cv::Mat labels;
  // CV_8UC1 of the same size (may be empty): the GC_PR_FGD pixels the noise hysteresis brought
  // in, which the reach (GraphCutOptions::reach_fraction) never turns into backdrop.
  cv::Mat kept;
};

// The trimap of `bgr` (CV_8UC3) from its score: score > object eroded by 2 px: GC_FGD;
// <= backdrop eroded by 2 px, or on the border ring and not above object: GC_BGD; above 30 % of
// the way from backdrop to object: GC_PR_FGD; else GC_PR_BGD.
// With the noise hysteresis (UsesNoiseHysteresis), "noise" read on NoiseScore(score): GC_BGD is
// <= noise eroded by 2 px (and the border ring); every pixel above noise 8-connected to a GC_FGD
// pixel through pixels above noise is at least GC_PR_FGD and kept from the reach's limit, unless
// its colour is common among the pixels above noise on the border ring (away from the sure object;
// 16 levels a channel on a square-root scale, one level of slack): a stand or a cloth that touches
// the frame's edge, and a fold of it seen between an object's parts, are not brought in; the
// object's own shadows are. `roi` (CV_8UC1, may be empty = everything): pixels outside are GC_BGD.
// `noise_score`: NoiseScore(score) when the caller has it already (empty: made here).
Trimap TrimapFromScore(const cv::Mat& bgr, const cv::Mat& score, const ScoreLevels& levels,
                       const cv::Mat& roi, const GraphCutOptions& options,
                       const cv::Mat& noise_score = cv::Mat());

// The refined mask (CV_8UC1, 0/255) of `bgr` (CV_8UC3) from `trimap` (TrimapFromScore): the colour
// cut (CutByColour) on the reduced copy, the result scaled up, and in a band of the scale's width
// around its edge each pixel decided by `score` against the mean of the local object and backdrop
// scores (the edge at half contrast). When the graph cut cannot run (no object or no backdrop
// seed), the trimap's object labels (GC_FGD, GC_PR_FGD) are returned.
cv::Mat RefineWithGraphCut(const cv::Mat& bgr, const cv::Mat& score, const Trimap& trimap,
                           const GraphCutOptions& options);

// Edge levels over the part of a mask that can hold any: `levels` (CV_32FC1, the part's size)
// are the mask's pixels from `part`'s corner on; no pixel outside `part` has a level (-1 there).
struct EdgeLevelPart {
  cv::Rect part;   // within the mask; empty (and `levels` too) for a mask with no pixel set
  cv::Mat levels;  // CV_32FC1
};

// Where the edge of `mask` (CV_8UC1, 0/255) lies in `score` (CV_8UC1): for each pixel within
// `radius_px` of the edge, the level 35 % of the way from the mean score of the backdrop pixels
// nearby (outside the mask by more than radius_px) to that of the object pixels nearby (inside by
// more than radius_px), in a window of 4 radius_px + 3; -1 elsewhere or where one side has no
// pixel in the window. Held over the rectangle of the mask's pixels widened by 3 radius_px + 3
// (the band and its windows), not over the whole mask.
EdgeLevelPart EdgeLevels(const cv::Mat& mask, const cv::Mat& score, int radius_px);

// `mask` with every pixel that has an edge level (EdgeLevels) decided again: object when its
// score reaches the level. The object's rim (pixels it partly covers) stays in, as a carved
// hull needs.
cv::Mat PlaceEdge(const cv::Mat& mask, const cv::Mat& score, int radius_px);

// Fills the holes of `mask` (background regions not 4-connected to the border) except those
// whose median score is at or below `backdrop_level` and that hold more than `min_open_px`
// pixels: the backdrop seen through the object (a handle, the gaps between columns) stays open,
// a dark shadow on the object is filled.
cv::Mat FillHolesUnlessBackdrop(const cv::Mat& mask, const cv::Mat& score, double backdrop_level,
                                int min_open_px);

}  // namespace revolve::capture
