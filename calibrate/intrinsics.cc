#include "calibrate/intrinsics.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "base/angles.h"

namespace revolve::calibrate {
namespace {

std::string JoinProblems(const std::vector<ViewReport>& views) {
  std::string out;
  int listed = 0;
  for (const ViewReport& v : views) {
    if (v.used) continue;
    if (listed == 5) {
      out += "; ...";
      break;
    }
    out += fmt::format("{}{}: {}", listed == 0 ? "" : "; ", v.name, v.problem);
    ++listed;
  }
  return out;
}

}  // namespace

double Coverage(const std::vector<Detection>& detections, int width_px, int height_px) {
  if (width_px <= 0 || height_px <= 0) return 0.0;
  // A grid of about 64 cells across the longer side.
  const double cell_px = std::max(width_px, height_px) / 64.0;
  const int gw = std::max(1, static_cast<int>(std::ceil(width_px / cell_px)));
  const int gh = std::max(1, static_cast<int>(std::ceil(height_px / cell_px)));
  cv::Mat grid = cv::Mat::zeros(gh, gw, CV_8UC1);
  for (const Detection& d : detections) {
    if (d.image_px.size() < 3) continue;
    std::vector<cv::Point2f> hull;
    cv::convexHull(d.image_px, hull);
    std::vector<cv::Point> cells;
    cells.reserve(hull.size());
    for (const cv::Point2f& p : hull) {
      cells.emplace_back(static_cast<int>(std::lround((p.x + 0.5) / cell_px - 0.5)),
                         static_cast<int>(std::lround((p.y + 0.5) / cell_px - 0.5)));
    }
    cv::fillConvexPoly(grid, cells, cv::Scalar(255));
  }
  return static_cast<double>(cv::countNonZero(grid)) / (static_cast<double>(gw) * gh);
}

Expected<IntrinsicsResult> CalibrateIntrinsics(const std::vector<ViewDetection>& views,
                                               int image_width_px, int image_height_px,
                                               const IntrinsicsOptions& options) {
  if (image_width_px <= 0 || image_height_px <= 0) {
    return MakeError(ErrorCode::kBadInput, "CalibrateIntrinsics: image size must be positive");
  }
  IntrinsicsResult result;
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  std::vector<Detection> used;
  std::vector<std::size_t> used_index;
  for (std::size_t i = 0; i < views.size(); ++i) {
    ViewReport report;
    report.name = views[i].name.empty() ? fmt::format("view {}", i) : views[i].name;
    if (!views[i].detection) {
      report.problem = views[i].detection.error().message;
    } else if (views[i].detection->size() < 4) {
      report.problem = "fewer than 4 corners";
    } else {
      report.used = true;
      object_points.push_back(views[i].detection->board_mm);
      image_points.push_back(views[i].detection->image_px);
      used.push_back(*views[i].detection);
      used_index.push_back(i);
    }
    result.views.push_back(std::move(report));
  }
  result.views_used = static_cast<int>(used.size());
  if (used.size() < 3) {
    std::string problems = JoinProblems(result.views);
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("calibration refused: the board was found in {} of {} views (need "
                                 "at least {}){}{}",
                                 used.size(), views.size(), std::max(3, options.min_views),
                                 problems.empty() ? "" : ": ", problems));
  }

  int flags = 0;
  if (!options.estimate_k3) flags |= cv::CALIB_FIX_K3;
  if (!options.estimate_tangential) flags |= cv::CALIB_ZERO_TANGENT_DIST;
  cv::Mat k;
  cv::Mat d;
  std::vector<cv::Mat> rvecs;
  std::vector<cv::Mat> tvecs;
  cv::Mat std_intrinsics;
  cv::Mat std_extrinsics;
  cv::Mat per_view;
  try {
    result.rms_px = cv::calibrateCamera(
        object_points, image_points, cv::Size(image_width_px, image_height_px), k, d, rvecs, tvecs,
        std_intrinsics, std_extrinsics, per_view, flags,
        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("calibration failed in OpenCV: {} (are the views all of the same, "
                                 "flat board?)",
                                 e.err));
  }
  CameraModel& camera = result.camera;
  camera.intrinsics.width_px = image_width_px;
  camera.intrinsics.height_px = image_height_px;
  camera.intrinsics.fx_px = k.at<double>(0, 0);
  camera.intrinsics.fy_px = k.at<double>(1, 1);
  camera.intrinsics.cx_px = k.at<double>(0, 2);
  camera.intrinsics.cy_px = k.at<double>(1, 2);
  camera.distortion.assign(d.begin<double>(), d.begin<double>() + std::min<int>(5, d.total()));
  result.fx_std_px = std_intrinsics.at<double>(0);
  result.fy_std_px = std_intrinsics.at<double>(1);
  result.cx_std_px = std_intrinsics.at<double>(2);
  result.cy_std_px = std_intrinsics.at<double>(3);

