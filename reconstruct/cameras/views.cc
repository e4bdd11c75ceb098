#include "reconstruct/cameras/views.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <numeric>
#include <vector>

#include <fmt/format.h>
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <opencv2/imgproc.hpp>

#include "base/log.h"
#include "base/mask_bits.h"
#include "base/mask_rect.h"
#include "reconstruct/parallel.h"

namespace revolve::reconstruct {
namespace {

double Radians(double deg) { return deg * std::numbers::pi / 180.0; }

Eigen::Vector3d ClosestPointOnRay(const Ray& ray, const Eigen::Vector3d& point) {
  return ray.origin + (point - ray.origin).dot(ray.direction) * ray.direction;
}

struct CarveResult {
  Eigen::Vector3i dims = Eigen::Vector3i::Zero();
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(-1);  // surviving cells' index range
  Eigen::Vector3i hi = Eigen::Vector3i::Constant(-1);
  double cell = 0.0;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  bool any = false;
  bool touches = false;
};

// p * [x; 1] rounded as Eigen rounds `p.leftCols<3>() * x + p.col(3)` (what this file projected
// with before): the first two rows as ((p0 x + p1 y) + p2 z) + p3, the third as (p0 x + (p1 y +
// p2 z)) + p3. Written out to be inlined (Eigen's is a call per point); the same values, so the
// same cells survive.
[[gnu::always_inline]] inline Eigen::Vector3d Homogeneous(const Matrix34d& p,
                                                          const Eigen::Vector3d& x) {
  return {((p(0, 0) * x.x() + p(0, 1) * x.y()) + p(0, 2) * x.z()) + p(0, 3),
          ((p(1, 0) * x.x() + p(1, 1) * x.y()) + p(1, 2) * x.z()) + p(1, 3),
          (p(2, 0) * x.x() + (p(2, 1) * x.y() + p(2, 2) * x.z())) + p(2, 3)};
}

// Views that must see a cell for tolerated misses to count (AutoVolumeOptions).
constexpr int kMinViewsToOutvote = 8;

// A silhouette one bit a pixel over its MaskRect (image pixels): the coarse passes read it at
// random, a pixel from each view for each cell, and the bits of all the views fit the caches
// where their bytes do not.
class PackedSilhouette {
 public:
  PackedSilhouette() = default;
  // `mask` holds its view's image from `origin` on; `rect`: its MaskRect, in image pixels.
  PackedSilhouette(const cv::Mat& mask, cv::Point origin, const cv::Rect& rect)
      : rect_(rect),
        words_((rect.width + 63) / 64),
        bits_(PackMaskBits(mask, rect - origin, words_)) {}
  const cv::Rect& rect() const { return rect_; }
  // Whether image pixel (u, v) is on the silhouette (off outside the rectangle).
  bool On(int u, int v) const {
    const auto x = static_cast<unsigned>(u - rect_.x);
    const auto y = static_cast<unsigned>(v - rect_.y);
    if (x >= static_cast<unsigned>(rect_.width) || y >= static_cast<unsigned>(rect_.height)) {
      return false;
    }
    return ((bits_[static_cast<std::size_t>(y) * words_ + (x >> 6)] >> (x & 63)) & 1u) != 0;
  }

