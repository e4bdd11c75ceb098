#include "calibrate/axis.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>

#include "base/angles.h"

namespace revolve::calibrate {
namespace {

Eigen::Matrix3d Rz(double angle_rad) {
  return Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

Eigen::Matrix3d ExpRotation(const Eigen::Vector3d& omega) {
  const double angle = omega.norm();
  if (angle < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
}

// The rotation closest (Frobenius) to `m`.
Eigen::Matrix3d ProjectToRotation(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0.0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) *= -1.0;
    r = u * svd.matrixV().transpose();
  }
  return r;
}

// One corner seen at one stop, in ideal (undistorted) pixels.
struct Observation {
  int stop = 0;  // index into the used stops
  double angle_rad = 0.0;
  Eigen::Vector3d board_mm = Eigen::Vector3d::Zero();
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

struct Model {
  Eigen::Isometry3d cam_from_table = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d object_from_board = Eigen::Isometry3d::Identity();
};

Eigen::Vector2d Project(const Model& m, const Eigen::Matrix3d& k, const Observation& o) {
  const Eigen::Vector3d object = m.object_from_board * o.board_mm;
  const Eigen::Vector3d cam = m.cam_from_table * (Rz(o.angle_rad) * object);
  const Eigen::Vector3d h = k * cam;
  return h.head<2>() / h.z();
}

Eigen::VectorXd Residuals(const Model& m, const Eigen::Matrix3d& k,
                          const std::vector<Observation>& obs) {
  Eigen::VectorXd r(2 * obs.size());
  for (std::size_t i = 0; i < obs.size(); ++i) {
    r.segment<2>(2 * static_cast<Eigen::Index>(i)) = Project(m, k, obs[i]) - obs[i].pixel;
  }
  return r;
}

// Parameters: with the table free, 4 for cam_from_table (rotation about the table's x and y,
// translation along them: rotation about the axis and sliding along it are the gauge freedom of
// the model, fixed afterwards by convention) then 6 for object_from_board (rotation, translation
// in the object frame). Without, only the 6.
Model Apply(const Model& m, const Eigen::VectorXd& dx, bool table_free) {
  Model out = m;
  int i = 0;
  if (table_free) {
    Eigen::Isometry3d delta = Eigen::Isometry3d::Identity();
    delta.linear() = ExpRotation(Eigen::Vector3d(dx[0], dx[1], 0.0));
    delta.translation() = Eigen::Vector3d(dx[2], dx[3], 0.0);
    out.cam_from_table = m.cam_from_table * delta;
    i = 4;
  }
  Eigen::Isometry3d delta = Eigen::Isometry3d::Identity();
  delta.linear() = ExpRotation(Eigen::Vector3d(dx[i], dx[i + 1], dx[i + 2]));
  delta.translation() = Eigen::Vector3d(dx[i + 3], dx[i + 4], dx[i + 5]);
  out.object_from_board = delta * m.object_from_board;
  return out;
}

// Levenberg-Marquardt on the reprojection error, numeric central-difference Jacobian.
void Refine(Model* model, const Eigen::Matrix3d& k, const std::vector<Observation>& obs,
            bool table_free) {
  const int n = table_free ? 10 : 6;
  double lambda = 1e-3;
  Eigen::VectorXd r = Residuals(*model, k, obs);
  double cost = r.squaredNorm();
  for (int iteration = 0; iteration < 100; ++iteration) {
    Eigen::MatrixXd j(r.size(), n);
    for (int p = 0; p < n; ++p) {
      constexpr double kStep = 1e-6;
      Eigen::VectorXd dx = Eigen::VectorXd::Zero(n);
      dx[p] = kStep;
      const Eigen::VectorXd plus = Residuals(Apply(*model, dx, table_free), k, obs);
      dx[p] = -kStep;
      const Eigen::VectorXd minus = Residuals(Apply(*model, dx, table_free), k, obs);
      j.col(p) = (plus - minus) / (2.0 * kStep);
    }
    const Eigen::MatrixXd a = j.transpose() * j;
    const Eigen::VectorXd g = j.transpose() * r;
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::MatrixXd damped = a;
      damped.diagonal() += lambda * a.diagonal().cwiseMax(1e-9);
      const Eigen::VectorXd dx = damped.ldlt().solve(-g);
      const Model candidate = Apply(*model, dx, table_free);
      const Eigen::VectorXd r_new = Residuals(candidate, k, obs);
      const double cost_new = r_new.squaredNorm();
      if (cost_new < cost) {
        const double gain = cost - cost_new;
        *model = candidate;
        r = r_new;
        cost = cost_new;
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = true;
        if (gain < 1e-12 * (1.0 + cost) || dx.norm() < 1e-12) return;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) return;
  }
}

Eigen::Isometry3d ToIsometry(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) t.linear()(a, b) = r.at<double>(a, b);
    t.translation()[a] = tvec.at<double>(a);
  }
  return t;
}

std::vector<Observation> Observations(const std::vector<Detection>& detections,
                                      const std::vector<double>& angles_deg,
                                      const CameraModel& camera) {
  std::vector<Observation> obs;
  for (std::size_t s = 0; s < detections.size(); ++s) {
    const std::vector<cv::Point2f> ideal = camera.UndistortPixels(detections[s].image_px);
    for (std::size_t i = 0; i < ideal.size(); ++i) {
      const cv::Point3f& b = detections[s].board_mm[i];
      obs.push_back({static_cast<int>(s), Radians(angles_deg[s]), Eigen::Vector3d(b.x, b.y, b.z),
                     Eigen::Vector2d(ideal[i].x, ideal[i].y)});
    }
  }
  return obs;
}

// The rotation-averaged board placement given cam_from_table and the per-stop poses.
Eigen::Isometry3d AverageBoardOnTable(const Eigen::Isometry3d& cam_from_table,
                                      const std::vector<Eigen::Isometry3d>& cam_from_board,
                                      const std::vector<double>& angles_deg) {
  Eigen::Matrix3d rotation_sum = Eigen::Matrix3d::Zero();
  Eigen::Vector3d translation_sum = Eigen::Vector3d::Zero();
  for (std::size_t s = 0; s < cam_from_board.size(); ++s) {
    Eigen::Isometry3d table_from_object = Eigen::Isometry3d::Identity();
    table_from_object.linear() = Rz(Radians(angles_deg[s]));
    const Eigen::Isometry3d b =
        table_from_object.inverse() * cam_from_table.inverse() * cam_from_board[s];
    rotation_sum += b.linear();
    translation_sum += b.translation();
  }
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = ProjectToRotation(rotation_sum);
  out.translation() = translation_sum / static_cast<double>(cam_from_board.size());
  return out;
}

// Largest-gap complement: the angular range the angles cover on the circle.
double SpanDeg(std::vector<double> angles_deg) {
  if (angles_deg.size() < 2) return 0.0;
  for (double& a : angles_deg) {
    a = std::fmod(a, 360.0);
    if (a < 0.0) a += 360.0;
  }
  std::sort(angles_deg.begin(), angles_deg.end());
  double largest_gap = angles_deg.front() + 360.0 - angles_deg.back();
  for (std::size_t i = 1; i < angles_deg.size(); ++i) {
    largest_gap = std::max(largest_gap, angles_deg[i] - angles_deg[i - 1]);
  }
  return 360.0 - largest_gap;
}

// The closed-form start: axis direction, sign, a point on it, then the board placement.
Expected<Model> InitialModel(const std::vector<Eigen::Isometry3d>& poses,
                             const std::vector<double>& angles_deg) {
  const std::size_t n = poses.size();
  // R_k^T a is the same for every stop (the board's view of the axis): a minimises
  // sum_k |R_k^T a - mean|^2, the smallest eigenvector of sum (R_k - R_mean)(R_k - R_mean)^T.
  Eigen::Matrix3d mean = Eigen::Matrix3d::Zero();
  for (const Eigen::Isometry3d& p : poses) mean += p.linear();
  mean /= static_cast<double>(n);
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Isometry3d& p : poses) {
    const Eigen::Matrix3d d = p.linear() - mean;
    scatter += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
  if (!(eigen.eigenvalues()[1] > 1e-6 * static_cast<double>(n))) {
    return MakeError(ErrorCode::kBadInput,
                     "the board did not turn between the stops (all poses alike): is it fixed to "
                     "the plate, and did the plate move?");
  }
  Eigen::Vector3d axis = eigen.eigenvectors().col(0).normalized();
  // Sign: the commanded angles turn counter-clockwise about +axis.
  double sign = 0.0;
  for (std::size_t s = 1; s < n; ++s) {
    const double commanded = WrapDeg(angles_deg[s] - angles_deg[0]);
    if (std::abs(commanded) > 170.0) continue;
    const Eigen::AngleAxisd relative(poses[s].linear() * poses[0].linear().transpose());
    sign += relative.angle() * relative.axis().dot(axis) * commanded;
  }
  if (sign < 0.0) axis = -axis;

  // A point on the axis: the fixed points of the relative motions, (I - R) c = t, plus the
  // condition that c lies level with the boards' mean position (fixes the slide along the axis).
  Eigen::Vector3d mean_origin = Eigen::Vector3d::Zero();
  for (const Eigen::Isometry3d& p : poses) mean_origin += p.translation();
  mean_origin /= static_cast<double>(n);
  std::vector<Eigen::Matrix<double, 1, 3>> rows;
  std::vector<double> rhs;
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = a + 1; b < n; ++b) {
      const Eigen::Isometry3d motion = poses[b] * poses[a].inverse();
      const double angle = Eigen::AngleAxisd(motion.linear()).angle();
      if (angle < Radians(5.0)) continue;
      const Eigen::Matrix3d m = Eigen::Matrix3d::Identity() - motion.linear();
      for (int r = 0; r < 3; ++r) {
        rows.push_back(m.row(r));
        rhs.push_back(motion.translation()[r]);
      }
    }
  }
  rows.push_back(axis.transpose());
  rhs.push_back(axis.dot(mean_origin));
  Eigen::MatrixXd a_matrix(static_cast<Eigen::Index>(rows.size()), 3);
  Eigen::VectorXd b_vector(static_cast<Eigen::Index>(rows.size()));
  for (std::size_t r = 0; r < rows.size(); ++r) {
    a_matrix.row(static_cast<Eigen::Index>(r)) = rows[r];
    b_vector[static_cast<Eigen::Index>(r)] = rhs[r];
  }
  const Eigen::Vector3d centre = a_matrix.colPivHouseholderQr().solve(b_vector);

  Model model;
  Eigen::Vector3d x = Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX().dot(axis) * axis;
  if (x.norm() < 1e-3) x = Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY().dot(axis) * axis;
  x.normalize();
  model.cam_from_table.linear().col(0) = x;
  model.cam_from_table.linear().col(1) = axis.cross(x);
  model.cam_from_table.linear().col(2) = axis;
  model.cam_from_table.translation() = centre;
  model.object_from_board = AverageBoardOnTable(model.cam_from_table, poses, angles_deg);
  return model;
}

