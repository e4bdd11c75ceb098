#include "station/commands/reconstruct_images_command.h"

#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <ostream>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "base/atomic_file.h"
#include "base/log.h"
#include "reconstruct/cameras/camera_file.h"
#include "reconstruct/cameras/views.h"
#include "reconstruct/image_set.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/meridian/meridian.h"
#include "reconstruct/metrics/metrics.h"
#include "reconstruct/metrics/reprojection.h"
#include "reconstruct/parallel.h"
#include "reconstruct/reconstructor.h"
#include "station/commands/scan_command.h"
#include "station/commands/set_masks.h"
#include "station/contact_sheet.h"
#include "station/report_json.h"
#include "station/timing.h"

namespace revolve::station {
namespace {

using Clock = std::chrono::steady_clock;
namespace rc = revolve::reconstruct;

// A view whose mask reprojects below this IoU against the model is flagged in report.json.
constexpr double kMinAgreeingIoU = 0.9;
// --bbox coordinates beyond this are refused (a million pixels or metres is no turntable).
constexpr double kMaxBoxCoordinate = 1e6;
// The hull keeps each photo's pixels this far around its silhouette's rectangle (less memory);
// a view whose texture may read further (Reconstructor::FrameWindow: coarse voxels, a volume
// partly out of view) reads its photo again.
constexpr int kFrameMarginPx = 24;

// An option out of range: the message, or empty when the options are usable.
std::string CheckOptions(const ReconstructImagesOptions& options) {
  if (options.images.empty()) return "--images DIR is required";
  if (options.out.empty()) return "--out DIR is required";
  if (options.method != "hull" && options.method != "meridian") {
    return fmt::format("--method {}: expected hull or meridian", options.method);
  }
  if (options.resolution < 16 || options.resolution > 1024) {
    return fmt::format("--resolution {}: expected 16..1024", options.resolution);
  }
  if (!(options.step_deg > 0.0 && options.step_deg <= 360.0)) {
    return fmt::format("--step-deg {}: expected an angle in (0, 360]", options.step_deg);
  }
  if (options.threshold < 0 || options.threshold > 254) {
    return fmt::format("--threshold {}: expected 0..254", options.threshold);
  }
  if (options.row_step_px < 1 || options.row_step_px > 256) {
    return fmt::format("--row-step {}: expected 1..256", options.row_step_px);
  }
  if (options.formats.empty()) return "--formats: expected at least one format";
  for (const std::string& format : options.formats) {
    if (!rc::IsModelFormat(format)) {
      return fmt::format("--formats: \"{}\" is not one of ply, obj, stl, glb, wrl", format);
    }
  }
  if (!(options.max_image_mp >= 0.01 && options.max_image_mp <= 10000.0)) {
    return fmt::format("--max-image-mp {}: expected 0.01..10000", options.max_image_mp);
  }
  if (options.bbox) {
    const auto& b = *options.bbox;
    if (!std::all_of(b.begin(), b.end(), [](double v) { return std::isfinite(v); })) {
      return "--bbox X0 Y0 Z0 X1 Y1 Z1: expected finite numbers";
    }
    if (!(b[0] < b[3] && b[1] < b[4] && b[2] < b[5])) {
      return "--bbox X0 Y0 Z0 X1 Y1 Z1: expected X0 < X1, Y0 < Y1 and Z0 < Z1";
    }
    // A box a voxel grid cannot span (its size overflows or its cells are astronomical) is a
    // typing error, not a carving volume.
    if (!std::all_of(b.begin(), b.end(),
                     [](double v) { return std::abs(v) <= kMaxBoxCoordinate; })) {
      return fmt::format(
          "--bbox X0 Y0 Z0 X1 Y1 Z1: expected coordinates within +-{:g} (the "
          "cameras file's units, or pixels without one)",
          kMaxBoxCoordinate);
    }
  }
  return {};
}

// One run of `reconstruct --images`: the steps in order, sharing what they found. Each step
// adds its part of report.json and its time.
class ImagesRun {
 public:
  ImagesRun(const ReconstructImagesOptions& options, std::ostream& out)
      : options_(options), out_(out), thesis_mode_(!options.cameras.has_value()) {}