 private:
  cv::Rect rect_;
  int words_ = 0;
  std::vector<std::uint64_t> bits_;
};

// Whether the cell centre `x` survives (AutoVolumeOptions). The views are tried in the order
// `order` (a permutation of them): the answer is the same in any order (a cell falls once more
// than `tolerated` views miss it, whichever they are), and a view that misses it is moved to the
// front, so that the next cells, its neighbours, meet the views that miss them first. Built for
// AVX2 too where the processor has it (floor is an instruction there; the same values).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
bool CellSurvives(const std::vector<PackedSilhouette>& silhouettes, const std::vector<View>& views,
                  const Eigen::Vector3d& x, int seen_needed, int tolerated,
                  std::vector<std::size_t>* order) {
  int seen = 0;
  int misses = 0;
  for (std::size_t n = 0; n < order->size(); ++n) {
    const std::size_t v = (*order)[n];
    const Eigen::Vector3d h = Homogeneous(views[v].pixel_from_object, x);
    if (!(h.z() > 0.0)) continue;
    // An affine view's depth is exactly 1 (the thesis's): its division, exact, is left out.
    const bool unit_depth = h.z() == 1.0;
    const double u = std::floor((unit_depth ? h.x() : h.x() / h.z()) + 0.5);
    const double w = std::floor((unit_depth ? h.y() : h.y() / h.z()) + 0.5);
    if (!(u >= 0.0 && w >= 0.0 && u < views[v].width_px && w < views[v].height_px)) continue;
    ++seen;
    if (!silhouettes[v].On(static_cast<int>(u), static_cast<int>(w))) {
      std::rotate(order->begin(), order->begin() + static_cast<std::ptrdiff_t>(n),
                  order->begin() + static_cast<std::ptrdiff_t>(n) + 1);
      if (++misses > tolerated) return false;
    }
  }
  return seen >= seen_needed && (misses == 0 || seen >= kMinViewsToOutvote);
}

// Cells a block test covers (CoarseCarve), and the views it asks.
constexpr int kBlockCells = 16;
constexpr std::size_t kBlockViews = 4;

// Coarse carving of cell centres (see AutoVolumeOptions), the layers of cells on all cores; the
// index range of the survivors is an exact minimum and maximum over the layers' (and over each
// row's first and last survivor).
CarveResult CoarseCarve(const std::vector<PackedSilhouette>& silhouettes,
                        const std::vector<View>& views, const Box& box,
                        const AutoVolumeOptions& options) {
  CarveResult result;
  const Eigen::Vector3d size = box.Size();
  result.cell = size.maxCoeff() / options.resolution;
  for (int a = 0; a < 3; ++a) {
    result.dims[a] = std::max(1, static_cast<int>(std::ceil(size[a] / result.cell - 1e-9)));
  }
  result.origin = box.Centre() - 0.5 * result.cell * result.dims.cast<double>();
  const int seen_needed = std::max(
      1,
      static_cast<int>(std::ceil(options.min_seen_fraction * static_cast<double>(views.size()))));
  struct Layer {
    Eigen::Vector3i lo = Eigen::Vector3i::Constant(-1);
    Eigen::Vector3i hi = Eigen::Vector3i::Constant(-1);
    bool any = false;
  };
  std::vector<Layer> layers(static_cast<std::size_t>(result.dims.z()));
  ParallelFor(0, layers.size(), [&](std::size_t layer) {
    const int k = static_cast<int>(layer);
    Layer& out = layers[layer];
    std::vector<std::size_t> order(views.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    const auto centre = [&](int i, int j) -> Eigen::Vector3d {
      return result.origin + result.cell * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5);
    };
    const auto survives = [&](int i, int j) {
      return CellSurvives(silhouettes, views, centre(i, j), seen_needed, options.tolerated_misses,
                          &order);
    };
    // Whether every cell i0..i1 of row j falls for certain, from the line through their centres:
    // more than `tolerated_misses` of the first kBlockViews views (in `order`) see all of it in
    // their image, in front and off their silhouette's rectangle. The centres lie on the segment
    // between the two ends' (to rounding), so their pixels (floor(u + 0.5)) lie within a pixel
    // of the ends' pixels' rectangle: each such view sees each cell and misses it, as
    // CellSurvives would find. False says nothing.
    const auto block_falls = [&](int i0, int i1, int j) {
      const Eigen::Vector3d ends[2] = {centre(i0, j), centre(i1, j)};
      int misses = 0;
      for (std::size_t n = 0; n < std::min(kBlockViews, order.size()); ++n) {
        const std::size_t v = order[n];
        const Matrix34d& p = views[v].pixel_from_object;
        double u[2], w[2], depth[2];
        for (int e = 0; e < 2; ++e) {
          const Eigen::Vector3d h = Homogeneous(p, ends[e]);
          depth[e] = h.z();
          u[e] = h.z() == 1.0 ? h.x() : h.x() / h.z();
          w[e] = h.z() == 1.0 ? h.y() : h.y() / h.z();
        }
        // In front all along, with room for the rounding of the cells' depths.
        if (!(std::min(depth[0], depth[1]) > 1e-6 * std::max(depth[0], depth[1]))) continue;
        const double u_lo = std::floor(std::min(u[0], u[1]) + 0.5) - 1.0;
        const double u_hi = std::floor(std::max(u[0], u[1]) + 0.5) + 1.0;
        const double w_lo = std::floor(std::min(w[0], w[1]) + 0.5) - 1.0;
        const double w_hi = std::floor(std::max(w[0], w[1]) + 0.5) + 1.0;
        if (!(u_lo >= 0.0 && w_lo >= 0.0 && u_hi < views[v].width_px &&
              w_hi < views[v].height_px)) {
          continue;
        }
        const cv::Rect& r = silhouettes[v].rect();
        const bool apart = r.empty() || u_hi < r.x || u_lo >= r.x + r.width || w_hi < r.y ||
                           w_lo >= r.y + r.height;
        if (apart && ++misses > options.tolerated_misses) return true;
      }
      return false;
    };
    // The first survivor of row j from `from` towards `to` (exclusive), `step` +1 or -1; `to`
    // when none. Blocks of cells that fall for certain are passed over untested.
    const auto first_survivor = [&](int j, int from, int to, int step) {
      int i = from;
      while (i != to) {
        const int block = std::min((to - i) * step, kBlockCells);
        const int last = i + step * (block - 1);
        if (options.block_tests && block > 1 &&
            block_falls(std::min(i, last), std::max(i, last), j)) {
          i += step * block;
          continue;
        }
        for (int n = 0; n < block; ++n, i += step) {
          if (survives(i, j)) return i;
        }
      }
      return to;
    };
    const auto add = [&](const Eigen::Vector3i& c) {
      if (!out.any) {
        out.lo = out.hi = c;
        out.any = true;
      } else {
        out.lo = out.lo.cwiseMin(c);
        out.hi = out.hi.cwiseMax(c);
      }
    };
    // Only the survivors' range is wanted: each row's first and last survivor, found from its
    // two ends; the cells between them are not tested. Whether row j holds a survivor at all
    // (whole row searched) is needed only from the ends of the layer inwards, up to the first
    // row that does; between those two rows, the rows can only widen the layer's range along x,
    // and only their cells outside it are tested.
    const int nx = result.dims.x();
    const int ny = result.dims.y();
    // Row j's first and last survivor (false: none).
    const auto whole_row = [&](int j) {
      const int i_first = first_survivor(j, 0, nx, 1);
      if (i_first == nx) return false;
      const int i_last = first_survivor(j, nx - 1, i_first, -1);
      add(Eigen::Vector3i(i_first, j, k));
      add(Eigen::Vector3i(i_last, j, k));
      return true;
    };
    int j_low = 0;
    while (j_low < ny && !whole_row(j_low)) ++j_low;
    if (j_low == ny) return;
    int j_high = ny - 1;
    while (j_high > j_low && !whole_row(j_high)) --j_high;
    for (int j = j_low + 1; j < j_high; ++j) {
      if (const int i = first_survivor(j, 0, out.lo.x(), 1); i < out.lo.x()) {
        add(Eigen::Vector3i(i, j, k));
      }
      if (const int i = first_survivor(j, nx - 1, out.hi.x(), -1); i > out.hi.x()) {
        add(Eigen::Vector3i(i, j, k));
      }
    }
  });
  for (const Layer& layer : layers) {
    if (!layer.any) continue;
    if (!result.any) {
      result.lo = layer.lo;
      result.hi = layer.hi;
      result.any = true;
    } else {
      result.lo = result.lo.cwiseMin(layer.lo);
      result.hi = result.hi.cwiseMax(layer.hi);
    }
  }
  if (result.any) {
    result.touches =
        (result.lo.array() == 0).any() || (result.hi.array() == result.dims.array() - 1).any();
  }
  return result;
}

Box SurvivorsBox(const CarveResult& carve, double margin_cells) {
  Box box;
  box.min = carve.origin +
            carve.cell * (carve.lo.cast<double>() + Eigen::Vector3d::Constant(0.5 - margin_cells));
  box.max = carve.origin +
            carve.cell * (carve.hi.cast<double>() + Eigen::Vector3d::Constant(0.5 + margin_cells));
  return box;
}

// A mask's pixel count and the sums of its pixels' columns and rows (the zeroth and first
// moments of its non-zero pixels, cv::moments(mask, true)'s m00, m10, m01, which are integers).
struct MaskMoments {
  std::int64_t m00 = 0;
  std::int64_t m10 = 0;
  std::int64_t m01 = 0;
};

// Rows in blocks of at most kMomentBlock columns, summed in 32 bits (a block's column sum is
// below 2^23) and added to the 64-bit moments: whole numbers, the same sums in any grouping. The
// blocks' loops run on vectors (built for AVX2 too where the processor has it).
constexpr int kMomentBlock = 4096;

#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
MaskMoments
Moments(const cv::Mat& mask) {
  MaskMoments moments;
  for (int y = 0; y < mask.rows; ++y) {
    const std::uint8_t* row = mask.ptr<std::uint8_t>(y);
    std::int64_t count = 0;
    std::int64_t sum_x = 0;
    for (int x0 = 0; x0 < mask.cols; x0 += kMomentBlock) {
      const int n = std::min(kMomentBlock, mask.cols - x0);
      const std::uint8_t* block = row + x0;
      std::uint32_t block_count = 0;
      std::uint32_t block_sum = 0;  // of the columns from x0
      for (int x = 0; x < n; ++x) {
        const std::uint32_t set = block[x] != 0 ? 1u : 0u;
        block_count += set;
        block_sum += set * static_cast<std::uint32_t>(x);
      }
      count += block_count;
      sum_x += static_cast<std::int64_t>(block_sum) + static_cast<std::int64_t>(block_count) * x0;
    }
    moments.m00 += count;
    moments.m10 += sum_x;
    moments.m01 += count * y;
  }
  return moments;
}

}  // namespace

View ThesisView(int width_px, int height_px, double plate_angle_deg) {
  const double c = std::cos(Radians(plate_angle_deg));
  const double s = std::sin(Radians(plate_angle_deg));
  View view;
  view.width_px = width_px;
  view.height_px = height_px;
  // u = u0 + (table x) with table_from_object = Rz(theta); v = (height - 1) - z.
  view.pixel_from_object << c, -s, 0.0, 0.5 * (width_px - 1),  //
      0.0, 0.0, -1.0, static_cast<double>(height_px - 1),      //
      0.0, 0.0, 0.0, 1.0;
  return view;
}

std::optional<Ray> BackProject(const View& view, const Eigen::Vector2d& pixel) {
  const Matrix34d& p = view.pixel_from_object;
  const Eigen::Vector4d a = (p.row(0) - pixel.x() * p.row(2)).transpose();
  const Eigen::Vector4d b = (p.row(1) - pixel.y() * p.row(2)).transpose();
  Eigen::Matrix<double, 2, 3> m;
  m.row(0) = a.head<3>().transpose();
  m.row(1) = b.head<3>().transpose();
  Eigen::Vector3d direction = m.row(0).cross(m.row(1)).transpose();
  const double norm = direction.norm();
  if (!(norm > 1e-12 * m.cwiseAbs().maxCoeff() * m.cwiseAbs().maxCoeff())) return std::nullopt;
  direction /= norm;
  const Eigen::Matrix2d mmt = m * m.transpose();
  const Eigen::Vector2d rhs(-a[3], -b[3]);
  Ray ray;
  ray.origin = m.transpose() * mmt.ldlt().solve(rhs);
  const Eigen::Vector3d depth_gradient = p.block<1, 3>(2, 0).transpose();
  double along = depth_gradient.dot(direction);
  if (depth_gradient.isZero(0.0)) {
    // Affine: the viewing direction is r1 x r2 (for K·[R t] with a proper R, the camera's +z).
    along = p.block<1, 3>(0, 0).cross(p.block<1, 3>(1, 0)).dot(direction.transpose());
  }
  ray.direction = along < 0.0 ? -direction : direction;
  return ray;
}

double Depth(const View& view, const Eigen::Vector3d& point_object) {
  return view.pixel_from_object.row(2).head<3>().dot(point_object) + view.pixel_from_object(2, 3);
}

View NormaliseViewSign(View view, const Eigen::Vector3d& point_in_front) {
  if (Depth(view, point_in_front) < 0.0) view.pixel_from_object = -view.pixel_from_object;
  return view;
}

Expected<Eigen::Vector3d> SilhouetteCentre(const std::vector<cv::Mat>& masks,
                                           const std::vector<View>& views,
                                           const std::vector<cv::Point>& mask_origins) {
  Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> directions;
  // Each mask's moments on all cores; summed in mask order.
  std::vector<MaskMoments> all_moments(std::min(masks.size(), views.size()));
  // A window's moments moved to its origin: whole numbers, exact.
  ParallelFor(0, all_moments.size(), [&](std::size_t i) {
    MaskMoments moments = Moments(masks[i]);
    if (!mask_origins.empty()) {
      moments.m10 += std::int64_t{mask_origins[i].x} * moments.m00;
      moments.m01 += std::int64_t{mask_origins[i].y} * moments.m00;
    }
    all_moments[i] = moments;
  });
  for (std::size_t i = 0; i < all_moments.size(); ++i) {
    const MaskMoments& moments = all_moments[i];
    if (moments.m00 <= 0) continue;
    const auto m00 = static_cast<double>(moments.m00);
    const std::optional<Ray> ray =
        BackProject(views[i], Eigen::Vector2d(static_cast<double>(moments.m10) / m00,
                                              static_cast<double>(moments.m01) / m00));
    if (!ray) continue;
    const Eigen::Matrix3d projector =
        Eigen::Matrix3d::Identity() - ray->direction * ray->direction.transpose();
    normal_matrix += projector;
    rhs += projector * ray->origin;
    directions.push_back(ray->direction);
  }
  double spread = 0.0;
  for (const Eigen::Vector3d& d : directions) {
    spread = std::max(spread, d.cross(directions.front()).norm());
  }
  if (directions.size() < 2 || spread < 1e-3) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("cannot locate the object: {} silhouette(s) with an object and "
                                 "their viewing directions {} (at least two views from different "
                                 "directions are needed)",
                                 directions.size(), spread < 1e-3 ? "are parallel" : "differ"));
  }
  return Eigen::Vector3d(normal_matrix.ldlt().solve(rhs));
}

