#include "station/commands/set_masks.h"

#include <algorithm>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <ostream>
#include <system_error>
#include <thread>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/atomic_file.h"
#include "base/log.h"
#include "base/mask_rect.h"
#include "base/png_encode.h"
#include "capture/segment/set_segmentation.h"
#include "config/config.h"
#include "reconstruct/hull/silhouette_consensus.h"
#include "reconstruct/image_set.h"
#include "reconstruct/parallel.h"
#include "station/contact_sheet.h"

namespace revolve::station {
namespace {

constexpr double kMinConsensus = 0.85;
constexpr double kConsensusMargin = 0.15;

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2),
                   values.end());
  return values[values.size() / 2];
}

}  // namespace

Expected<capture::SegmentOptions> ImagesSegmentOptions(
    const std::optional<std::filesystem::path>& config, const std::string& method) {
  capture::SegmentOptions options;
  options.method = "auto";
  if (config) {
    Expected<config::Document> document = config::LoadFile(*config);
    if (!document) return std::unexpected(document.error());
    const config::Section root = config::Section::Root(*document);
    Expected<config::Section> section = root.Child("segment");
    if (!section) return std::unexpected(section.error());
    const bool names_method = section->Has("method");
    Expected<capture::SegmentOptions> parsed = capture::ParseSegmentOptions(*section);
    if (!parsed) return std::unexpected(parsed.error());
    options = *parsed;
    if (!names_method) options.method = "auto";
  }
  if (!method.empty()) options.method = method;
  if (Expected<std::unique_ptr<capture::Segmenter>> ok = capture::CreateSegmenter(options); !ok) {
    return std::unexpected(Error{
        ErrorCode::kBadInput, method.empty()
                                  ? ok.error().message
                                  : fmt::format("--segment {}: {}", method, ok.error().message)});
  }
  return options;
}

Expected<SetMasks> SegmentPhotos(const std::vector<cv::Mat>& photos,
                                 const capture::SegmentOptions& options, std::ostream& out,
                                 const std::vector<cv::Mat>* graphcut_masks) {
  Expected<capture::SetSegmentation> segmented =
      capture::SegmentImageSet(photos, options, graphcut_masks);
  if (!segmented) return std::unexpected(segmented.error());
  return DescribeSegmentation(std::move(*segmented), options, out);
}

SetMasks DescribeSegmentation(capture::SetSegmentation segmented,
                              const capture::SegmentOptions& options, std::ostream& out) {
  SetMasks result;
  result.masks = std::move(segmented.masks);
  result.problems = std::move(segmented.problems);
  const capture::BackdropSurvey& survey = segmented.survey;
  out << fmt::format("segmentation: {} ({})\n", segmented.method,
                     options.method == "auto" ? segmented.reason : "as configured");
  Logger("station")->info("reconstruct --images: segmentation {}: {}", segmented.method,
                          segmented.reason);
  result.report = {{"method", segmented.method},
                   {"requested", options.method},
                   {"reason", segmented.reason},
                   {"backdrop",
                    {{"kind", survey.kind},
                     {"bgr", {survey.bgr[0], survey.bgr[1], survey.bgr[2]}},
                     {"luma", survey.luma},
                     {"chroma", survey.chroma},
                     {"outline_stillness", survey.outline_stillness},
                     {"outline_uniformity", survey.outline_uniformity}}}};
  return result;
}