  Expected<nlohmann::json> Run() {
    const Clock::time_point start = Clock::now();
    REVOLVE_RETURN_IF_ERROR(PrepareOutput());
    REVOLVE_RETURN_IF_ERROR(Timed("load_ms", [&] { return Load(); }));
    REVOLVE_RETURN_IF_ERROR(Timed("segment_ms", [&] { return Segment(); }));
    const Expected<void> judged = [&]() -> Expected<void> {
      REVOLVE_RETURN_IF_ERROR(RequireTwoUsable());
      REVOLVE_RETURN_IF_ERROR(Timed("cameras_ms", [&] { return CamerasAndVolume(); }));
      return Timed("consensus_ms", [&] { return Consensus(); });
    }();
    // The masks, for a person to check, once: those the carving uses, or the segmentation's
    // when the run stops before (why it stopped is then told, the masks written).
    if (!judged) {
      REVOLVE_RETURN_IF_ERROR(WriteMasks(options_.out, names_, thumbnails_, masks_, FrameSize(),
                                         mask_origins_, problems_));
      return std::unexpected(judged.error());
    }
    REVOLVE_RETURN_IF_ERROR(WriteMasksWhileReconstructing());
    REVOLVE_RETURN_IF_ERROR(WriteFilesWhileMeasuring());
    Describe();
    times_["total_ms"] = MsSince(start);
    report_["times_ms"] = times_;
    REVOLVE_RETURN_IF_ERROR(WriteReportAndSay());
    return report_;
  }

 private:
  template <typename Step>
  Expected<void> Timed(const char* key, Step&& step) {
    const Clock::time_point t = Clock::now();
    Expected<void> done = step();
    times_[key] = MsSince(t);
    return done;
  }

  // The output folder first (a read-only or unwritable --out is said before any work), but not
  // for a set that is not there: a mistyped --images leaves nothing behind.
  Expected<void> PrepareOutput() {
    if (std::error_code ec; !std::filesystem::is_directory(options_.images, ec)) {
      return MakeError(ErrorCode::kNotFound,
                       fmt::format("{}: no such folder", options_.images.string()));
    }
    return CreateOutputFolder(options_.out / "model");
  }

  Expected<void> Load() {
    legacy_threshold_ = options_.segment == "threshold";
    if (!legacy_threshold_) {
      REVOLVE_ASSIGN_OR_RETURN(segment_options_,
                               ImagesSegmentOptions(options_.config, options_.segment));
      REVOLVE_ASSIGN_OR_RETURN(by_frame_,
                               capture::FrameByFrameSegmentation::Create(*segment_options_));
    }
    rc::ImageSetOptions set_options;
    set_options.max_image_pixels = static_cast<std::int64_t>(options_.max_image_mp * 1e6);
    set_options.pattern = options_.pattern;
    set_options.step_deg = options_.step_deg;
    set_options.segmentation.threshold = options_.threshold;
    set_options.segment_photos = legacy_threshold_;
    // The hull reads only a window of each photo; the meridian method whole photos. The contact
    // sheet's thumbnails are made from the whole photos.
    set_options.frame_margin_px = options_.method == "hull" ? kFrameMarginPx : -1;
    std::mutex thumbnails_mutex;
    set_options.on_photo = [&](std::size_t index, const cv::Mat& photo) {
      cv::Mat thumbnail = ContactSheetThumbnail(photo);
      const std::lock_guard<std::mutex> lock(thumbnails_mutex);
      if (thumbnails_.size() <= index) thumbnails_.resize(index + 1);
      thumbnails_[index] = std::move(thumbnail);
    };
    // Each photo is segmented where it was decoded, and (hull) cut to its window there: the
    // set's photos are not held whole at once.
    if (by_frame_) {
      set_options.segment_photo = [&](std::size_t index, const cv::Mat& photo) {
        return by_frame_->Add(index, photo);
      };
    }
    REVOLVE_ASSIGN_OR_RETURN(set_, rc::LoadImageSet(options_.images, set_options));
    thumbnails_.resize(set_.images.size());
    photos_ = set_.kind == rc::ImageKind::kPhoto;
    out_ << fmt::format("{} {} of {}x{} px from {}\n", set_.images.size(),
                        rc::KindName(set_.kind, true), set_.width_px, set_.height_px,
                        options_.images.string());
    TurnNote();
    if (set_.exif_turned > 0) {
      out_ << fmt::format(
          "  {} of them turned upright as their EXIF orientation says (as a "
          "viewer shows them)\n",
          set_.exif_turned);
    }
    for (rc::SetImage& image : set_.images) {
      names_.push_back(image.file_name);
      masks_.push_back(std::move(image.mask));  // held once: the consensus replaces them
    }
    problems_.assign(masks_.size(), std::string());
    return {};
  }

