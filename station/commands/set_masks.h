// The masks of `revolve reconstruct --images`: the photos segmented with capture's segmenter
// (the same code as a scan), saved where a person can check them, and judged view by view
// against the model they made.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "capture/segment/set_segmentation.h"
#include "capture/segmenter.h"

namespace revolve::station {

// The [segment] options of --images: `config` (a TOML file; only its [segment] table is read)
// and `method` (--segment; empty: the file's method, or "auto" when neither names one).
// Errors: the file's (not_found, bad_input naming file:line:column and key), or bad_input for
// an unknown method.
Expected<capture::SegmentOptions> ImagesSegmentOptions(
    const std::optional<std::filesystem::path>& config, const std::string& method);

struct SetMasks {
  std::vector<cv::Mat> masks;         // one per image, CV_8UC1 0/255
  std::vector<std::string> problems;  // one per image: empty, or why its mask is not usable
  nlohmann::json report;              // report.json's "segmentation" section
};

// The masks of a set's segmentation (capture::SegmentImageSet's, or
// FrameByFrameSegmentation's), logging the method and why to `out`. A view with a problem keeps
// its (possibly empty) mask and its reason.
SetMasks DescribeSegmentation(capture::SetSegmentation segmented,
                              const capture::SegmentOptions& options, std::ostream& out);

// Segments `photos` (CV_8UC3, one size) with capture::SegmentImageSet (`graphcut_masks`: see
// there), then DescribeSegmentation.
Expected<SetMasks> SegmentPhotos(const std::vector<cv::Mat>& photos,
                                 const capture::SegmentOptions& options, std::ostream& out,
                                 const std::vector<cv::Mat>* graphcut_masks = nullptr);

// Writes OUT/masks/<stem>.png (one per image, named after `names`' stems) and
// OUT/contact_sheet.png (every image with its mask outlined: `thumbnails` are the photos'
// ContactSheetThumbnail, station/contact_sheet.h; empty, or an empty one, for silhouettes, which
// are shown as they are). `masks` are of `size`, or windows of masks of `size`, mask i's pixels
// from mask_origins[i] on (none set outside; mask_origins empty: whole masks). A view whose
// `problems` entry is not empty was left out of the carving: its tile has an amber border
// (MarkedLeftOut; an empty mask's stays red). Errors: io naming the file.
Expected<void> WriteMasks(const std::filesystem::path& out_dir,
                          const std::vector<std::string>& names,
                          const std::vector<cv::Mat>& thumbnails, const std::vector<cv::Mat>& masks,
                          cv::Size size, const std::vector<cv::Point>& mask_origins = {},
                          const std::vector<std::string>& problems = {});

// Silhouette consensus (reconstruct/hull/silhouette_consensus.h) over the usable views (those
// whose `problems` entry is empty; `views` normalised, the box the carving volume): every usable
// mask is cut to the other views' hull, and a view whose agreement is below 0.85 and 0.15 below
// the median is left out (its problem says why). `masks` come whole (each its view's image,
// *mask_origins empty) or as windows (each FrameWindow(mask, 0) of its whole mask, from
// *mask_origins), and leave as windows: each mask's FrameWindow(mask, 0) (its silhouette's
// rectangle; an empty mask's whole image), its origin into *mask_origins. Returns the per-view
// agreement (0 for views left out before) for report.json; logs to `out`.
Expected<std::vector<double>> ApplyConsensus(std::vector<cv::Mat>& masks,
                                             const std::vector<View>& views,
                                             std::vector<std::string>& problems,
                                             const Eigen::Vector3d& box_min,
                                             const Eigen::Vector3d& box_max, std::ostream& out,
                                             std::vector<cv::Point>* mask_origins);

// Per view: the mask's area (px), the model's reprojection IoU against it, and `disagrees` when
// the IoU is below `min_iou` or 0.05 below the views' median; also the views left out of the
// carving (`problems` non-empty) with their reason. Warns on `out` for each such view.
nlohmann::json JudgeViews(const std::vector<std::string>& names, const std::vector<cv::Mat>& masks,
                          const std::vector<double>& iou, const std::vector<std::string>& problems,
                          double min_iou, std::ostream& out);

}  // namespace revolve::station