  std::vector<Eigen::Vector3d> normals;
  for (std::size_t u = 0; u < used.size(); ++u) {
    cv::Mat r;
    cv::Rodrigues(rvecs[u], r);
    const Eigen::Vector3d normal(r.at<double>(0, 2), r.at<double>(1, 2), r.at<double>(2, 2));
    normals.push_back(normal);
    ViewReport& report = result.views[used_index[u]];
    report.rms_px = per_view.at<double>(static_cast<int>(u));
    report.tilt_deg = Degrees(std::acos(std::clamp(std::abs(normal.z()), 0.0, 1.0)));
    report.distance_mm = cv::norm(tvecs[u]);
  }
  for (std::size_t a = 0; a < normals.size(); ++a) {
    for (std::size_t b = a + 1; b < normals.size(); ++b) {
      const double angle = Degrees(std::acos(std::clamp(normals[a].dot(normals[b]), -1.0, 1.0)));
      result.tilt_spread_deg = std::max(result.tilt_spread_deg, angle);
    }
  }
  result.coverage = Coverage(used, image_width_px, image_height_px);

  std::vector<std::string> reasons;
  if (result.views_used < options.min_views) {
    reasons.push_back(
        fmt::format("the board was found in only {} of {} views (need {}: capture "
                    "more, moving and tilting the board between views)",
                    result.views_used, views.size(), options.min_views));
  }
  if (result.coverage < options.min_coverage) {
    reasons.push_back(
        fmt::format("the boards cover {:.0f} % of the image (need {:.0f} %: show the "
                    "board near the image's edges and corners too)",
                    100.0 * result.coverage, 100.0 * options.min_coverage));
  }
  if (result.tilt_spread_deg < options.min_tilt_spread_deg) {
    reasons.push_back(
        fmt::format("the board's orientations differ by at most {:.1f} deg (need "
                    "{:.0f} deg: tilt the board about 30 deg left, right, up and "
                    "down; facing the camera square on, the focal length cannot be "
                    "measured)",
                    result.tilt_spread_deg, options.min_tilt_spread_deg));
  }
  if (!(result.rms_px <= options.max_rms_px)) {
    reasons.push_back(
        fmt::format("RMS reprojection error {:.3f} px > {:.3f} px (blurred or "
                    "moving views, a board that is not flat, or a wrong square "
                    "count; worst views: see the per-view errors)",
                    result.rms_px, options.max_rms_px));
  }
  if (!reasons.empty()) {
    std::string message = "calibration refused: ";
    for (std::size_t i = 0; i < reasons.size(); ++i) {
      if (i > 0) message += "; ";
      message += reasons[i];
    }
    return MakeError(ErrorCode::kBadInput, message);
  }
  return result;
}

Expected<IntrinsicsResult> CalibrateIntrinsicsFromImages(const std::vector<cv::Mat>& images,
                                                         const std::vector<std::string>& names,
                                                         const Board& board,
                                                         const IntrinsicsOptions& options,
                                                         const DetectOptions& detect) {
  if (auto valid = board.Validate(); !valid) return std::unexpected(valid.error());
  if (images.empty()) return MakeError(ErrorCode::kBadInput, "calibration refused: no images");
  const cv::Size size = images.front().size();
  std::vector<ViewDetection> views;
  views.reserve(images.size());
  for (std::size_t i = 0; i < images.size(); ++i) {
    std::string name = i < names.size() ? names[i] : fmt::format("image {}", i);
    if (images[i].size() != size) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("{}: {}x{} pixels, but the first image is {}x{}: calibrate one "
                                   "camera mode at a time",
                                   name, images[i].cols, images[i].rows, size.width, size.height));
    }
    views.push_back({std::move(name), DetectBoard(images[i], board, detect)});
  }
  return CalibrateIntrinsics(views, size.width, size.height, options);
}

}  // namespace revolve::calibrate