  // The masks and the contact sheet are written while the model is made, each on all cores
  // (reconstruct/parallel.h): neither reads what the other writes, and Reconstruct releases its
  // references to the frames as it goes, not the copies given to WriteMasks. Each step's time is
  // its own (they overlap).
  Expected<void> WriteMasksWhileReconstructing() {
    Expected<void> written;
    Expected<void> made;
    double masks_ms = 0.0;
    double reconstruct_ms = 0.0;
    rc::ParallelInvoke(
        [&] {
          const Clock::time_point t = Clock::now();
          written = WriteMasks(options_.out, names_, thumbnails_, masks_, FrameSize(),
                               mask_origins_, problems_);
          masks_ms = MsSince(t);
        },
        [&] {
          const Clock::time_point t = Clock::now();
          made = Reconstruct();
          reconstruct_ms = MsSince(t);
        });
    times_["masks_ms"] = masks_ms;
    times_["reconstruct_ms"] = reconstruct_ms;
    if (!written) return written;
    return made;
  }

  // Silhouettes: segmented here (photos), from the masks made as the photos were decoded when
  // they are the set's (FrameByFrameSegmentation), else from the photos read whole again.
  Expected<void> Segment() {
    if (photos_ && !legacy_threshold_) {
      std::optional<capture::SetSegmentation> done;
      REVOLVE_ASSIGN_OR_RETURN(done, by_frame_->Finish());
      SetMasks segmented;
      if (done) {
        segmented = DescribeSegmentation(std::move(*done), *segment_options_, out_);
      } else {
        std::vector<cv::Mat> photos(set_.images.size());
        std::vector<std::optional<Error>> errors(photos.size());
        rc::ParallelFor(0, photos.size(), [&](std::size_t i) {
          Expected<cv::Mat> photo = WholePhoto(i);
          if (photo) {
            photos[i] = std::move(*photo);
          } else {
            errors[i] = photo.error();
          }
        });
        for (const std::optional<Error>& error : errors) {
          if (error) return std::unexpected(*error);
        }
        const std::vector<cv::Mat>& rough = by_frame_->graphcut_masks();
        REVOLVE_ASSIGN_OR_RETURN(segmented, SegmentPhotos(photos, *segment_options_, out_,
                                                          rough.empty() ? nullptr : &rough));
        for (std::size_t i = 0; i < photos.size(); ++i) {
          set_.images[i].image = std::move(photos[i]);
          set_.images[i].image_origin = cv::Point();
        }
      }
      by_frame_.reset();
      if (options_.method == "hull") {
        // Each photo still whole cut to its window now that its mask is known (as Load cuts
        // those it can).
        rc::ParallelFor(0, set_.images.size(), [&](std::size_t i) {
          rc::SetImage& image = set_.images[i];
          if (!IsWhole(image)) return;
          const cv::Rect window = rc::FrameWindow(segmented.masks[i], kFrameMarginPx);
          image.image = image.image(window).clone();
          image.image_origin = window.tl();
        });
      }
      // Each mask held as its window from here on (the whole masks would stay alongside the
      // consensus's own whole copies of them).
      masks_ = std::move(segmented.masks);
      mask_origins_.assign(masks_.size(), cv::Point());
      rc::ParallelFor(0, masks_.size(), [&](std::size_t i) {
        const cv::Rect window = rc::FrameWindow(masks_[i], 0);
        masks_[i] = masks_[i](window).clone();
        mask_origins_[i] = window.tl();
      });
      problems_ = std::move(segmented.problems);
      report_["segmentation"] = segmented.report;
    } else {
      const bool cut_out = set_.kind == rc::ImageKind::kCutOut;
      report_["segmentation"] = {
          {"method", photos_   ? "threshold"
                     : cut_out ? "alpha"
                               : "none (binary silhouettes)"},
          {"reason",
           photos_   ? fmt::format("--segment threshold: any channel above {}", options_.threshold)
           : cut_out ? fmt::format("the photos are cut out: each one's alpha channel is its mask "
                                   "(object where it reaches {} of 255)",
                                   rc::kCutOutMinAlpha)
                     : "the images are silhouettes already"}};
    }
    return {};
  }

