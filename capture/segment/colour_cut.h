// A graph cut of a trimap's undecided pixels by colour (GrabCut's energy, Rother et al. 2004),
// with colour histograms instead of Gaussian mixtures ("GrabCut in One Cut", Tang et al. 2013)
// and a graph over the undecided pixels only.
//
// Why not cv::grabCut: it fits and evaluates two 5-component Gaussian mixtures at every pixel of
// its rectangle and builds the graph over all of them, ~0.6 us a pixel and iteration: 190 ms
// for a 320x240 frame, three times the refinement's budget. Here the sure pixels only feed the
// colour models (one table look-up each) and bound the undecided ones; the cut costs what the
// band around the edge costs.
#pragma once

#include <opencv2/core.hpp>

namespace revolve::capture {

struct ColourCutOptions {
  int iterations = 3;        // colour models learned again from each cut, then cut again
  double smoothness = 50.0;  // weight of a cut between two pixels of equal colour (GrabCut's gamma)
};

// Decides the undecided pixels (cv::GC_PR_FGD, GC_PR_BGD) of `labels` (CV_8UC1, GrabCut's labels,
// in place) from the colours of `bgr` (CV_8UC3, same size): each pixel costs -log of its colour's
// share in the object or backdrop histogram (16 levels a channel on a square-root scale, finer
// in the dark), a cut between 8-neighbours smoothness * exp(-beta |c1 - c2|^2) / distance with
// beta = 1 / (2 mean |c1 - c2|^2). Sure labels (GC_FGD, GC_BGD) stay. Returns false, labels
// untouched, when either class has no pixel at all.
// `object_samples` (CV_8UC1 of the same size, may be empty): pixels whose colours teach the
// object's histogram in every iteration, whatever the last cut made of them, and never the
// backdrop's (what the noise hysteresis brought in: a region the cut gives up cannot teach the
// backdrop model its colours, and the next cut then give up the whole of it).
bool CutByColour(const cv::Mat& bgr, cv::Mat& labels, const ColourCutOptions& options = {},
                 const cv::Mat& object_samples = cv::Mat());

}  // namespace revolve::capture
