#include "reconstruct/cameras/camera_export.h"

#include <cmath>

#include <fmt/format.h>
#include <Eigen/QR>

namespace revolve::reconstruct {
namespace {

// COLMAP's and nerfstudio's pixel coordinates put the image's corner at 0; revolve's the top-left
// pixel's centre.
constexpr double kCornerFromCentrePx = 0.5;

// Enough digits that a pose or a focal length reads back to within 1e-12 of itself.
std::string Number(double value) { return fmt::format("{:.17g}", value); }

}  // namespace

Expected<PinholeView> DecomposeView(const View& view) {
  if (view.IsAffine()) {
    return MakeError(ErrorCode::kBadInput,
                     "the view is orthographic (affine): photogrammetry tools need pinhole "
                     "cameras");
  }
  const Eigen::Matrix3d m = view.pixel_from_object.leftCols<3>();
  // RQ decomposition m = K R through the QR decomposition of the row-reversed, transposed m.
  Eigen::Matrix3d reverse = Eigen::Matrix3d::Zero();
  reverse(0, 2) = reverse(1, 1) = reverse(2, 0) = 1.0;
  const Eigen::HouseholderQR<Eigen::Matrix3d> qr((reverse * m).transpose());
  const Eigen::Matrix3d q = qr.householderQ();
  const Eigen::Matrix3d upper = qr.matrixQR().triangularView<Eigen::Upper>();
  Eigen::Matrix3d k = reverse * upper.transpose() * reverse;
  Eigen::Matrix3d r = reverse * q.transpose();
  for (int i = 0; i < 3; ++i) {
    if (k(i, i) < 0.0) {
      k.col(i) *= -1.0;
      r.row(i) *= -1.0;
    }
  }
  if (!(k(2, 2) > 0.0) || !k.allFinite()) {
    return MakeError(ErrorCode::kBadInput, "the view's projection matrix is degenerate");
  }
  if (r.determinant() < 0.0) {
    return MakeError(ErrorCode::kBadInput,
                     "the view is mirrored (its rotation has determinant -1): no camera pose");
  }
  const double scale = k(2, 2);
  k /= scale;
  if (std::abs(k(0, 1)) > 1e-6 * k(0, 0)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("the view's camera has skew {:.3g} px: COLMAP's camera models "
                                 "have none",
                                 k(0, 1)));
  }
  PinholeView out;
  out.intrinsics.fx_px = k(0, 0);
  out.intrinsics.fy_px = k(1, 1);
  out.intrinsics.cx_px = k(0, 2);
  out.intrinsics.cy_px = k(1, 2);
  out.intrinsics.width_px = view.width_px;
  out.intrinsics.height_px = view.height_px;
  out.cam_from_object.linear() = r;
  out.cam_from_object.translation() = k.inverse() * view.pixel_from_object.col(3) / scale;
  return out;
}

std::string ColmapMaskName(const std::string& image_name) { return image_name + ".png"; }

std::string ColmapCamerasText(const PinholeCamera& camera) {
  const Intrinsics& in = camera.intrinsics;
  std::string text =
      "# Camera list with one line of data per camera:\n"
      "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      "# Number of cameras: 1\n";
  const std::string common = fmt::format(
      "{} {} {} {} {} {}", in.width_px, in.height_px, Number(in.fx_px), Number(in.fy_px),
      Number(in.cx_px + kCornerFromCentrePx), Number(in.cy_px + kCornerFromCentrePx));
  if (camera.HasDistortion()) {
    text += fmt::format("1 OPENCV {} {} {} {} {}\n", common, Number(camera.k1), Number(camera.k2),
                        Number(camera.p1), Number(camera.p2));
  } else {
    text += fmt::format("1 PINHOLE {}\n", common);
  }
  return text;
}

std::string ColmapImagesText(const std::vector<PosedImage>& images) {
  std::string text = fmt::format(
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      "# Number of images: {}, mean observations per image: 0\n",
      images.size());
  for (std::size_t i = 0; i < images.size(); ++i) {
    Eigen::Quaterniond q(images[i].cam_from_object.rotation());
    q.normalize();
    if (q.w() < 0.0) q.coeffs() *= -1.0;
    const Eigen::Vector3d t = images[i].cam_from_object.translation();
    text += fmt::format("{} {} {} {} {} {} {} {} 1 {}\n\n", i + 1, Number(q.w()), Number(q.x()),
                        Number(q.y()), Number(q.z()), Number(t.x()), Number(t.y()), Number(t.z()),
                        images[i].name);
  }
  return text;
}

std::string ColmapEmptyPointsText() {
  return "# 3D point list with one line of data per point:\n"
         "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
         "# Number of points: 0, mean track length: 0\n";
}

nlohmann::json NerfstudioTransforms(const PinholeCamera& camera,
                                    const std::vector<PosedImage>& images) {
  const Intrinsics& in = camera.intrinsics;
  nlohmann::json out = {{"camera_model", "OPENCV"},
                        {"fl_x", in.fx_px},
                        {"fl_y", in.fy_px},
                        {"cx", in.cx_px + kCornerFromCentrePx},
                        {"cy", in.cy_px + kCornerFromCentrePx},
                        {"w", in.width_px},
                        {"h", in.height_px},
                        {"k1", camera.k1},
                        {"k2", camera.k2},
                        {"p1", camera.p1},
                        {"p2", camera.p2}};
  // OpenCV camera axes to OpenGL's: y and z negated.
  const Eigen::Matrix4d gl_from_cv = Eigen::Vector4d(1.0, -1.0, -1.0, 1.0).asDiagonal();
  nlohmann::json frames = nlohmann::json::array();
  for (const PosedImage& image : images) {
    const Eigen::Matrix4d object_from_cam = image.cam_from_object.inverse().matrix() * gl_from_cv;
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) {
      rows.push_back({object_from_cam(r, 0), object_from_cam(r, 1), object_from_cam(r, 2),
                      object_from_cam(r, 3)});
    }
    nlohmann::json frame = {{"file_path", "images/" + image.name}, {"transform_matrix", rows}};
    if (!image.mask_name.empty()) frame["mask_path"] = "masks/" + image.mask_name;
    frames.push_back(frame);
  }
  out["frames"] = frames;
  return out;
}

}  // namespace revolve::reconstruct