  void CollectUsable() {
    usable_.clear();
    for (std::size_t i = 0; i < masks_.size(); ++i) {
      if (problems_[i].empty()) usable_.push_back(i);
    }
  }

  Expected<void> RequireTwoUsable() {
    CollectUsable();
    if (usable_.size() >= 2) return {};
    std::string why;
    for (std::size_t i = 0; i < masks_.size(); ++i) {
      if (!problems_[i].empty()) why += fmt::format("\n  {}: {}", names_[i], problems_[i]);
    }
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{}: only {} of {} images gave a usable silhouette (the masks "
                                 "are in {}):{}",
                                 options_.images.string(), usable_.size(), masks_.size(),
                                 (options_.out / "masks").string(), why));
  }

  // In thesis mode with the angles not in the names: a note when the images do not make one
  // turn at the step (the default 10 degrees for a set of 18 or 72 photos is a likely slip).
  void TurnNote() {
    if (!thesis_mode_ || set_.images.empty() ||
        options_.pattern.find("{angle}") != std::string::npos) {
      return;
    }
    int last = 0;
    for (const rc::SetImage& image : set_.images) last = std::max(last, image.index);
    const double turn_deg = (last + 1) * options_.step_deg;
    if (std::abs(turn_deg - 360.0) < 1e-6) return;
    const std::string note = fmt::format(
        "note: {} images {:g} deg apart (--step-deg) {} {:g} deg; if they make one turn they are "
        "{:g} deg apart: pass --step-deg {:g}",
        last + 1, options_.step_deg, turn_deg < 360.0 ? "cover" : "would turn", turn_deg,
        360.0 / (last + 1), 360.0 / (last + 1));
    Logger("station")->warn("reconstruct --images: {}", note);
    out_ << note << "\n";
  }

  Expected<void> CamerasAndVolume() {
    nlohmann::json input = {
        {"images", options_.images.string()}, {"pattern", options_.pattern},
        {"count", set_.images.size()},        {"kind", rc::KindName(set_.kind, true)},
        {"width_px", set_.width_px},          {"height_px", set_.height_px},
        {"exif_turned", set_.exif_turned}};
    if (photos_ && legacy_threshold_) input["threshold"] = options_.threshold;
    if (thesis_mode_) {
      for (const rc::SetImage& image : set_.images) {
        views_.push_back(rc::ThesisView(set_.width_px, set_.height_px, image.angle_deg));
      }
      input["camera_model"] = "thesis (calibration-free orthographic: axis on the middle column)";
      input["step_deg"] = options_.step_deg;
    } else {
      REVOLVE_RETURN_IF_ERROR(ImportCameras(input));
    }
    report_["input"] = input;
    report_["method"] = options_.method;
    report_["units"] = thesis_mode_ ? "px" : "as in the cameras file";
    report_["scale"] = thesis_mode_ ? "unscaled (thesis mode: one unit is one pixel at the axis)"
                                    : "the cameras file's units (Middlebury: metres)";
    return FindVolume(rc::AutoVolumeOptions{}.tolerated_misses);
  }