Expected<void> WriteMasks(const std::filesystem::path& out_dir,
                          const std::vector<std::string>& names,
                          const std::vector<cv::Mat>& thumbnails, const std::vector<cv::Mat>& masks,
                          cv::Size size, const std::vector<cv::Point>& mask_origins,
                          const std::vector<std::string>& problems) {
  const std::filesystem::path dir = out_dir / "masks";
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    return MakeError(ErrorCode::kIo,
                     fmt::format("{}: cannot create the folder: {}", dir.string(), ec.message()));
  }
  const std::size_t count = masks.size();
  const auto path_of = [&](std::size_t i) {
    return dir / (std::filesystem::path(names[i]).stem().string() + ".png");
  };
  // The masks' PNGs and tiles on all cores (reconstruct/parallel.h), each in its slot. Their
  // files are written on a thread of its own as the PNGs come, each synced (a pool thread waiting
  // for the disk would leave its core idle while the model is carved), then put in place together
  // with one sync of the folder, once all are written. The first error in image order is
  // returned; no temporary file is left.
  std::vector<cv::Mat> tiles(count);
  std::vector<Expected<std::string>> encoded(count, std::string());
  std::vector<Expected<void>> written(count);
  std::vector<std::unique_ptr<AtomicFile>> files(count);
  std::mutex mutex;
  std::condition_variable changed;
  std::vector<char> ready(count, 0);
  const auto write_all = [&] {
    for (std::size_t i = 0; i < count; ++i) {
      {
        std::unique_lock lock(mutex);
        changed.wait(lock, [&] { return ready[i] != 0; });
      }
      if (!encoded[i]) {
        written[i] = MakeError(encoded[i].error().code, fmt::format("{}: {}", path_of(i).string(),
                                                                    encoded[i].error().message));
        continue;
      }
      auto file = std::make_unique<AtomicFile>(path_of(i));
      written[i] = file->Open();
      if (!written[i]) continue;
      file->Append(*encoded[i]);
      written[i] = file->Sync();
      encoded[i] = std::string();
      files[i] = std::move(file);
    }
  };
  bool written_here = false;
  {
    std::jthread writer;
    try {
      writer = std::jthread(write_all);
    } catch (const std::system_error&) {
      written_here = true;  // no thread to be had: the files are written once all are encoded
    }
    const auto mark = [&](std::size_t i) {
      {
        const std::lock_guard lock(mutex);
        ready[i] = 1;
      }
      changed.notify_all();
    };
    try {
      reconstruct::ParallelFor(0, count, [&](std::size_t i) {
        const cv::Mat mask = masks[i].empty() ? cv::Mat::zeros(size, CV_8UC1)
                             : mask_origins.empty()
                                 ? masks[i]
                                 : reconstruct::WholeFromWindow(masks[i], mask_origins[i], size);
        encoded[i] = EncodePng(mask);
        mark(i);
        if (i < thumbnails.size() && !thumbnails[i].empty()) {
          tiles[i] = ContactSheetOutline(thumbnails[i], mask);
        } else {
          // The mask's thumbnail in grey, then in colour: the pixels of shrinking it in colour
          // (each channel alike), for a third of the work; only its window's part shrunk where that
          // is exact.
          const cv::Rect content = masks[i].empty() || mask_origins.empty()
                                       ? cv::Rect(cv::Point(), mask.size())
                                       : cv::Rect(mask_origins[i], masks[i].size());
          cv::Mat shown;
          cv::cvtColor(ContactSheetThumbnail(mask, content), shown, cv::COLOR_GRAY2BGR);
          tiles[i] = ContactSheetOutline(shown, mask);
        }
        // (An empty mask keeps its red border.)
        if (i < problems.size() && !problems[i].empty() && cv::countNonZero(mask) > 0) {
          tiles[i] = MarkedLeftOut(tiles[i]);
        }
      });
    } catch (...) {
      // Every mask marked done, so that the writer returns before this goes on.
      for (std::size_t i = 0; i < count; ++i) mark(i);
      throw;
    }
  }
  if (written_here) write_all();
  for (const Expected<void>& w : written) {
    if (!w) return w;
  }
  for (const std::unique_ptr<AtomicFile>& file : files) {
    REVOLVE_RETURN_IF_ERROR(file->Publish());
  }
  // Makes the renames durable (best effort, as AtomicFile::Commit: the files are in place).
  (void)SyncDirectory(dir);
  return WritePngFile(out_dir / "contact_sheet.png", AssembleContactSheet(tiles));
}

