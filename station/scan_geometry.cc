#include "station/scan_geometry.h"

#include <cmath>
#include <fstream>
#include <numbers>
#include <sstream>

#include <fmt/format.h>

#include "reconstruct/cameras/views.h"
#include "station/report_json.h"

namespace revolve::station {
namespace {

namespace cal = revolve::calibrate;
namespace rc = revolve::reconstruct;

nlohmann::json AxisJson(const cal::SilhouetteAxis& axis, int width_px) {
  return {{"column_px", axis.column_px},
          {"reference_row_px", axis.reference_row_px},
          {"offset_from_middle_px", axis.OffsetFromMiddlePx(width_px)},
          {"tilt_deg", axis.tilt_deg},
          {"rms_px", axis.rms_px},
          {"mirror_iou", axis.mirror_iou},
          {"pairs", axis.pairs}};
}

}  // namespace

std::string_view ToString(GeometrySource source) {
  switch (source) {
    case GeometrySource::kCalibration:
      return "calibration";
    case GeometrySource::kCamera:
      return "camera";
    case GeometrySource::kThesis:
      return "thesis";
  }
  return "thesis";
}

View ThesisViewWithAxis(int width_px, int height_px, double plate_angle_deg, double column_px,
                        double tilt_deg) {
  View view = rc::ThesisView(width_px, height_px, plate_angle_deg);
  // ThesisView puts the axis on the middle column; move it to column_px...
  view.pixel_from_object(0, 3) = column_px;
  // ...and turn the image about (column_px, middle row) so that the axis's downward direction
  // (0, 1) becomes (sin t, cos t): its lower end to the right for a positive tilt.
  if (tilt_deg != 0.0) {
    const double t = tilt_deg * std::numbers::pi / 180.0;
    const Eigen::Vector2d pivot(column_px, 0.5 * (height_px - 1));
    Eigen::Matrix2d turn;
    turn << std::cos(t), std::sin(t), -std::sin(t), std::cos(t);
    Eigen::Matrix3d a = Eigen::Matrix3d::Identity();
    a.topLeftCorner<2, 2>() = turn;
    a.topRightCorner<2, 1>() = pivot - turn * pivot;
    view.pixel_from_object = a * view.pixel_from_object;
  }
  return view;
}

Expected<ScanGeometry> ScanGeometry::Create(const rc::ReconstructOptions& options,
                                            const capture::Camera& camera,
                                            const std::filesystem::path& calibration_file) {
  ScanGeometry g;
  g.options_ = options;
  g.camera_ = &camera;
  if (!calibration_file.empty()) {
    auto calibration = cal::LoadCalibration(calibration_file);
    if (!calibration) return std::unexpected(calibration.error());
    auto rig = calibration->ToRig();
    if (!rig) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("{}: {} (a lens-only calibration: run `revolve calibrate axis "
                      "--calibration {}` with the board on the plate)",
                      calibration_file.string(), rig.error().message, calibration_file.string()));
    }
    std::ifstream in(calibration_file, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    g.calibration_text_ = text.str();
    g.calibration_file_ = calibration_file;
    g.rig_ = *rig;
    if (calibration->camera.HasDistortion()) {
      g.undistorter_ = std::make_shared<const cal::Undistorter>(calibration->camera);
    }
    g.calibration_ = std::move(*calibration);
    g.source_ = GeometrySource::kCalibration;
  } else if (camera.KnownView(0.0)) {
    g.source_ = GeometrySource::kCamera;
  } else {
    g.source_ = GeometrySource::kThesis;
  }
  if (g.source_ != GeometrySource::kThesis) {
    auto reconstructor = rc::Create(options);
    if (!reconstructor) return std::unexpected(reconstructor.error());
    g.reconstructor_ = std::move(*reconstructor);
  }
  return g;
}

Expected<void> ScanGeometry::CheckFrameSize(int width_px, int height_px) const {
  if (source_ == GeometrySource::kCamera) {
    const std::optional<View> view = camera_->KnownView(0.0);
    if (view && view->width_px > 0 &&
        (view->width_px != width_px || view->height_px != height_px)) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("the images are {} x {} pixels, but the camera ({}) makes {} x "
                      "{}: its geometry would not fit them",
                      width_px, height_px, camera_->Describe(), view->width_px, view->height_px));
    }
    return {};
  }
  if (!calibration_) return {};
  if (auto ok = calibration_->CheckFrameSize(width_px, height_px); !ok) {
    return std::unexpected(WithContext(ok.error(), calibration_file_.string()));
  }
  return {};
}

cv::Mat ScanGeometry::Undistort(const cv::Mat& frame) const {
  if (!undistorter_ || frame.empty()) return frame;
  return undistorter_->Apply(frame);
}

View ScanGeometry::ViewAt(double angle_deg, int width_px, int height_px) const {
  View view;
  if (source_ == GeometrySource::kCalibration) {
    view.pixel_from_object = rig_.value().PixelFromObject(angle_deg);  // set with the source
  } else if (source_ == GeometrySource::kCamera) {
    view = camera_->KnownView(angle_deg).value();  // the source says it has one
  } else {
    view = ThesisViewWithAxis(width_px, height_px, angle_deg, axis_column_px_, axis_tilt_deg_);
  }
  view.width_px = width_px;
  view.height_px = height_px;
  return view;
}

std::optional<View> ScanGeometry::LiveView(double angle_deg, int width_px, int height_px) const {
  if (source_ == GeometrySource::kThesis) return std::nullopt;
  return ViewAt(angle_deg, width_px, height_px);
}

