#include "calibrate/board_render.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace revolve::calibrate {
namespace {

// Lens distortion applied to a supersampled ideal image: for every output pixel, where its ray
// lands in the ideal image. The map is computed on a coarse grid (the distortion field is smooth)
// and interpolated.
cv::Mat Distort(const cv::Mat& ideal_ss, const CameraModel& camera, int s, int background) {
  constexpr int kGrid = 4;
  const int w = ideal_ss.cols;
  const int h = ideal_ss.rows;
  const int gw = (w + kGrid - 1) / kGrid;
  const int gh = (h + kGrid - 1) / kGrid;
  const double half_s = 0.5 * (s - 1);
  std::vector<cv::Point2f> nodes;
  nodes.reserve(static_cast<std::size_t>(gw) * gh);
  for (int j = 0; j < gh; ++j) {
    for (int i = 0; i < gw; ++i) {
      // Grid node (i, j) sits at the centre of its kGrid x kGrid block of supersampled pixels.
      const double qx = kGrid * i + 0.5 * (kGrid - 1);
      const double qy = kGrid * j + 0.5 * (kGrid - 1);
      nodes.emplace_back(static_cast<float>((qx - half_s) / s),
                         static_cast<float>((qy - half_s) / s));
    }
  }
  const std::vector<cv::Point2f> ideal = camera.UndistortPixels(nodes);
  cv::Mat map_x(gh, gw, CV_32F);
  cv::Mat map_y(gh, gw, CV_32F);
  for (int j = 0; j < gh; ++j) {
    for (int i = 0; i < gw; ++i) {
      const cv::Point2f& p = ideal[static_cast<std::size_t>(j) * gw + i];
      map_x.at<float>(j, i) = static_cast<float>(s * p.x + half_s);
      map_y.at<float>(j, i) = static_cast<float>(s * p.y + half_s);
    }
  }
  // resize's pixel-centre alignment maps output pixel x to grid coordinate (x + 0.5) / kGrid - 0.5,
  // i.e. exactly back to supersampled pixel x.
  cv::Mat full_x;
  cv::Mat full_y;
  cv::resize(map_x, full_x, cv::Size(gw * kGrid, gh * kGrid), 0, 0, cv::INTER_LINEAR);
  cv::resize(map_y, full_y, cv::Size(gw * kGrid, gh * kGrid), 0, 0, cv::INTER_LINEAR);
  const cv::Rect roi(0, 0, w, h);
  cv::Mat out;
  cv::remap(ideal_ss, out, full_x(roi), full_y(roi), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            cv::Scalar(background));
  return out;
}

}  // namespace

Expected<cv::Mat> RenderBoard(const CameraModel& camera, const Eigen::Isometry3d& cam_from_board,
                              const Board& board, const BoardRenderOptions& options) {
  if (auto valid = board.Validate(); !valid) return std::unexpected(valid.error());
  const Intrinsics& in = camera.intrinsics;
  if (in.width_px <= 0 || in.height_px <= 0 || options.supersample < 1 || options.supersample > 8) {
    return MakeError(ErrorCode::kBadInput, "RenderBoard: bad image size or supersample");
  }
  const int s = options.supersample;
  const double margin_mm = options.margin_mm < 0.0 ? 0.5 * board.square_mm : options.margin_mm;

  // The paper's corners must lie in front of the camera (a homography cannot clip).
  const std::array<Eigen::Vector3d, 4> paper = {
      Eigen::Vector3d(-board.square_mm - margin_mm, -board.square_mm - margin_mm, 0.0),
      Eigen::Vector3d(board.cols * board.square_mm + margin_mm, -board.square_mm - margin_mm, 0.0),
      Eigen::Vector3d(-board.square_mm - margin_mm, board.rows * board.square_mm + margin_mm, 0.0),
      Eigen::Vector3d(board.cols * board.square_mm + margin_mm,
                      board.rows * board.square_mm + margin_mm, 0.0)};
  double nearest_mm = 1e300;
  for (const Eigen::Vector3d& corner : paper) {
    const double z = (cam_from_board * corner).z();
    if (!(z > 1.0)) {
      return MakeError(ErrorCode::kBadInput,
                       "RenderBoard: the board reaches behind the camera (z <= 1 mm)");
    }
    nearest_mm = std::min(nearest_mm, z);
  }
  // Texture resolution: about the finest scale of the supersampled rendering on the board.
  double px_per_mm = options.texture_px_per_mm;
  if (!(px_per_mm > 0.0)) {
    px_per_mm = std::clamp(s * std::max(in.fx_px, in.fy_px) / nearest_mm, 2.0, 24.0);
  }
  Expected<BoardImage> texture = DrawBoard(board, px_per_mm, margin_mm, /*antialias=*/true);
  if (!texture) return std::unexpected(texture.error());
  cv::Mat paper_image;
  const double contrast = (options.paper_grey - options.ink_grey) / 255.0;
  texture->image.convertTo(paper_image, CV_8U, contrast, options.ink_grey);
  // The camera sees the printed face when the board's z (into the print) points away from it.
  const Eigen::Vector3d z_board = cam_from_board.linear().col(2);
  if (z_board.dot(cam_from_board.translation()) <= 0.0) {
    paper_image.setTo(cv::Scalar(options.paper_grey));
  }

  // Supersampled pixel q = s * p + (s - 1) / 2 for pixel p of the final image.
  Eigen::Matrix3d supersample = Eigen::Matrix3d::Identity();
  supersample(0, 0) = supersample(1, 1) = s;
  supersample(0, 2) = supersample(1, 2) = 0.5 * (s - 1);
  Eigen::Matrix3d plane;  // board plane (X, Y, 1) -> camera
  plane.col(0) = cam_from_board.linear().col(0);
  plane.col(1) = cam_from_board.linear().col(1);
  plane.col(2) = cam_from_board.translation();
  const Eigen::Matrix3d image_from_texture =
      supersample * in.K() * plane * texture->board_from_image;
  cv::Mat h(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) h.at<double>(r, c) = image_from_texture(r, c);
  }
  cv::Mat ideal(in.height_px * s, in.width_px * s, CV_8UC1, cv::Scalar(options.background_grey));
  cv::warpPerspective(paper_image, ideal, h, ideal.size(), cv::INTER_LINEAR,
                      cv::BORDER_TRANSPARENT);
  if (camera.HasDistortion()) ideal = Distort(ideal, camera, s, options.background_grey);

  cv::Mat image;
  if (s > 1) {
    cv::resize(ideal, image, cv::Size(in.width_px, in.height_px), 0, 0, cv::INTER_AREA);
  } else {
    image = ideal;
  }
  cv::Mat image_f;
  image.convertTo(image_f, CV_32F);
  if (options.blur_sigma_px > 0.0) {
    cv::GaussianBlur(image_f, image_f, cv::Size(0, 0), options.blur_sigma_px);
  }
  if (options.noise_sigma > 0.0) {
    cv::Mat noise(image_f.size(), CV_32F);
    cv::RNG rng(options.seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, options.noise_sigma);
    image_f += noise;
  }
  image_f.convertTo(image, CV_8U);  // saturating
  cv::Mat bgr;
  cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

Expected<cv::Mat> RenderBoardOnTable(const Rig& rig, const std::vector<double>& distortion,
                                     double plate_angle_deg,
                                     const Eigen::Isometry3d& object_from_board, const Board& board,
                                     const BoardRenderOptions& options) {
  const CameraModel camera{rig.intrinsics, distortion};
  return RenderBoard(camera, rig.CamFromObject(plate_angle_deg) * object_from_board, board,
                     options);
}

}  // namespace revolve::calibrate