  Expected<void> ImportCameras(nlohmann::json& input) {
    rc::CameraFile cameras;
    REVOLVE_ASSIGN_OR_RETURN(cameras, rc::ReadCameraFile(*options_.cameras));
    REVOLVE_ASSIGN_OR_RETURN(views_,
                             rc::ViewsForImages(cameras, names_, set_.width_px, set_.height_px));
    input["cameras"] = options_.cameras->string();
    input["camera_model"] = cameras.format == rc::CameraFileFormat::kMiddlebury
                                ? "imported K [R t] (Middlebury)"
                                : "imported 3x4 projection matrices";
    nlohmann::json odd = nlohmann::json::object();
    for (std::size_t i = 0; i < views_.size(); ++i) {
      const rc::ProjectionCheck check = rc::CheckProjection(views_[i].pixel_from_object);
      if (!check.oddities.empty()) odd[names_[i]] = check.oddities;
    }
    if (!odd.empty()) input["camera_oddities"] = odd;
    if (cameras.cameras.size() > views_.size()) {
      out_ << fmt::format("note: {} of the {} cameras in {} have no image\n",
                          cameras.cameras.size() - views_.size(), cameras.cameras.size(),
                          options_.cameras->string());
    }
    return {};
  }

  // Carving volume, and the depth sign of every view from a point known to be in front.
  // The carving volume from the usable views' masks; `tolerated_misses`: see
  // rc::AutoVolumeOptions (the consensus's box tolerates one mask that lost a part of the object,
  // the carving's does not).
  Expected<void> FindVolume(int tolerated_misses) {
    if (options_.bbox) {
      const auto& b = *options_.bbox;
      box_min_ = Eigen::Vector3d(b[0], b[1], b[2]);
      box_max_ = Eigen::Vector3d(b[3], b[4], b[5]);
      if (!thesis_mode_) {
        for (View& view : views_) view = rc::NormaliseViewSign(view, 0.5 * (box_min_ + box_max_));
      }
      report_["volume"] = {
          {"source", "--bbox"}, {"min", Vec3Json(box_min_)}, {"max", Vec3Json(box_max_)}};
      return {};
    }
    std::vector<cv::Mat> usable_masks;
    std::vector<View> usable_views;
    std::vector<cv::Point> usable_origins;  // empty: whole masks
    usable_masks.reserve(usable_.size());
    usable_views.reserve(usable_.size());
    for (std::size_t i : usable_) {
      usable_masks.push_back(masks_[i]);
      usable_views.push_back(views_[i]);
      if (!mask_origins_.empty()) usable_origins.push_back(mask_origins_[i]);
    }
    rc::AutoVolumeOptions volume_options;
    volume_options.tolerated_misses = tolerated_misses;
    Expected<rc::AutoVolume> volume = rc::CarvingVolumeFromSilhouettes(
        usable_masks, usable_views, volume_options, usable_origins);
    if (!volume) {
      return std::unexpected(WithContext(volume.error(), "finding the carving volume"));
    }
    for (View& view : views_) view = rc::NormaliseViewSign(view, volume->centre);
    box_min_ = volume->box.min;
    box_max_ = volume->box.max;
    report_["volume"] = {{"source", "silhouettes"},
                         {"min", Vec3Json(box_min_)},
                         {"max", Vec3Json(box_max_)},
                         {"centre", Vec3Json(volume->centre)},
                         {"unbounded_by_the_views", volume->touches_limit}};
    return {};
  }

  // Every mask against the hull of the other views.
  Expected<void> Consensus() {
    // From here each mask is held as its bounding rectangle (a fraction of the image; photos'
    // masks are from the segmentation on): whole masks are made again one at a time where
    // needed.
    Expected<std::vector<double>> agreement =
        ApplyConsensus(masks_, views_, problems_, box_min_, box_max_, out_, &mask_origins_);
    if (!agreement) return std::unexpected(WithContext(agreement.error(), "silhouette consensus"));
    agreement_ = std::move(*agreement);
    CollectUsable();
    // The carving's volume: from the views left, every one of them trusted.
    if (!options_.bbox) REVOLVE_RETURN_IF_ERROR(FindVolume(0));
    return {};
  }