Expected<AutoVolume> CarvingVolumeFromSilhouettes(const std::vector<cv::Mat>& masks,
                                                  const std::vector<View>& views_in,
                                                  const AutoVolumeOptions& options,
                                                  const std::vector<cv::Point>& mask_origins) {
  if (masks.size() != views_in.size() ||
      (!mask_origins.empty() && mask_origins.size() != masks.size())) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{} masks for {} views ({} window origins)", masks.size(),
                                 views_in.size(), mask_origins.size()));
  }
  for (std::size_t i = 0; i < masks.size(); ++i) {
    const cv::Rect image(0, 0, views_in[i].width_px, views_in[i].height_px);
    const cv::Rect window(mask_origins.empty() ? cv::Point() : mask_origins[i], masks[i].size());
    const bool fits = mask_origins.empty() ? window == image : (window & image) == window;
    if (masks[i].type() != CV_8UC1 || !fits) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("mask {} is not CV_8UC1 {} its view's size {}x{}", i,
                                   mask_origins.empty() ? "of" : "within", views_in[i].width_px,
                                   views_in[i].height_px));
    }
  }
  // Each silhouette's rectangle (in its image) and its bits over it; the centre from the pixels
  // in the rectangles alone (the same moments: none is set outside).
  std::vector<cv::Rect> rects(masks.size());
  std::vector<PackedSilhouette> silhouettes(masks.size());
  std::vector<cv::Mat> within(masks.size());
  ParallelFor(0, masks.size(), [&](std::size_t i) {
    const cv::Point origin = mask_origins.empty() ? cv::Point() : mask_origins[i];
    rects[i] = MaskRect(masks[i]);
    if (!rects[i].empty()) {
      within[i] = masks[i](rects[i]);
      rects[i] += origin;
    }
    silhouettes[i] = PackedSilhouette(masks[i], origin, rects[i]);
  });
  std::vector<cv::Point> within_origins(masks.size());
  for (std::size_t i = 0; i < masks.size(); ++i) within_origins[i] = rects[i].tl();
  Expected<Eigen::Vector3d> centre = SilhouetteCentre(within, views_in, within_origins);
  if (!centre) return std::unexpected(centre.error());
  std::vector<View> views;
  views.reserve(views_in.size());
  for (const View& view : views_in) views.push_back(NormaliseViewSign(view, *centre));

  // The search box: the silhouettes' extents around the centre.
  double radius = 0.0;
  for (std::size_t i = 0; i < masks.size(); ++i) {
    const cv::Rect& rect = rects[i];
    if (rect.area() == 0) continue;
    for (const Eigen::Vector2d& corner :
         {Eigen::Vector2d(rect.x - 0.5, rect.y - 0.5),
          Eigen::Vector2d(rect.x + rect.width - 0.5, rect.y - 0.5),
          Eigen::Vector2d(rect.x - 0.5, rect.y + rect.height - 0.5),
          Eigen::Vector2d(rect.x + rect.width - 0.5, rect.y + rect.height - 0.5)}) {
      if (const std::optional<Ray> ray = BackProject(views[i], corner)) {
        radius = std::max(radius, (ClosestPointOnRay(*ray, *centre) - *centre).norm());
      }
    }
  }
  if (!(radius > 0.0)) {
    return MakeError(ErrorCode::kBadInput, "every silhouette is empty");
  }
  AutoVolume result;
  result.centre = *centre;
  Box search{*centre - Eigen::Vector3d::Constant(1.5 * radius),
             *centre + Eigen::Vector3d::Constant(1.5 * radius)};
  CarveResult carve;
  for (int attempt = 0;; ++attempt) {
    carve = CoarseCarve(silhouettes, views, search, options);
    if (!carve.any) {
      return MakeError(ErrorCode::kBadInput,
                       "no point lies inside every silhouette that sees it: the cameras do not "
                       "match the images, or the silhouettes are wrong");
    }
    if (!carve.touches || attempt == 3) break;
    search = Box{*centre - 2.0 * (*centre - search.min), *centre + 2.0 * (search.max - *centre)};
  }
  result.touches_limit = carve.touches;
  const Box first = SurvivorsBox(carve, options.margin_cells);
  carve = CoarseCarve(silhouettes, views, first, options);
  result.box = carve.any ? SurvivorsBox(carve, options.margin_cells) : first;
  Logger("reconstruct")
      ->debug(
          "auto volume: centre ({:.4g}, {:.4g}, {:.4g}), box ({:.4g}, {:.4g}, {:.4g}) to "
          "({:.4g}, {:.4g}, {:.4g}){}",
          centre->x(), centre->y(), centre->z(), result.box.min.x(), result.box.min.y(),
          result.box.min.z(), result.box.max.x(), result.box.max.y(), result.box.max.z(),
          result.touches_limit ? " (the silhouettes leave it unbounded)" : "");
  return result;
}

}  // namespace revolve::reconstruct