Expected<std::vector<double>> ApplyConsensus(std::vector<cv::Mat>& masks,
                                             const std::vector<View>& views,
                                             std::vector<std::string>& problems,
                                             const Eigen::Vector3d& box_min,
                                             const Eigen::Vector3d& box_max, std::ostream& out,
                                             std::vector<cv::Point>* mask_origins) {
  std::vector<double> agreement(masks.size(), 0.0);
  // Masks that come as windows (FrameWindow(mask, 0) of each) stay windows where not cut.
  const bool came_as_windows = !mask_origins->empty();
  const std::vector<cv::Point> origins = came_as_windows ? *mask_origins : std::vector<cv::Point>();
  if (!came_as_windows) mask_origins->assign(masks.size(), cv::Point());
  // Each mask to its window, on all cores (a cut mask is cut to its window already).
  std::vector<char> windowed(masks.size(), came_as_windows ? 1 : 0);
  const auto to_windows = [&] {
    reconstruct::ParallelFor(0, masks.size(), [&](std::size_t i) {
      if (windowed[i]) return;
      const cv::Rect window = reconstruct::FrameWindow(masks[i], 0);
      masks[i] = masks[i](window).clone();
      (*mask_origins)[i] = window.tl();
    });
  };
  std::vector<std::size_t> usable;
  std::vector<cv::Mat> usable_masks;
  std::vector<View> usable_views;
  std::vector<cv::Point> usable_origins;  // empty: whole masks
  for (std::size_t i = 0; i < masks.size(); ++i) {
    if (!problems[i].empty()) continue;
    usable.push_back(i);
    usable_masks.push_back(masks[i]);
    usable_views.push_back(views[i]);
    if (came_as_windows) usable_origins.push_back(origins[i]);
  }
  if (usable.size() < 3) {
    to_windows();
    return agreement;
  }
  Expected<reconstruct::SilhouetteConsensus> consensus = reconstruct::ConsensusOfSilhouettes(
      usable_masks, usable_views, box_min, box_max, {}, usable_origins);
  if (!consensus) return std::unexpected(consensus.error());
  // The originals are held once from here (masks): each cut mask replaces its original.
  usable_masks.clear();
  const double median = Median(consensus->agreement);
  for (std::size_t k = 0; k < usable.size(); ++k) {
    const std::size_t i = usable[k];
    agreement[i] = consensus->agreement[k];
    if (agreement[i] < kMinConsensus && agreement[i] < median - kConsensusMargin) {
      problems[i] = fmt::format(
          "its mask disagrees with the hull of the other views (IoU "
          "{:.3f}, median {:.3f})",
          agreement[i], median);
      continue;
    }
    // The cut mask's own window: its silhouette's rectangle within the cut's (FrameWindow of
    // the whole cut mask, an empty one's whole image).
    const cv::Mat& cut = consensus->masks[k];
    const cv::Rect tight = cut.empty() ? cv::Rect() : MaskRect(cut);
    if (tight.empty()) {
      masks[i] = cv::Mat::zeros(consensus->size[k], CV_8UC1);
      (*mask_origins)[i] = cv::Point();
    } else {
      masks[i] = cut(tight).clone();
      (*mask_origins)[i] = consensus->cut_roi[k].tl() + tight.tl();
    }
    windowed[i] = 1;
    consensus->masks[k].release();
  }
  to_windows();
  out << fmt::format("silhouette consensus: median agreement {:.3f} over {} views\n", median,
                     usable.size());
  return agreement;
}

nlohmann::json JudgeViews(const std::vector<std::string>& names, const std::vector<cv::Mat>& masks,
                          const std::vector<double>& iou, const std::vector<std::string>& problems,
                          double min_iou, std::ostream& out) {
  std::vector<double> used;
  for (std::size_t i = 0; i < iou.size(); ++i) {
    if (problems[i].empty()) used.push_back(iou[i]);
  }
  const double median = Median(used);
  nlohmann::json views = nlohmann::json::array();
  for (std::size_t i = 0; i < names.size(); ++i) {
    nlohmann::json view = {
        {"image", names[i]}, {"mask_area_px", cv::countNonZero(masks[i])}, {"hull_iou", iou[i]}};
    const bool disagrees = problems[i].empty() && (iou[i] < min_iou || iou[i] < median - 0.05);
    view["disagrees"] = disagrees || !problems[i].empty();
    if (!problems[i].empty()) {
      view["left_out"] = problems[i];
      out << fmt::format("warning: {}: left out of the carving: {}\n", names[i], problems[i]);
    } else if (disagrees) {
      out << fmt::format(
          "warning: {}: its mask disagrees with the model the other views carve "
          "(IoU {:.3f}, median {:.3f}); check masks/{}.png\n",
          names[i], iou[i], median, std::filesystem::path(names[i]).stem().string());
    }
    views.push_back(std::move(view));
  }
  return views;
}

}  // namespace revolve::station