  cv::Size FrameSize() const { return {set_.width_px, set_.height_px}; }

  // Mask i whole (its window's pixels, zeros around them).
  cv::Mat WholeMask(std::size_t i) const {
    return mask_origins_.empty() ? masks_[i]
                                 : rc::WholeFromWindow(masks_[i], mask_origins_[i], FrameSize());
  }

  Expected<void> Reconstruct() {
    if (options_.method == "meridian") return ReconstructMeridian();
    rc::ReconstructOptions reconstruct_options;
    reconstruct_options.method = options_.method;
    reconstruct_options.resolution = options_.resolution;
    reconstruct_options.bbox_min_mm = box_min_;
    reconstruct_options.bbox_max_mm = box_max_;
    reconstruct_options.length_unit = thesis_mode_ ? "px" : "units";
    // No turntable plate at z = 0 here: thesis mode's z = 0 is the bottom row, a cameras file's
    // frame is its own.
    reconstruct_options.flat_bottom = false;
    reconstruct_options.share_frames = true;  // the set's frames are not written to again
    // The texture atlas only for the formats that carry it (OBJ, glTF); the PLY and the VRML
    // carry the vertices' colours.
    reconstruct_options.texture =
        std::any_of(options_.formats.begin(), options_.formats.end(),
                    [](const std::string& format) { return format == "obj" || format == "glb"; });
    reconstruct_options.finish_once = true;
    reconstruct_options.meridian_row_step_px = options_.row_step_px;
    reconstruct_options.meridian_both_sides = options_.both_sides;
    std::unique_ptr<rc::Reconstructor> reconstructor;
    REVOLVE_ASSIGN_OR_RETURN(reconstructor, rc::Create(reconstruct_options));
    for (std::size_t i : usable_) {
      rc::SetImage& image = set_.images[i];
      const cv::Mat mask = WholeMask(i);
      REVOLVE_RETURN_IF_ERROR(CoverWindow(*reconstructor, mask, i));
      if (Expected<void> done =
              reconstructor->IntegrateWindow(mask, image.image, image.image_origin, views_[i]);
          !done) {
        return std::unexpected(WithContext(done.error(), image.path.string()));
      }
      // The reconstructor holds the frame now; the set's reference goes.
      image.image.release();
    }
    REVOLVE_ASSIGN_OR_RETURN(mesh_, reconstructor->Finish());
    return {};
  }

  bool IsWhole(const rc::SetImage& image) const {
    return image.image_origin == cv::Point() &&
           image.image.size() == cv::Size(set_.width_px, set_.height_px);
  }

  // Photo i whole: the set's, or read again when the set holds a window of it.
  Expected<cv::Mat> WholePhoto(std::size_t i) const {
    const rc::SetImage& image = set_.images[i];
    const cv::Size size(set_.width_px, set_.height_px);
    if (IsWhole(image)) return image.image;
    cv::Mat photo;
    REVOLVE_ASSIGN_OR_RETURN(
        photo,
        rc::ReadImage8(image.path, static_cast<std::int64_t>(options_.max_image_mp * 1e6), size));
    if (photo.channels() == 1) cv::cvtColor(photo, photo, cv::COLOR_GRAY2BGR);
    return photo;
  }

  // Reads photo i again, when the window of it the set holds misses some of the pixels the
  // reconstructor may read (Reconstructor::FrameWindow), and keeps that window of it.
  Expected<void> CoverWindow(const rc::Reconstructor& reconstructor, const cv::Mat& mask,
                             std::size_t i) {
    rc::SetImage& image = set_.images[i];
    if (image.image.empty()) return {};
    const cv::Rect needed = reconstructor.FrameWindow(mask, views_[i]);
    if ((cv::Rect(image.image_origin, image.image.size()) & needed) == needed) return {};
    Logger("station")->debug("{}: read again for the pixels at ({}, {}) {}x{}", image.file_name,
                             needed.x, needed.y, needed.width, needed.height);
    cv::Mat photo;
    REVOLVE_ASSIGN_OR_RETURN(photo, WholePhoto(i));
    image.image = photo(needed).clone();
    image.image_origin = needed.tl();
    return {};
  }