struct Statistics {
  double rms = 0.0;
  double max = 0.0;
};

Statistics Stats(const std::vector<double>& values) {
  Statistics s;
  if (values.empty()) return s;
  double sum = 0.0;
  for (double v : values) {
    sum += v * v;
    s.max = std::max(s.max, std::abs(v));
  }
  s.rms = std::sqrt(sum / static_cast<double>(values.size()));
  return s;
}

}  // namespace

std::string_view ToString(BoardPlacement placement) {
  switch (placement) {
    case BoardPlacement::kLying:
      return "lying";
    case BoardPlacement::kStanding:
      return "standing";
    case BoardPlacement::kTilted:
      return "tilted";
  }
  return "tilted";
}

Expected<BoardPose> EstimateBoardPose(const Detection& detection, const CameraModel& camera) {
  if (detection.size() < 4 || detection.board_mm.size() != detection.size()) {
    return MakeError(ErrorCode::kBadInput, "fewer than 4 corners: no board pose");
  }
  const cv::Mat k = camera.CameraMatrix();
  const cv::Mat d = camera.DistortionVector();
  cv::Mat rvec;
  cv::Mat tvec;
  try {
    if (!cv::solvePnP(detection.board_mm, detection.image_px, k, d, rvec, tvec, false,
                      cv::SOLVEPNP_IPPE)) {
      return MakeError(ErrorCode::kBadInput, "solvePnP found no board pose");
    }
    cv::solvePnPRefineLM(detection.board_mm, detection.image_px, k, d, rvec, tvec);
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kBadInput, fmt::format("solvePnP failed: {}", e.err));
  }
  std::vector<cv::Point2f> projected;
  cv::projectPoints(detection.board_mm, rvec, tvec, k, d, projected);
  double sum = 0.0;
  for (std::size_t i = 0; i < projected.size(); ++i) {
    const cv::Point2f e = projected[i] - detection.image_px[i];
    sum += e.dot(e);
  }
  BoardPose pose;
  pose.cam_from_board = ToIsometry(rvec, tvec);
  pose.rms_px = std::sqrt(sum / static_cast<double>(projected.size()));
  return pose;
}

