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
};

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

// The trimap as GrabCut's labels (cv::GC_BGD, GC_FGD, GC_PR_BGD, GC_PR_FGD), CV_8UC1 of the
// score's size: score > object eroded by 2 px: GC_FGD; <= backdrop eroded by 2 px, or on the
// border ring and not above object: GC_BGD; above 30 % of the way from backdrop to object:
// GC_PR_FGD; else GC_PR_BGD.
// `roi` (CV_8UC1, may be empty = everything): pixels outside are GC_BGD.
cv::Mat TrimapFromScore(const cv::Mat& score, const ScoreLevels& levels, const cv::Mat& roi,
                        const GraphCutOptions& options);

// The refined mask (CV_8UC1, 0/255) of `bgr` (CV_8UC3) from `trimap` (TrimapFromScore): the colour
// cut (CutByColour) on the reduced copy, the result scaled up, and in a band of the scale's width
// around its edge each pixel decided by `score` against the mean of the local object and backdrop
// scores (the edge at half contrast). When the graph cut cannot run (no object or no backdrop
// seed), the trimap's object labels (GC_FGD, GC_PR_FGD) are returned.
cv::Mat RefineWithGraphCut(const cv::Mat& bgr, const cv::Mat& score, const cv::Mat& trimap,
                           const GraphCutOptions& options);

// Where the edge of `mask` (CV_8UC1, 0/255) lies in `score` (CV_8UC1): for each pixel within
// `radius_px` of the edge, the level 35 % of the way from the mean score of the backdrop pixels
// nearby (outside the mask by more than radius_px) to that of the object pixels nearby (inside by
// more than radius_px), in a window of 4 radius_px + 3; -1 elsewhere or where one side has no
// pixel in the window. CV_32FC1 of the mask's size.
cv::Mat EdgeLevels(const cv::Mat& mask, const cv::Mat& score, int radius_px);

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