  Expected<void> ReconstructMeridian() {
    rc::MeridianReconstructor meridian(rc::MeridianOptions{
        options_.row_step_px, options_.both_sides, rc::ReconstructOptions{}.texture_size_px});
    for (std::size_t i : usable_) {
      if (Expected<void> done = meridian.Integrate(WholeMask(i), set_.images[i].image, views_[i]);
          !done) {
        return std::unexpected(WithContext(done.error(), set_.images[i].path.string()));
      }
    }
    rc::MeridianModel model;
    REVOLVE_ASSIGN_OR_RETURN(model, meridian.FinishModel());
    mesh_ = model.mesh;
    meridian_model_ = std::move(model);
    return {};
  }

  Expected<void> WriteFiles() {
    const std::filesystem::path model_dir = options_.out / "model";
    std::error_code ec;
    std::filesystem::create_directories(model_dir, ec);
    if (ec) {
      return MakeError(ErrorCode::kIo, fmt::format("{}: cannot create the folder: {}",
                                                   model_dir.string(), ec.message()));
    }
    // A meridian mesh carries its view-dependent texture: WriteModel writes it into the VRML.
    REVOLVE_ASSIGN_OR_RETURN(files_, rc::WriteModel(mesh_, model_dir, "model", options_.formats));
    return {};
  }

  // The model files are written while the model is measured: the writing on a thread of its own
  // (its writers wait for the disk much of their time; a pool thread waiting would leave its
  // core idle), the measuring on the pool. Each step's time is its own (they overlap).
  Expected<void> WriteFilesWhileMeasuring() {
    Expected<void> written;
    double write_ms = 0.0;
    {
      const std::jthread writer([&] {
        const Clock::time_point t = Clock::now();
        written = WriteFiles();
        write_ms = MsSince(t);
      });
      const Clock::time_point t = Clock::now();
      Measure();
      times_["metrics_ms"] = MsSince(t);
    }
    times_["write_ms"] = write_ms;
    return written;
  }

  void Measure() {
    // Independent, each on all cores. The reprojection finds every edge's faces: whether the
    // mesh is closed and oriented is known then, not checked twice.
    rc::ParallelInvoke(
        [&] { stats_ = rc::ComputeMeasures(mesh_); },
        [&] { reprojection_ = rc::SilhouetteReprojection(mesh_, views_, masks_, mask_origins_); });
    if (reprojection_.closed_and_oriented) {
      stats_.closed = stats_.oriented = true;
    } else {
      rc::CheckEdges(mesh_, &stats_);
    }
  }

  // report.json's model and reprojection sections.
  void Describe() {
    nlohmann::json file_names = nlohmann::json::array();
    for (const std::filesystem::path& f : files_) {
      file_names.push_back(std::filesystem::relative(f, options_.out).string());
    }
    report_["model"] = {{"files", file_names},
                        {"vertices", stats_.vertex_count},
                        {"triangles", stats_.triangle_count},
                        {"volume", stats_.volume_mm3},
                        {"surface_area", stats_.area_mm2},
                        {"bbox_min", Vec3Json(stats_.bbox_min_mm)},
                        {"bbox_max", Vec3Json(stats_.bbox_max_mm)},
                        {"dimensions", Vec3Json(stats_.bbox_max_mm - stats_.bbox_min_mm)},
                        {"watertight", stats_.closed},
                        {"consistently_oriented", stats_.oriented}};
    if (meridian_model_) {
      report_["model"]["meridians"] = meridian_model_->meridian_count;
      report_["model"]["rows"] = meridian_model_->row_count;
      report_["model"]["texture_images"] = meridian_model_->mesh.view_texture.images.size();
    }
    nlohmann::json per_view =
        JudgeViews(names_, masks_, reprojection_.iou, problems_, kMinAgreeingIoU, out_);
    for (std::size_t i = 0; i < per_view.size(); ++i) {
      per_view[i]["iou"] = reprojection_.iou[i];
      per_view[i]["consensus_agreement"] = agreement_[i];
    }
    report_["reprojection"] = {{"mean_iou", reprojection_.mean},
                               {"min_iou", reprojection_.min},
                               {"worst_image", WorstName()},
                               {"per_view", per_view}};
  }

