// The contact sheet: every stop's frame with its silhouette outlined, on one PNG, so a person
// sees at a glance what the station saw.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace revolve::station {

// A thumbnail (at most 192 px wide: the frame shrunk by a whole factor, 1280 px to 183, 720 to
// 180) of `frame` (CV_8UC3) with the outline of `mask` (CV_8UC1, same size) drawn in green; an
// empty mask is marked with a red border.
cv::Mat ContactSheetTile(const cv::Mat& frame, const cv::Mat& mask);

// ContactSheetTile in two steps, for a caller that drops the frame before the mask is final:
// the frame's thumbnail, then the mask (the frame's size) outlined on a copy of it.
// ContactSheetOutline(ContactSheetThumbnail(frame), mask) == ContactSheetTile(frame, mask).
// A grey frame's thumbnail is grey, and in colour the thumbnail of its colour copy.
cv::Mat ContactSheetThumbnail(const cv::Mat& frame);
// The same thumbnail of a frame that is zero outside `content` (a silhouette within its
// rectangle), made by shrinking only the content's neighbourhood (the factor is whole: each
// thumbnail pixel averages its own frame pixels): the same pixels, a fifth of the work for a
// typical silhouette. Where that does not hold, ContactSheetThumbnail(frame).
cv::Mat ContactSheetThumbnail(const cv::Mat& frame, const cv::Rect& content);
cv::Mat ContactSheetOutline(const cv::Mat& thumbnail, const cv::Mat& mask);

// `tile` with an amber border (3 px): its view was left out of the carving (its mask disagrees
// with the other views', or looks wrong).
cv::Mat MarkedLeftOut(cv::Mat tile);

// Tiles in rows of up to 6, each labelled with its stop number. An empty list gives a small
// black image.
cv::Mat AssembleContactSheet(const std::vector<cv::Mat>& tiles);

}  // namespace revolve::station
