#include "station/commands/reconstruct_images_command.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "base/atomic_file.h"
#include "base/log.h"
#include "reconstruct/cameras/camera_file.h"
#include "reconstruct/cameras/views.h"
#include "reconstruct/image_set.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/meridian/meridian.h"
#include "reconstruct/metrics/metrics.h"
#include "reconstruct/metrics/reprojection.h"
#include "reconstruct/reconstructor.h"
#include "station/commands/scan_command.h"
#include "station/commands/set_masks.h"
#include "station/report_json.h"
#include "station/timing.h"

namespace revolve::station {
namespace {

using Clock = std::chrono::steady_clock;
namespace rc = revolve::reconstruct;

// A view whose mask reprojects below this IoU against the model is flagged in report.json.
constexpr double kMinAgreeingIoU = 0.9;

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
  }
  return {};
}

Expected<nlohmann::json> Run(const ReconstructImagesOptions& options, std::ostream& out) {
  nlohmann::json report;
  nlohmann::json times;
  const Clock::time_point start = Clock::now();

  // The output folder first (a read-only or unwritable --out is said before any work), but not
  // for a set that is not there: a mistyped --images leaves nothing behind.
  if (std::error_code ec; !std::filesystem::is_directory(options.images, ec)) {
    return MakeError(ErrorCode::kNotFound,
                     fmt::format("{}: no such folder", options.images.string()));
  }
  if (auto made = CreateOutputFolder(options.out / "model"); !made) {
    return std::unexpected(made.error());
  }

  // Inputs.
  Clock::time_point t = Clock::now();
  const bool legacy_threshold = options.segment == "threshold";
  std::optional<capture::SegmentOptions> segment_options;
  if (!legacy_threshold) {
    Expected<capture::SegmentOptions> parsed =
        ImagesSegmentOptions(options.config, options.segment);
    if (!parsed) return std::unexpected(parsed.error());
    segment_options = std::move(*parsed);
  }
  rc::ImageSetOptions set_options;
  set_options.max_image_pixels = static_cast<std::int64_t>(options.max_image_mp * 1e6);
  set_options.pattern = options.pattern;
  set_options.step_deg = options.step_deg;
  set_options.segmentation.threshold = options.threshold;
  set_options.segment_photos = legacy_threshold;
  Expected<rc::ImageSet> set = rc::LoadImageSet(options.images, set_options);
  if (!set) return std::unexpected(set.error());
  const bool photos = set->kind == rc::ImageKind::kPhoto;
  out << fmt::format("{} {} of {}x{} px from {}\n", set->images.size(),
                     photos ? "photos" : "binary silhouettes", set->width_px, set->height_px,
                     options.images.string());
  std::vector<std::string> names;
  std::vector<cv::Mat> masks;
  std::vector<cv::Mat> frames;
  for (const rc::SetImage& image : set->images) {
    names.push_back(image.file_name);
    masks.push_back(image.mask);
    frames.push_back(image.image);
  }
  times["load_ms"] = MsSince(t);

  // Silhouettes: segmented here (photos), saved for a person to check before anything can fail.
  t = Clock::now();
  std::vector<std::string> problems(masks.size());
  if (photos && !legacy_threshold) {
    Expected<SetMasks> segmented = SegmentPhotos(frames, *segment_options, out);
    if (!segmented) return std::unexpected(segmented.error());
    masks = std::move(segmented->masks);
    problems = std::move(segmented->problems);
    report["segmentation"] = segmented->report;
  } else {
    report["segmentation"] = {
        {"method", photos ? "threshold" : "none (binary silhouettes)"},
        {"reason", photos
                       ? fmt::format("--segment threshold: any channel above {}", options.threshold)
                       : "the images are silhouettes already"}};
  }
  if (Expected<void> written = WriteMasks(options.out, names, frames, masks); !written) {
    return std::unexpected(written.error());
  }
  times["segment_ms"] = MsSince(t);
  std::vector<std::size_t> usable;
  for (std::size_t i = 0; i < masks.size(); ++i) {
    if (problems[i].empty()) usable.push_back(i);
  }
  if (usable.size() < 2) {
    std::string why;
    for (std::size_t i = 0; i < masks.size(); ++i) {
      if (!problems[i].empty()) why += fmt::format("\n  {}: {}", names[i], problems[i]);
    }
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{}: only {} of {} images gave a usable silhouette (the masks "
                                 "are in {}):{}",
                                 options.images.string(), usable.size(), masks.size(),
                                 (options.out / "masks").string(), why));
  }
  std::vector<cv::Mat> usable_masks;
  usable_masks.reserve(usable.size());
  for (std::size_t i : usable) usable_masks.push_back(masks[i]);

  // Cameras.
  t = Clock::now();
  std::vector<View> views;
  const bool thesis_mode = !options.cameras.has_value();
  nlohmann::json input = {
      {"images", options.images.string()}, {"pattern", options.pattern},
      {"count", set->images.size()},       {"kind", photos ? "photos" : "binary silhouettes"},
      {"width_px", set->width_px},         {"height_px", set->height_px}};
  if (photos && legacy_threshold) input["threshold"] = options.threshold;
  if (thesis_mode) {
    for (const rc::SetImage& image : set->images) {
      views.push_back(rc::ThesisView(set->width_px, set->height_px, image.angle_deg));
    }
    input["camera_model"] = "thesis (calibration-free orthographic: axis on the middle column)";
    input["step_deg"] = options.step_deg;
  } else {
    Expected<rc::CameraFile> cameras = rc::ReadCameraFile(*options.cameras);
    if (!cameras) return std::unexpected(cameras.error());
    Expected<std::vector<View>> imported =
        rc::ViewsForImages(*cameras, names, set->width_px, set->height_px);
    if (!imported) return std::unexpected(imported.error());
    views = std::move(*imported);
    input["cameras"] = options.cameras->string();
    input["camera_model"] = cameras->format == rc::CameraFileFormat::kMiddlebury
                                ? "imported K [R t] (Middlebury)"
                                : "imported 3x4 projection matrices";
    nlohmann::json odd = nlohmann::json::object();
    for (std::size_t i = 0; i < views.size(); ++i) {
      const rc::ProjectionCheck check = rc::CheckProjection(views[i].pixel_from_object);
      if (!check.oddities.empty()) odd[names[i]] = check.oddities;
    }
    if (!odd.empty()) input["camera_oddities"] = odd;
    if (cameras->cameras.size() > views.size()) {
      out << fmt::format("note: {} of the {} cameras in {} have no image\n",
                         cameras->cameras.size() - views.size(), cameras->cameras.size(),
                         options.cameras->string());
    }
  }
  report["input"] = input;
  report["method"] = options.method;
  report["units"] = thesis_mode ? "px" : "as in the cameras file";
  report["scale"] = thesis_mode ? "unscaled (thesis mode: one unit is one pixel at the axis)"
                                : "the cameras file's units (Middlebury: metres)";

  // Carving volume, and the depth sign of every view from a point known to be in front.
  Eigen::Vector3d box_min = Eigen::Vector3d::Zero();
  Eigen::Vector3d box_max = Eigen::Vector3d::Zero();
  if (options.bbox) {
    const auto& b = *options.bbox;
    box_min = Eigen::Vector3d(b[0], b[1], b[2]);
    box_max = Eigen::Vector3d(b[3], b[4], b[5]);
    if (!thesis_mode) {
      for (View& view : views) view = rc::NormaliseViewSign(view, 0.5 * (box_min + box_max));
    }
    report["volume"] = {
        {"source", "--bbox"}, {"min", Vec3Json(box_min)}, {"max", Vec3Json(box_max)}};
  } else {
    std::vector<View> usable_views;
    usable_views.reserve(usable.size());
    for (std::size_t i : usable) usable_views.push_back(views[i]);
    Expected<rc::AutoVolume> volume = rc::CarvingVolumeFromSilhouettes(usable_masks, usable_views);
    if (!volume) {
      return std::unexpected(WithContext(volume.error(), "finding the carving volume"));
    }
    for (View& view : views) view = rc::NormaliseViewSign(view, volume->centre);
    box_min = volume->box.min;
    box_max = volume->box.max;
    report["volume"] = {{"source", "silhouettes"},
                        {"min", Vec3Json(box_min)},
                        {"max", Vec3Json(box_max)},
                        {"centre", Vec3Json(volume->centre)},
                        {"unbounded_by_the_views", volume->touches_limit}};
  }
  times["cameras_ms"] = MsSince(t);

  // Every mask against the hull of the other views.
  t = Clock::now();
  Expected<std::vector<double>> agreement =
      ApplyConsensus(masks, views, problems, box_min, box_max, out);
  if (!agreement) return std::unexpected(WithContext(agreement.error(), "silhouette consensus"));
  usable.clear();
  for (std::size_t i = 0; i < masks.size(); ++i) {
    if (problems[i].empty()) usable.push_back(i);
  }
  if (Expected<void> written = WriteMasks(options.out, names, frames, masks); !written) {
    return std::unexpected(written.error());
  }
  times["consensus_ms"] = MsSince(t);

  // Reconstruction.
  t = Clock::now();
  rc::ReconstructOptions reconstruct_options;
  reconstruct_options.method = options.method;
  reconstruct_options.resolution = options.resolution;
  reconstruct_options.bbox_min_mm = box_min;
  reconstruct_options.bbox_max_mm = box_max;
  // No turntable plate at z = 0 here: thesis mode's z = 0 is the bottom row, a cameras file's
  // frame is its own.
  reconstruct_options.flat_bottom = false;
  reconstruct_options.meridian_row_step_px = options.row_step_px;
  reconstruct_options.meridian_both_sides = options.both_sides;
  reconstruct_options.share_frames = true;  // the set's frames are not written to again
  std::optional<rc::MeridianModel> meridian_model;
  rc::Mesh mesh;
  if (options.method == "meridian") {
    rc::MeridianReconstructor meridian(rc::MeridianOptions{options.row_step_px, options.both_sides,
                                                           reconstruct_options.texture_size_px});
    for (std::size_t i : usable) {
      if (Expected<void> done = meridian.Integrate(masks[i], set->images[i].image, views[i]);
          !done) {
        return std::unexpected(WithContext(done.error(), set->images[i].path.string()));
      }
    }
    Expected<rc::MeridianModel> model = meridian.FinishModel();
    if (!model) return std::unexpected(model.error());
    mesh = model->mesh;
    meridian_model = std::move(*model);
  } else {
    Expected<std::unique_ptr<rc::Reconstructor>> reconstructor = rc::Create(reconstruct_options);
    if (!reconstructor) return std::unexpected(reconstructor.error());
    for (std::size_t i : usable) {
      if (Expected<void> done =
              (*reconstructor)->Integrate(masks[i], set->images[i].image, views[i]);
          !done) {
        return std::unexpected(WithContext(done.error(), set->images[i].path.string()));
      }
      // The reconstructor holds the frame now; the set's references go.
      set->images[i].image.release();
      frames[i].release();
    }
    Expected<rc::Mesh> finished = (*reconstructor)->Finish();
    if (!finished) return std::unexpected(finished.error());
    mesh = std::move(*finished);
  }
  times["reconstruct_ms"] = MsSince(t);

  // Files.
  t = Clock::now();
  const std::filesystem::path model_dir = options.out / "model";
  std::error_code ec;
  std::filesystem::create_directories(model_dir, ec);
  if (ec) {
    return MakeError(ErrorCode::kIo, fmt::format("{}: cannot create the folder: {}",
                                                 model_dir.string(), ec.message()));
  }
  // A meridian mesh carries its view-dependent texture: WriteModel writes it into the VRML.
  Expected<std::vector<std::filesystem::path>> files =
      rc::WriteModel(mesh, model_dir, "model", options.formats);
  if (!files) return std::unexpected(files.error());
  times["write_ms"] = MsSince(t);

  // Metrics.
  t = Clock::now();
  const rc::MeshStats stats = rc::ComputeStats(mesh);
  nlohmann::json file_names = nlohmann::json::array();
  for (const std::filesystem::path& f : *files) {
    file_names.push_back(std::filesystem::relative(f, options.out).string());
  }
  report["model"] = {{"files", file_names},
                     {"vertices", stats.vertex_count},
                     {"triangles", stats.triangle_count},
                     {"volume", stats.volume_mm3},
                     {"surface_area", stats.area_mm2},
                     {"bbox_min", Vec3Json(stats.bbox_min_mm)},
                     {"bbox_max", Vec3Json(stats.bbox_max_mm)},
                     {"dimensions", Vec3Json(stats.bbox_max_mm - stats.bbox_min_mm)},
                     {"watertight", stats.closed},
                     {"consistently_oriented", stats.oriented}};
  if (meridian_model) {
    report["model"]["meridians"] = meridian_model->meridian_count;
    report["model"]["rows"] = meridian_model->row_count;
    report["model"]["texture_images"] = meridian_model->mesh.view_texture.images.size();
  }
  const rc::ReprojectionStats reprojection = rc::SilhouetteReprojection(mesh, views, masks);
  nlohmann::json per_view =
      JudgeViews(names, masks, reprojection.iou, problems, kMinAgreeingIoU, out);
  for (std::size_t i = 0; i < per_view.size(); ++i) {
    per_view[i]["iou"] = reprojection.iou[i];
    per_view[i]["consensus_agreement"] = (*agreement)[i];
  }
  report["reprojection"] = {
      {"mean_iou", reprojection.mean},
      {"min_iou", reprojection.min},
      {"worst_image", names[static_cast<std::size_t>(reprojection.worst_view)]},
      {"per_view", per_view}};
  times["metrics_ms"] = MsSince(t);
  times["total_ms"] = MsSince(start);
  report["times_ms"] = times;
  const std::string text = report.dump(2) + "\n";
  if (Expected<void> w = WriteFileAtomically(options.out / "report.json", std::string_view(text));
      !w) {
    return std::unexpected(w.error());
  }
  const Eigen::Vector3d size = stats.bbox_max_mm - stats.bbox_min_mm;
  const std::string unit = thesis_mode ? "px" : "units";
  out << fmt::format(
      "{}: {} triangles, {:.4g} x {:.4g} x {:.4g} {}, volume {:.4g} {}^3{}; silhouette "
      "reprojection IoU mean {:.3f}, min {:.3f} ({})\n",
      options.method, stats.triangle_count, size.x(), size.y(), size.z(), unit, stats.volume_mm3,
      unit, thesis_mode ? " (unscaled)" : "", reprojection.mean, reprojection.min,
      names[static_cast<std::size_t>(reprojection.worst_view)]);
  for (const std::filesystem::path& f : *files) out << "  " << f.string() << "\n";
  out << "  " << (options.out / "masks").string() << "/, "
      << (options.out / "contact_sheet.png").string() << "\n";
  out << "  " << (options.out / "report.json").string() << "\n";
  return report;
}

}  // namespace

int RunReconstructImages(const ReconstructImagesOptions& options, std::ostream& out,
                         std::ostream& err) {
  if (const std::string problem = CheckOptions(options); !problem.empty()) {
    err << "revolve reconstruct: " << problem << "\n";
    return kExitUsage;
  }
  Expected<nlohmann::json> report = Run(options, out);
  if (!report) {
    Logger("station")->error("reconstruct: {}", report.error().ToString());
    err << "revolve reconstruct: " << report.error().message << "\n";
    return kExitFailed;
  }
  return kExitOk;
}

}  // namespace revolve::station