Expected<AxisResult> CalibrateAxis(const std::vector<StopDetection>& stops,
                                   const CameraModel& camera, const Board& board,
                                   const AxisOptions& options) {
  if (auto valid = board.Validate(); !valid) return std::unexpected(valid.error());
  if (!board.OrientationUnique()) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("axis calibration: a chessboard of {}x{} inner corners looks the "
                                 "same turned by 180 deg, so its stops cannot be compared; use one "
                                 "with an odd and an even count (e.g. 9x6) or a ChArUco board",
                                 board.cols, board.rows));
  }
  AxisResult result;
  std::vector<Detection> detections;
  std::vector<Eigen::Isometry3d> poses;
  std::vector<double> angles;
  std::vector<std::size_t> used_index;
  std::string problems;
  for (std::size_t s = 0; s < stops.size(); ++s) {
    StopReport report;
    report.angle_deg = stops[s].angle_deg;
    if (!stops[s].detection) {
      report.problem = stops[s].detection.error().message;
    } else if (Expected<BoardPose> pose = EstimateBoardPose(*stops[s].detection, camera); !pose) {
      report.problem = pose.error().message;
    } else {
      report.used = true;
      detections.push_back(*stops[s].detection);
      poses.push_back(pose->cam_from_board);
      angles.push_back(stops[s].angle_deg);
      used_index.push_back(s);
    }
    if (!report.used && problems.size() < 400) {
      problems += fmt::format("; stop at {:g} deg: {}", report.angle_deg, report.problem);
    }
    result.stops.push_back(std::move(report));
  }
  result.stops_used = static_cast<int>(poses.size());
  result.span_deg = SpanDeg(angles);
  if (result.stops_used < std::max(2, options.min_stops)) {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("axis calibration refused: the board was found at {} of {} stops "
                    "(need {}: lay the board flat on the plate, fully in view at "
                    "every stop){}",
                    result.stops_used, stops.size(), std::max(2, options.min_stops), problems));
  }
  if (result.span_deg < options.min_span_deg) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("axis calibration refused: the stops with the board span {:.0f} "
                                 "deg of the turn (need {:.0f} deg: turn through more stops, or "
                                 "lay the board flat so that it stays in view)",
                                 result.span_deg, options.min_span_deg));
  }

  Expected<Model> initial = InitialModel(poses, angles);
  if (!initial) return std::unexpected(initial.error());
  Model model = *initial;
  const std::vector<Observation> obs = Observations(detections, angles, camera);
  const Eigen::Matrix3d k = camera.intrinsics.K();
  Refine(&model, k, obs, /*table_free=*/true);

  // Convention (axis.h): placement, origin height, x axis.
  const Eigen::Vector3d board_normal_object = model.object_from_board.linear().col(2);
  const double normal_z = std::abs(board_normal_object.z());
  if (normal_z > std::cos(Radians(20.0))) {
    result.placement = BoardPlacement::kLying;
  } else if (normal_z < std::sin(Radians(20.0))) {
    result.placement = BoardPlacement::kStanding;
  } else {
    result.placement = BoardPlacement::kTilted;
  }
  double lowest = 1e300;
  for (int id = 0; id < board.CornerCount(); ++id) {
    lowest = std::min(lowest, (model.object_from_board * board.Corner(id)).z());
  }
  const double height = options.board_height_mm.value_or(
      result.placement == BoardPlacement::kLying ? 0.0 : board.square_mm);
  const Eigen::Vector3d axis = model.cam_from_table.linear().col(2);
  Eigen::Vector3d x_cam = Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX().dot(axis) * axis;
  if (x_cam.norm() < 1e-3) {
    x_cam = Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY().dot(axis) * axis;
  }
  const Eigen::Vector3d x_table = model.cam_from_table.linear().transpose() * x_cam.normalized();
  Eigen::Isometry3d gauge = Eigen::Isometry3d::Identity();  // commutes with every Rz(theta)
  gauge.linear() = Rz(std::atan2(x_table.y(), x_table.x()));
  gauge.translation() = Eigen::Vector3d(0.0, 0.0, lowest - height);
  model.cam_from_table = model.cam_from_table * gauge;
  model.object_from_board = gauge.inverse() * model.object_from_board;
  result.cam_from_table = model.cam_from_table;
  result.object_from_board = model.object_from_board;

  // Residuals.
  const Eigen::VectorXd r = Residuals(model, k, obs);
  std::vector<double> all_px;
  std::vector<std::vector<double>> stop_px(poses.size());
  for (std::size_t i = 0; i < obs.size(); ++i) {
    const double e = r.segment<2>(2 * static_cast<Eigen::Index>(i)).norm();
    all_px.push_back(e);
    stop_px[static_cast<std::size_t>(obs[i].stop)].push_back(e);
  }
  const Statistics px = Stats(all_px);
  result.reprojection_rms_px = px.rms;
  result.reprojection_max_px = px.max;
  std::vector<double> all_mm;
  std::vector<double> angle_errors;
  std::vector<double> wobble;
  for (std::size_t s = 0; s < poses.size(); ++s) {
    Eigen::Isometry3d table_from_object = Eigen::Isometry3d::Identity();
    table_from_object.linear() = Rz(Radians(angles[s]));
    const Eigen::Isometry3d predicted =
        model.cam_from_table * table_from_object * model.object_from_board;
    std::vector<double> mm;
    for (const cv::Point3f& b : detections[s].board_mm) {
      const Eigen::Vector3d p(b.x, b.y, b.z);
      mm.push_back((poses[s] * p - predicted * p).norm());
      all_mm.push_back(mm.back());
    }
    // The plate turn the board saw: table_from_object it implies, vs Rz(commanded).
    const Eigen::Matrix3d seen = model.cam_from_table.linear().transpose() * poses[s].linear() *
                                 model.object_from_board.linear().transpose();
    const Eigen::Matrix3d deviation = table_from_object.linear().transpose() * seen;
    const double angle_error = Degrees(std::atan2(deviation(1, 0), deviation(0, 0)));
    angle_errors.push_back(angle_error);
    wobble.push_back(Degrees(std::acos(std::clamp(deviation(2, 2), -1.0, 1.0))));
    StopReport& report = result.stops[used_index[s]];
    report.reprojection_rms_px = Stats(stop_px[s]).rms;
    report.corner_rms_mm = Stats(mm).rms;
    report.angle_error_deg = angle_error;
  }
  const Statistics mm = Stats(all_mm);
  result.corner_rms_mm = mm.rms;
  result.corner_max_mm = mm.max;
  result.angle_rms_deg = Stats(angle_errors).rms;
  result.wobble_deg = Stats(wobble).rms;

  if (!(result.reprojection_rms_px <= options.max_reprojection_rms_px)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("axis calibration refused: RMS reprojection error {:.2f} px > "
                                 "{:.2f} px (did the board slip on the plate, do the plate's "
                                 "angles match the commanded ones, is the lens calibration this "
                                 "camera's?)",
                                 result.reprojection_rms_px, options.max_reprojection_rms_px));
  }
  // Does +z point up in the image?
  const Eigen::Vector3d o = k * result.cam_from_table.translation();
  const Eigen::Vector3d up = k * (result.cam_from_table * Eigen::Vector3d(0.0, 0.0, 50.0));
  if (o.z() > 0.0 && up.z() > 0.0 && up.y() / up.z() > o.y() / o.z()) {
    result.warnings.push_back(
        "the axis's +z points down in the image: increasing plate angles turn clockwise seen "
        "from above (check the drive's direction) or the camera is upside down");
  }
  if (result.angle_rms_deg > 0.2) {
    result.warnings.push_back(fmt::format(
        "the plate's angles differ from the commanded ones by {:.2f} deg RMS (backlash, a "
        "slipping belt or a wrong step angle?)",
        result.angle_rms_deg));
  }
  return result;
}

