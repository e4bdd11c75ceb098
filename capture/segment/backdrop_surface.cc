#include "capture/segment/backdrop_surface.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include <Eigen/Cholesky>
#include <opencv2/imgproc.hpp>

#include "base/mask_rect.h"

namespace revolve::capture {

std::vector<cv::Point> RectOutline(const cv::Rect& box) {
  std::vector<cv::Point> points;
  if (box.width <= 0 || box.height <= 0) return points;
  for (int x = box.x; x < box.x + box.width; ++x) {
    points.emplace_back(x, box.y);
    if (box.height > 1) points.emplace_back(x, box.y + box.height - 1);
  }
  for (int y = box.y + 1; y + 1 < box.y + box.height; ++y) {
    points.emplace_back(box.x, y);
    if (box.width > 1) points.emplace_back(box.x + box.width - 1, y);
  }
  return points;
}

cv::Rect RoiBox(cv::Size size, const cv::Mat& roi) {
  const cv::Rect box = roi.empty() ? cv::Rect() : MaskRect(roi);
  return box.area() == 0 ? cv::Rect(cv::Point(), size) : box;
}

BackdropSurface::Terms BackdropSurface::TermsAt(double u, double v) {
  Terms terms;
  terms << 1.0, u, v, u * u, v * v, u * v;
  return terms;
}

std::optional<BackdropSurface> BackdropSurface::FitToOutline(const cv::Mat& bgr,
                                                             const cv::Rect& box) {
  const std::vector<cv::Point> points = RectOutline(box & cv::Rect(0, 0, bgr.cols, bgr.rows));
  if (points.size() < 16) return std::nullopt;
  BackdropSurface surface;
  const cv::Rect ring = cv::boundingRect(points);
  surface.cx_ = ring.x + 0.5 * (ring.width - 1);
  surface.cy_ = ring.y + 0.5 * (ring.height - 1);
  surface.sx_ = std::max(1.0, 0.5 * (ring.width - 1));
  surface.sy_ = std::max(1.0, 0.5 * (ring.height - 1));
  std::vector<Terms> terms;
  terms.reserve(points.size());
  for (const cv::Point& p : points) {
    terms.push_back(TermsAt((p.x - surface.cx_) / surface.sx_, (p.y - surface.cy_) / surface.sy_));
  }
  std::vector<double> residuals(points.size());
  using Normal = Eigen::Matrix<double, 6, 6>;
  // The normal matrix's lower triangle, summed point by point in order (each element as the
  // whole outer product's would be), then mirrored. The first round takes every point: one
  // matrix for the three channels.
  const auto add = [](Normal* normal, const Terms& t) {
    for (int b = 0; b < 6; ++b) {
      for (int a = b; a < 6; ++a) (*normal)(a, b) += t(a) * t(b);
    }
  };
  const auto mirrored = [](Normal normal) {
    normal.triangularView<Eigen::StrictlyUpper>() = normal.transpose();
    return normal;
  };
  Normal every_point = Normal::Zero();
  for (const Terms& t : terms) add(&every_point, t);
  every_point = mirrored(every_point);
  for (int c = 0; c < 3; ++c) {
    Terms fit = Terms::Zero();
    double limit = std::numeric_limits<double>::infinity();
    for (int round = 0; round < 3; ++round) {
      Normal normal = Normal::Zero();
      Terms rhs = Terms::Zero();
      for (std::size_t i = 0; i < points.size(); ++i) {
        const double value = bgr.at<cv::Vec3b>(points[i])[c];
        if (round > 0 && std::abs(value - fit.dot(terms[i])) > limit) continue;
        if (round > 0) add(&normal, terms[i]);
        rhs += value * terms[i];
      }
      if (round == 0) {
        normal = every_point;
      } else {
        normal = mirrored(normal);
      }
      const Terms next = normal.ldlt().solve(rhs);
      if (!next.allFinite()) return std::nullopt;
      fit = next;
      for (std::size_t i = 0; i < points.size(); ++i) {
        residuals[i] = std::abs(bgr.at<cv::Vec3b>(points[i])[c] - fit.dot(terms[i]));
      }
      const auto middle = residuals.begin() + static_cast<std::ptrdiff_t>(residuals.size() / 2);
      std::nth_element(residuals.begin(), middle, residuals.end());
      limit = std::max(2.0, 3.0 * 1.4826 * *middle);
    }
    surface.channels_[static_cast<std::size_t>(c)] = fit;
  }
  return surface;
}

double BackdropSurface::Rise() const {
  double rise = 0.0;
  for (const Terms& channel : channels_) {
    double low = std::numeric_limits<double>::infinity(), high = -low;
    for (int j = 0; j <= 8; ++j) {
      for (int i = 0; i <= 8; ++i) {
        const double value = channel.dot(TermsAt(i / 4.0 - 1.0, j / 4.0 - 1.0));
        low = std::min(low, value);
        high = std::max(high, value);
      }
    }
    rise = std::max(rise, high - low);
  }
  return rise;
}

cv::Vec3d BackdropSurface::At(int x, int y) const {
  const Terms at = TermsAt((x - cx_) / sx_, (y - cy_) / sy_);
  return {channels_[0].dot(at), channels_[1].dot(at), channels_[2].dot(at)};
}

cv::Mat BackdropSurface::Image(cv::Size size) const {
  constexpr int kStep = 8;
  // cv::resize by kStep reads grid point i at pixel kStep i + (kStep - 1) / 2 of its result
  // (pixel centres matched); the grid has one point more on each side, so that the frame's
  // pixels, from kStep on in the result, all lie between points.
  const int columns = (size.width + kStep - 1) / kStep + 2;
  const int rows = (size.height + kStep - 1) / kStep + 2;
  const double offset = (kStep - 1) / 2.0 - kStep;
  cv::Mat grid(rows, columns, CV_8UC3);
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < columns; ++i) {
      const Terms at = TermsAt((kStep * i + offset - cx_) / sx_, (kStep * j + offset - cy_) / sy_);
      for (int c = 0; c < 3; ++c) {
        grid.at<cv::Vec3b>(j, i)[c] =
            cv::saturate_cast<std::uint8_t>(channels_[static_cast<std::size_t>(c)].dot(at));
      }
    }
  }
  cv::Mat dense;
  cv::resize(grid, dense, cv::Size(columns * kStep, rows * kStep), 0.0, 0.0, cv::INTER_LINEAR);
  return dense(cv::Rect(kStep, kStep, size.width, size.height));
}

}  // namespace revolve::capture
