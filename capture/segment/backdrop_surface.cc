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
  // Each point's B, G, R, read once.
  std::array<std::vector<double>, 3> values;
  for (std::vector<double>& channel : values) channel.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const cv::Vec3b& colour = bgr.at<cv::Vec3b>(points[i]);
    for (int c = 0; c < 3; ++c) values[static_cast<std::size_t>(c)][i] = colour[c];
  }
  using Normal = Eigen::Matrix<double, 6, 6>;
  // The normal matrix's lower triangle, summed point by point in order (each element as the
  // whole outer product's would be), then mirrored. The 21 sums are kept apart (in registers) as
  // the points are added. The first round takes every point: one matrix for the three channels.
  struct Lower {
    std::array<double, 21> sum{};  // (a, b), a >= b, column by column
    // Every point of `terms` whose `keep` is true (all of them when it is empty), in order.
    void AddAll(const std::vector<Terms>& terms, const std::vector<char>& keep) {
      double s00 = 0, s10 = 0, s20 = 0, s30 = 0, s40 = 0, s50 = 0, s11 = 0, s21 = 0, s31 = 0,
             s41 = 0, s51 = 0, s22 = 0, s32 = 0, s42 = 0, s52 = 0, s33 = 0, s43 = 0, s53 = 0,
             s44 = 0, s54 = 0, s55 = 0;
      for (std::size_t i = 0; i < terms.size(); ++i) {
        if (!keep.empty() && !keep[i]) continue;
        const double t0 = terms[i](0), t1 = terms[i](1), t2 = terms[i](2), t3 = terms[i](3),
                     t4 = terms[i](4), t5 = terms[i](5);
        s00 += t0 * t0, s10 += t1 * t0, s20 += t2 * t0, s30 += t3 * t0, s40 += t4 * t0;
        s50 += t5 * t0, s11 += t1 * t1, s21 += t2 * t1, s31 += t3 * t1, s41 += t4 * t1;
        s51 += t5 * t1, s22 += t2 * t2, s32 += t3 * t2, s42 += t4 * t2, s52 += t5 * t2;
        s33 += t3 * t3, s43 += t4 * t3, s53 += t5 * t3, s44 += t4 * t4, s54 += t5 * t4;
        s55 += t5 * t5;
      }
      sum = {s00, s10, s20, s30, s40, s50, s11, s21, s31, s41, s51,
             s22, s32, s42, s52, s33, s43, s53, s44, s54, s55};
    }
    Normal Mirrored() const {
      Normal normal;
      std::size_t k = 0;
      for (int b = 0; b < 6; ++b) {
        for (int a = b; a < 6; ++a) normal(a, b) = normal(b, a) = sum[k++];
      }
      return normal;
    }
  };
  std::vector<char> kept(points.size(), 1);
  Lower every_point;
  every_point.AddAll(terms, {});
  const Normal every_point_normal = every_point.Mirrored();
  for (int c = 0; c < 3; ++c) {
    const std::vector<double>& value_of = values[static_cast<std::size_t>(c)];
    Terms fit = Terms::Zero();
    double limit = std::numeric_limits<double>::infinity();
    constexpr int kRounds = 3;
    for (int round = 0; round < kRounds; ++round) {
      Terms rhs = Terms::Zero();
      for (std::size_t i = 0; i < points.size(); ++i) {
        const double value = value_of[i];
        kept[i] = round == 0 || !(std::abs(value - fit.dot(terms[i])) > limit);
        if (kept[i]) rhs += value * terms[i];
      }
      Lower lower;
      if (round > 0) lower.AddAll(terms, kept);
      const Normal normal = round == 0 ? every_point_normal : lower.Mirrored();
      const Terms next = normal.ldlt().solve(rhs);
      if (!next.allFinite()) return std::nullopt;
      fit = next;
      if (round + 1 == kRounds) break;  // no round after it to keep points by its residuals
      for (std::size_t i = 0; i < points.size(); ++i) {
        residuals[i] = std::abs(value_of[i] - fit.dot(terms[i]));
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