Expected<AxisResult> CalibrateAxisFromImages(const std::vector<cv::Mat>& images,
                                             const std::vector<double>& angles_deg,
                                             const CameraModel& camera, const Board& board,
                                             const AxisOptions& options,
                                             const DetectOptions& detect) {
  if (images.size() != angles_deg.size()) {
    return MakeError(ErrorCode::kBadInput, fmt::format("axis calibration: {} images but {} angles",
                                                       images.size(), angles_deg.size()));
  }
  std::vector<StopDetection> stops;
  stops.reserve(images.size());
  for (std::size_t i = 0; i < images.size(); ++i) {
    stops.push_back({angles_deg[i], DetectBoard(images[i], board, detect)});
  }
  return CalibrateAxis(stops, camera, board, options);
}

Expected<BoardOnTable> FitBoardOnTable(const std::vector<StopDetection>& stops,
                                       const CameraModel& camera,
                                       const Eigen::Isometry3d& cam_from_table) {
  std::vector<Detection> detections;
  std::vector<Eigen::Isometry3d> poses;
  std::vector<double> angles;
  for (const StopDetection& stop : stops) {
    if (!stop.detection) continue;
    Expected<BoardPose> pose = EstimateBoardPose(*stop.detection, camera);
    if (!pose) continue;
    detections.push_back(*stop.detection);
    poses.push_back(pose->cam_from_board);
    angles.push_back(stop.angle_deg);
  }
  if (poses.empty()) {
    return MakeError(ErrorCode::kBadInput, "the board was found at none of the stops");
  }
  Model model;
  model.cam_from_table = cam_from_table;
  model.object_from_board = AverageBoardOnTable(cam_from_table, poses, angles);
  const std::vector<Observation> obs = Observations(detections, angles, camera);
  const Eigen::Matrix3d k = camera.intrinsics.K();
  Refine(&model, k, obs, /*table_free=*/false);
  const Eigen::VectorXd r = Residuals(model, k, obs);
  std::vector<double> errors;
  for (Eigen::Index i = 0; i < r.size() / 2; ++i) errors.push_back(r.segment<2>(2 * i).norm());
  const Statistics s = Stats(errors);
  BoardOnTable out;
  out.object_from_board = model.object_from_board;
  out.reprojection_rms_px = s.rms;
  out.reprojection_max_px = s.max;
  out.stops_used = static_cast<int>(poses.size());
  return out;
}

}  // namespace revolve::calibrate