Expected<void> ScanGeometry::Integrate(const cv::Mat& mask, const cv::Mat& frame,
                                       double angle_deg) {
  masks_.push_back(mask);
  angles_.push_back(angle_deg);
  if (source_ == GeometrySource::kThesis) {
    frames_.push_back(frame);
    return {};
  }
  return reconstructor_->Integrate(mask, frame, ViewAt(angle_deg, mask.cols, mask.rows));
}

void ScanGeometry::FitSilhouetteAxis() {
  if (masks_.empty()) return;
  silhouette_axis_ = cal::AxisFromSilhouettes(masks_, angles_);
}

Expected<void> ScanGeometry::Finish(rc::Mesh* mesh, const rc::MeshStageHook& on_stage) {
  FitSilhouetteAxis();
  if (source_ != GeometrySource::kThesis) return reconstructor_->FinishStaged(mesh, on_stage);

  if (masks_.empty()) return MakeError(ErrorCode::kBadInput, "no stop to reconstruct");
  const int width_px = masks_.front().cols;
  axis_column_px_ = 0.5 * (width_px - 1);
  axis_tilt_deg_ = 0.0;
  if (silhouette_axis_ && *silhouette_axis_ && (*silhouette_axis_)->mirror_iou >= kMinMirrorIou) {
    axis_used_ = true;
    axis_column_px_ = (*silhouette_axis_)->column_px;
    axis_tilt_deg_ = (*silhouette_axis_)->tilt_deg;
  }
  std::vector<View> views;
  for (std::size_t i = 0; i < masks_.size(); ++i) {
    views.push_back(ViewAt(angles_[i], masks_[i].cols, masks_[i].rows));
  }
  auto volume = rc::CarvingVolumeFromSilhouettes(masks_, views);
  if (!volume) {
    return std::unexpected(WithContext(volume.error(), "thesis mode: finding the carving volume"));
  }
  volume_ = {{"min", Vec3Json(volume->box.min)},
             {"max", Vec3Json(volume->box.max)},
             {"unbounded_by_the_views", volume->touches_limit}};
  rc::ReconstructOptions options = options_;
  options.bbox_min_mm = volume->box.min;
  options.bbox_max_mm = volume->box.max;
  // z = 0 is the image's bottom row here, not the plate.
  options.flat_bottom = false;
  auto reconstructor = rc::Create(options);
  if (!reconstructor) return std::unexpected(reconstructor.error());
  reconstructor_ = std::move(*reconstructor);
  for (std::size_t i = 0; i < masks_.size(); ++i) {
    if (auto done = reconstructor_->Integrate(masks_[i], frames_[i], views[i]); !done) {
      return std::unexpected(
          WithContext(done.error(), fmt::format("stop at {:g} deg", angles_[i])));
    }
    frames_[i].release();
  }
  return reconstructor_->FinishStaged(mesh, on_stage);
}

nlohmann::json ScanGeometry::ReportJson() const {
  nlohmann::json j;
  const int width_px = masks_.empty() ? 0 : masks_.front().cols;
  switch (source_) {
    case GeometrySource::kCalibration: {
      j["units"] = "mm";
      j["scale"] = "metric (calibration)";
      j["camera_model"] = "calibrated pinhole (calibration.toml; frames undistorted)";
      const cal::Calibration& c = calibration_.value();
      nlohmann::json calibration = {{"file", calibration_file_.string()},
                                    {"copy", "calibration.toml"},
                                    {"created", c.created},
                                    {"software_version", c.software_version},
                                    {"board", c.board.Describe()},
                                    {"lens_rms_px", c.lens.rms_px},
                                    {"undistorted", undistorter_ != nullptr}};
      if (c.axis) {
        calibration["axis_reprojection_rms_px"] = c.axis->reprojection_rms_px;
        calibration["axis_direction_cam"] = Vec3Json(c.axis->cam_from_table.linear().col(2));
        calibration["plate_centre_cam_mm"] = Vec3Json(c.axis->cam_from_table.translation());
      }
      j["calibration"] = calibration;
      break;
    }
    case GeometrySource::kCamera:
      j["units"] = "mm";
      j["scale"] = "metric (simulated rig geometry)";
      j["camera_model"] = "the camera's own geometry";
      break;
    case GeometrySource::kThesis:
      j["units"] = "px";
      j["scale"] = "unknown";
      j["camera_model"] = axis_used_ ? "thesis (calibration-free orthographic: axis line fitted to "
                                       "the silhouettes)"
                                     : "thesis (calibration-free orthographic: axis on the "
                                       "middle column)";
      j["thesis_axis"] = {{"column_px", axis_column_px_},
                          {"tilt_deg", axis_tilt_deg_},
                          {"source", axis_used_ ? "silhouettes" : "middle column"}};
      if (!volume_.is_null()) j["volume_px"] = volume_;
      break;
  }
  if (silhouette_axis_) {
    nlohmann::json s;
    if (*silhouette_axis_) {
      s = AxisJson(**silhouette_axis_, width_px);
      if (source_ == GeometrySource::kThesis) {
        s["used"] = axis_used_;
        if (!axis_used_) {
          s["why_not"] = fmt::format("mirrored IoU {:.3f} < {:.2f}",
                                     (*silhouette_axis_)->mirror_iou, kMinMirrorIou);
        }
      }
      if (rig_) {
        const cal::SilhouetteAxis line = cal::ProjectedAxisLine(*rig_);
        s["calibrated_column_px"] = line.column_px;
        s["calibrated_tilt_deg"] = line.tilt_deg;
        s["column_difference_px"] =
            (*silhouette_axis_)->ColumnAt(line.reference_row_px) - line.column_px;
      }
    } else {
      s["error"] = silhouette_axis_->error().message;
      if (source_ == GeometrySource::kThesis) s["used"] = false;
    }
    j["silhouette_axis"] = s;
  }
  return j;
}

}  // namespace revolve::station
