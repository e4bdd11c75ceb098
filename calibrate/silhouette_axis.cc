#include "calibrate/silhouette_axis.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <utility>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/angles.h"

namespace revolve::calibrate {
namespace {

// Left and right edges of the silhouette in every row, in continuous pixel coordinates (the
// outer boundaries of the first and last object pixels: column - 0.5 and column + 0.5). NaN for
// empty rows and for edges on the image border (the silhouette is cut there: not an edge).
struct RowEdges {
  std::vector<double> left;
  std::vector<double> right;
  bool any = false;
};

RowEdges Edges(const cv::Mat& mask) {
  RowEdges e;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  e.left.assign(static_cast<std::size_t>(mask.rows), nan);
  e.right.assign(static_cast<std::size_t>(mask.rows), nan);
  for (int v = 0; v < mask.rows; ++v) {
    const std::uint8_t* row = mask.ptr<std::uint8_t>(v);
    int first = -1;
    int last = -1;
    for (int u = 0; u < mask.cols; ++u) {
      if (row[u] == 0) continue;
      if (first < 0) first = u;
      last = u;
    }
    if (first < 0) continue;
    e.any = true;
    if (first > 0) e.left[static_cast<std::size_t>(v)] = first - 0.5;
    if (last < mask.cols - 1) e.right[static_cast<std::size_t>(v)] = last + 0.5;
  }
  return e;
}

struct Sample {
  double row = 0.0;
  double column = 0.0;
};

struct Line {
  double column = 0.0;  // at the reference row
  double slope = 0.0;   // du / dv
};

Line FitLine(const std::vector<Sample>& samples, const std::vector<bool>& inlier, double row0,
             bool fit_slope) {
  double sw = 0.0, sv = 0.0, su = 0.0, svv = 0.0, svu = 0.0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (!inlier[i]) continue;
    const double v = samples[i].row - row0;
    sw += 1.0;
    sv += v;
    su += samples[i].column;
    svv += v * v;
    svu += v * samples[i].column;
  }
  Line line;
  if (sw == 0.0) return line;
  const double det = sw * svv - sv * sv;
  if (!fit_slope || det < 1e-9 * sw * sw) {
    line.column = su / sw;
    return line;
  }
  line.slope = (sw * svu - sv * su) / det;
  line.column = (su - line.slope * sv) / sw;
  return line;
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

cv::Mat MirrorAbout(const cv::Mat& mask, const Line& line, double row0) {
  const Eigen::Vector2d p0(line.column, row0);
  const Eigen::Vector2d d = Eigen::Vector2d(line.slope, 1.0).normalized();
  const Eigen::Matrix2d a = 2.0 * d * d.transpose() - Eigen::Matrix2d::Identity();
  const Eigen::Vector2d b = p0 - a * p0;
  cv::Mat m = (cv::Mat_<double>(2, 3) << a(0, 0), a(0, 1), b.x(), a(1, 0), a(1, 1), b.y());
  cv::Mat out;
  // A reflection is its own inverse, so the direction of the map does not matter.
  cv::warpAffine(mask, out, m, mask.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0);
  return out;
}

double Iou(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat ab;
  cv::Mat either;
  cv::bitwise_and(a != 0, b != 0, ab);
  cv::bitwise_or(a != 0, b != 0, either);
  const int u = cv::countNonZero(either);
  return u == 0 ? 0.0 : static_cast<double>(cv::countNonZero(ab)) / u;
}

}  // namespace

double SilhouetteAxis::ColumnAt(double row_px) const {
  return column_px + std::tan(tilt_deg * std::numbers::pi / 180.0) * (row_px - reference_row_px);
}

Expected<SilhouetteAxis> AxisFromSilhouettes(const std::vector<cv::Mat>& masks,
                                             const std::vector<double>& angles_deg,
                                             const SilhouetteAxisOptions& options) {
  if (masks.size() != angles_deg.size()) {
    return MakeError(ErrorCode::kBadInput, fmt::format("silhouette axis: {} masks but {} angles",
                                                       masks.size(), angles_deg.size()));
  }
  if (masks.empty()) return MakeError(ErrorCode::kBadInput, "silhouette axis: no masks");
  const cv::Size size = masks.front().size();
  for (std::size_t i = 0; i < masks.size(); ++i) {
    if (masks[i].type() != CV_8UC1 || masks[i].size() != size) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("silhouette axis: mask {} is not an 8-bit single-channel image "
                                   "of {}x{}",
                                   i, size.width, size.height));
    }
  }
  // Opposite pairs, each once.
  std::set<std::pair<std::size_t, std::size_t>> pairs;
  for (std::size_t i = 0; i < masks.size(); ++i) {
    std::size_t best = masks.size();
    double best_error = options.pair_tolerance_deg;
    for (std::size_t j = 0; j < masks.size(); ++j) {
      const double error = std::abs(WrapDeg(angles_deg[j] - angles_deg[i] - 180.0));
      if (j != i && error <= best_error) {
        best = j;
        best_error = error;
      }
    }
    if (best < masks.size()) pairs.emplace(std::min(i, best), std::max(i, best));
  }
  if (static_cast<int>(pairs.size()) < std::max(1, options.min_pairs)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("silhouette axis: {} pairs of views 180 deg apart (need {}): the "
                                 "silhouette fallback needs views half a turn apart, e.g. an even "
                                 "number of stops over a full turn",
                                 pairs.size(), std::max(1, options.min_pairs)));
  }
  std::vector<RowEdges> edges(masks.size());
  std::vector<bool> computed(masks.size(), false);
  auto edges_of = [&](std::size_t i) -> const RowEdges& {
    if (!computed[i]) {
      edges[i] = Edges(masks[i]);
      computed[i] = true;
    }
    return edges[i];
  };
  std::vector<Sample> samples;
  for (const auto& [i, j] : pairs) {
    const RowEdges& a = edges_of(i);
    const RowEdges& b = edges_of(j);
    if (!a.any || !b.any) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("silhouette axis: the mask at {:g} deg is empty (no object "
                                   "segmented)",
                                   angles_deg[a.any ? j : i]));
    }
    for (int v = 0; v < size.height; ++v) {
      const auto r = static_cast<std::size_t>(v);
      // The left edge of one view mirrors the right edge of the other.
      if (std::isfinite(a.left[r]) && std::isfinite(b.right[r])) {
        samples.push_back({static_cast<double>(v), 0.5 * (a.left[r] + b.right[r])});
      }
      if (std::isfinite(a.right[r]) && std::isfinite(b.left[r])) {
        samples.push_back({static_cast<double>(v), 0.5 * (a.right[r] + b.left[r])});
      }
    }
  }
  if (samples.size() < 10) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("silhouette axis: only {} rows seen in both views of the opposite "
                                 "pairs (the object must be in view, not cut by the image border)",
                                 samples.size()));
  }

  const double row0 = 0.5 * (size.height - 1);
  std::vector<bool> inlier(samples.size(), true);
  Line line;
  {
    std::vector<double> columns;
    columns.reserve(samples.size());
    for (const Sample& s : samples) columns.push_back(s.column);
    line.column = Median(columns);
  }
  for (int iteration = 0; iteration < 6; ++iteration) {
    std::vector<double> abs_residuals;
    abs_residuals.reserve(samples.size());
    for (const Sample& s : samples) {
      abs_residuals.push_back(std::abs(s.column - line.column - line.slope * (s.row - row0)));
    }
    const double sigma = std::max(0.25, 1.4826 * Median(abs_residuals));
    for (std::size_t i = 0; i < samples.size(); ++i) {
      inlier[i] = abs_residuals[i] <= options.outlier_sigmas * sigma;
    }
    line = FitLine(samples, inlier, row0, options.fit_tilt);
  }
  SilhouetteAxis result;
  result.column_px = line.column;
  result.reference_row_px = row0;
  result.tilt_deg = Degrees(std::atan(line.slope));
  result.pairs = static_cast<int>(pairs.size());
  double sum = 0.0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (!inlier[i]) continue;
    const double r = samples[i].column - line.column - line.slope * (samples[i].row - row0);
    sum += r * r;
    ++result.samples;
  }
  result.rms_px = result.samples > 0 ? std::sqrt(sum / result.samples) : 0.0;
  double iou = 0.0;
  for (const auto& [i, j] : pairs) iou += Iou(MirrorAbout(masks[i], line, row0), masks[j]);
  result.mirror_iou = iou / static_cast<double>(pairs.size());
  return result;
}

SilhouetteAxis ProjectedAxisLine(const Rig& rig) {
  const Matrix34d p = rig.PixelFromObject(0.0);
  // The image of the axis: through the image of the table origin and the axis's vanishing point.
  const Eigen::Vector3d line = p.col(3).cross(p.col(2));
  SilhouetteAxis out;
  out.reference_row_px = 0.5 * (rig.intrinsics.height_px - 1);
  if (std::abs(line.x()) < 1e-12) return out;  // the axis appears horizontal: no column
  out.column_px = -(line.z() + line.y() * out.reference_row_px) / line.x();
  out.tilt_deg = Degrees(std::atan(-line.y() / line.x()));
  return out;
}

}  // namespace revolve::calibrate