  const std::string& WorstName() const {
    return names_[static_cast<std::size_t>(reprojection_.worst_view)];
  }

  Expected<void> WriteReportAndSay() {
    const std::string text = report_.dump(2) + "\n";
    REVOLVE_RETURN_IF_ERROR(
        WriteFileAtomically(options_.out / "report.json", std::string_view(text)));
    const Eigen::Vector3d size = stats_.bbox_max_mm - stats_.bbox_min_mm;
    const std::string unit = thesis_mode_ ? "px" : "units";
    out_ << fmt::format(
        "{}: {} triangles, {:.4g} x {:.4g} x {:.4g} {}, volume {:.4g} {}^3{}; silhouette "
        "reprojection IoU mean {:.3f}, min {:.3f} ({})\n",
        options_.method, stats_.triangle_count, size.x(), size.y(), size.z(), unit,
        stats_.volume_mm3, unit, thesis_mode_ ? " (unscaled)" : "", reprojection_.mean,
        reprojection_.min, WorstName());
    for (const std::filesystem::path& f : files_) out_ << "  " << f.string() << "\n";
    out_ << "  " << (options_.out / "masks").string() << "/, "
         << (options_.out / "contact_sheet.png").string() << "\n";
    out_ << "  " << (options_.out / "report.json").string() << "\n";
    return {};
  }

  const ReconstructImagesOptions& options_;
  std::ostream& out_;
  const bool thesis_mode_;
  nlohmann::json report_;
  nlohmann::json times_;
  bool legacy_threshold_ = false;
  bool photos_ = false;
  std::optional<capture::SegmentOptions> segment_options_;
  std::optional<capture::FrameByFrameSegmentation> by_frame_;  // Load to Segment (photos)
  rc::ImageSet set_;
  std::vector<std::string> names_;
  std::vector<cv::Mat> masks_;
  std::vector<cv::Point> mask_origins_;  // empty: masks_ whole; else each mask's window origin
  std::vector<cv::Mat> thumbnails_;      // the contact sheet's, per photo (empty for silhouettes)
  std::vector<std::string> problems_;    // per image: why it is left out, empty when usable
  std::vector<std::size_t> usable_;
  std::vector<View> views_;
  Eigen::Vector3d box_min_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d box_max_ = Eigen::Vector3d::Zero();
  std::vector<double> agreement_;
  rc::Mesh mesh_;
  std::optional<rc::MeridianModel> meridian_model_;
  std::vector<std::filesystem::path> files_;
  rc::MeshStats stats_;
  rc::ReprojectionStats reprojection_;
};

}  // namespace

int RunReconstructImages(const ReconstructImagesOptions& options, std::ostream& out,
                         std::ostream& err) {
  if (const std::string problem = CheckOptions(options); !problem.empty()) {
    err << "revolve reconstruct: " << problem << "\n";
    return kExitUsage;
  }
  // One malloc arena for the process's threads: glibc gives threads arenas of their own, and
  // what one thread frees stays in its arena for that thread's next buffers; the pool's threads
  // take turns with the photos, masks and the texture's arrays, so one arena holds ~20 MB less
  // at the peak (docs/performance.md, ninth pass), and no slower measured.
  mallopt(M_ARENA_MAX, 1);
  std::error_code ec;
  const bool out_existed = std::filesystem::exists(options.out, ec);
  Expected<nlohmann::json> report = ImagesRun(options, out).Run();
  if (!report) {
    // A refused run leaves no empty folder behind; what it did write (the masks, for a person
    // to check why) stays. remove() deletes only empty folders.
    if (!out_existed) {
      std::filesystem::remove(options.out / "model", ec);
      std::filesystem::remove(options.out, ec);
    }
    Logger("station")->error("reconstruct: {}", report.error().ToString());
    err << "revolve reconstruct: " << report.error().message << "\n";
    return kExitFailed;
  }
  return kExitOk;
}

}  // namespace revolve::station
