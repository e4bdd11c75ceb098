// The camera model of a scan: how object points become pixels at each stop, and what that means
// for the model's units. Shared by ScanSession (a scan) and `revolve reconstruct SCAN_DIR`.
//
// One of three, in this order of preference:
//  - calibration: a calibration file (docs/calibration.md), [calibration] file or a scan's
//    calibration.toml. Frames are undistorted (Undistort) before segmentation and saving; the
//    view at plate angle a is Rig::PixelFromObject(a) of Calibration::ToRig(); millimetres.
//  - camera: the camera's own geometry (Camera::KnownView: the simulated camera); millimetres.
//  - thesis: neither. The thesis's calibration-free orthographic views (reconstruct/cameras/
//    views.h ThesisView), lengths in pixels, scale unknown. The axis's image line is fitted to
//    the scan's silhouettes (calibrate/silhouette_axis.h) and used instead of the middle column
//    when the fit is good (mirrored IoU >= kMinMirrorIou); the carving volume is found from the
//    silhouettes. Both need every silhouette, so this mode integrates the stops in Finish().
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "calibrate/calibration.h"
#include "calibrate/camera_model.h"
#include "calibrate/silhouette_axis.h"
#include "capture/camera.h"
#include "reconstruct/mesh.h"
#include "reconstruct/reconstructor.h"

namespace revolve::station {

enum class GeometrySource { kCalibration, kCamera, kThesis };

// "calibration" / "camera" / "thesis".
std::string_view ToString(GeometrySource source);

// Thesis mode takes the silhouettes' axis line when their mirrored IoU reaches this.
inline constexpr double kMinMirrorIou = 0.9;

// The thesis's orthographic view (ThesisView) with the axis's image line at `column_px` on the
// middle row, turned by `tilt_deg` (calibrate::SilhouetteAxis's convention) about that point.
View ThesisViewWithAxis(int width_px, int height_px, double plate_angle_deg, double column_px,
                        double tilt_deg);

class ScanGeometry {
 public:
  // Loads `calibration_file` when not empty (errors: not_found, bad_input naming the file; a
  // lens-only calibration is bad_input), else takes the camera's KnownView, else thesis mode.
  // `options` are the scan's [reconstruct] options (thesis mode replaces the volume with one
  // found from the silhouettes, in pixels, and cuts no flat bottom).
  static Expected<ScanGeometry> Create(const reconstruct::ReconstructOptions& options,
                                       const capture::Camera& camera,
                                       const std::filesystem::path& calibration_file);

  GeometrySource source() const { return source_; }
  bool metric() const { return source_ != GeometrySource::kThesis; }
  // The loaded calibration (source kCalibration) and its file's text, as read.
  const std::optional<calibrate::Calibration>& calibration() const { return calibration_; }
  const std::string& calibration_text() const { return calibration_text_; }
  const std::filesystem::path& calibration_file() const { return calibration_file_; }

  // bad_input unless frames of this size are what the calibration was made at, or what the
  // camera whose known geometry is used makes (thesis mode: any size).
  Expected<void> CheckFrameSize(int width_px, int height_px) const;

  // The frame as the views describe it: undistorted with a calibration whose lens distorts,
  // else `frame` itself. Use on every frame (and background) before segmentation.
  cv::Mat Undistort(const cv::Mat& frame) const;

  // Adds a stop: its mask (CV_8UC1), frame (for colour; may be empty) and read-back plate angle.
  // Integrated at once, except in thesis mode (kept for Finish).
  Expected<void> Integrate(const cv::Mat& mask, const cv::Mat& frame, double angle_deg);

  // The view of a stop at plate angle `angle_deg` as it is known while scanning (with a
  // calibration or the camera's own geometry); nullopt in thesis mode, whose views need every
  // silhouette. For live previews (station/live_view.h).
  std::optional<View> LiveView(double angle_deg, int width_px, int height_px) const;
  // The carving volume in the object frame (mm) of a metric geometry.
  const Eigen::Vector3d& bbox_min_mm() const { return options_.bbox_min_mm; }
  const Eigen::Vector3d& bbox_max_mm() const { return options_.bbox_max_mm; }

  // The mesh of every stop integrated, made in `*mesh` with `on_stage` told of its stages as
  // Reconstructor::FinishStaged does (for a reconstruct::ModelWriter). Errors: as
  // Reconstructor::Finish; thesis mode: no silhouette, or no carving volume found.
  Expected<void> Finish(reconstruct::Mesh* mesh, const reconstruct::MeshStageHook& on_stage);

  // What report.json says about the geometry (call after Finish): "units" ("mm" | "px"),
  // "scale", "camera_model", "calibration" {file, created, ...} with a calibration,
  // "silhouette_axis" (the fit on the scan's masks, and in thesis mode whether it was used;
  // with a calibration compared with the calibrated axis's image line).
  nlohmann::json ReportJson() const;

  // The view of the stop at plate angle `angle_deg` in a width x height frame: the calibrated
  // rig's or the camera's pinhole view (object frame, mm); in thesis mode the orthographic view
  // with the axis line found in Finish (the middle column before it).
  View ViewAt(double angle_deg, int width_px, int height_px) const;

 private:
  ScanGeometry() = default;
  void FitSilhouetteAxis();

  GeometrySource source_ = GeometrySource::kThesis;
  reconstruct::ReconstructOptions options_;
  const capture::Camera* camera_ = nullptr;  // borrowed (source kCamera)
  std::optional<calibrate::Calibration> calibration_;
  std::optional<Rig> rig_;  // of the calibration
  std::shared_ptr<const calibrate::Undistorter> undistorter_;
  std::string calibration_text_;
  std::filesystem::path calibration_file_;
  std::unique_ptr<reconstruct::Reconstructor> reconstructor_;  // null in thesis mode until Finish

  // Every stop's mask and angle (for the silhouette axis); thesis mode also keeps the frames.
  std::vector<cv::Mat> masks_;
  std::vector<cv::Mat> frames_;
  std::vector<double> angles_;
  std::optional<Expected<calibrate::SilhouetteAxis>> silhouette_axis_;
  bool axis_used_ = false;  // thesis mode: the silhouettes' line replaced the middle column
  double axis_column_px_ = 0.0;
  double axis_tilt_deg_ = 0.0;
  nlohmann::json volume_;  // thesis mode: the carving volume found
};

}  // namespace revolve::station
