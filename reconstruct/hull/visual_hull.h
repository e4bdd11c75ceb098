// Incremental visual hull: a voxel grid carved one silhouette at a time.
//
// Point test (the definition every part of the carver agrees on): a point X survives a view iff
// either it is not seen by the view (P * [X; 1] has a non-positive third coordinate, or its
// nearest pixel lies outside the image), or its nearest pixel holds a non-zero mask value. The
// nearest pixel of (u, v) is (floor(u + 0.5), floor(v + 0.5)); pixel (0, 0) is the centre of the
// top-left pixel (base/rig.h). A view never carves what it cannot see. A voxel survives when its
// centre survives every integrated view.
//
// Storage: occupancy is bit-packed in 4x4x4 bricks, one 64-bit word per brick (bit
// x | y << 2 | z << 4 of the brick), bricks in x-fastest order; bits of voxels past the grid's
// dims are always 0. 1 bit per voxel: 2 MiB at 256^3, 16 MiB at 512^3, 128 MiB at 1024^3.
// Above the bricks an implicit octree (blocks of 8, 16, ... voxels aligned on multiples of their
// size) keeps one "still has occupied voxels" flag per block, so carved regions are skipped.
//
// Hierarchical carving (Integrate): per view a summed-area table of the mask; a block's voxel
// centres project inside a rectangle bounded from the projection of the box's middle c and the
// projection's derivative (for X = c + d, u(X) - u(c) = ((P0 - u(c) P2) . d) / w(X), w(X) at
// least w(c) - sum |P2a| |d_a|), widened by 1e-6 px against floating-point error, which only
// makes it conservative. Mask count 0 and rectangle inside the image: carve the block.
// Count equal to the rectangle's area clipped to the image: nothing in the block is carved.
// All corners behind the camera: nothing is seen. Otherwise (including a block straddling the
// camera plane) subdivide down to bricks, then test single voxels with the point test (a row
// of 4 voxels at a time in vectors: the same operations per voxel, AVX2 where present). The
// result is bit-identical to IntegrateNaive, the per-voxel reference (both evaluate the same
// projection expression; visual_hull.cc is built without floating-point contraction).
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "reconstruct/hull/marching_cubes.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

// A regular grid of cubic voxels in the object frame (mm). Voxel (i, j, k) spans
// [origin + (i, j, k) * voxel_mm, origin + (i + 1, j + 1, k + 1) * voxel_mm]; its centre is
// origin + (i + 0.5, j + 0.5, k + 0.5) * voxel_mm.
struct VoxelGrid {
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();  // the grid's min corner
  double voxel_mm = 1.0;
  Eigen::Vector3i dims = Eigen::Vector3i::Zero();  // voxels along x, y, z

  // `resolution` voxels along the longest side of [bbox_min_mm, bbox_max_mm]; each other side
  // gets ceil(extent / voxel_mm) voxels (at least 1), so the grid starts at bbox_min_mm and may
  // reach up to one voxel past bbox_max_mm. Errors: bad_input for an empty or inverted box or a
  // resolution outside [1, 4096].
  static Expected<VoxelGrid> FromBox(const Eigen::Vector3d& bbox_min_mm,
                                     const Eigen::Vector3d& bbox_max_mm, int resolution);

  Eigen::Vector3d Centre(int i, int j, int k) const {
    return origin_mm + voxel_mm * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5);
  }
  Eigen::Vector3d MaxCorner() const { return origin_mm + voxel_mm * dims.cast<double>(); }
  std::int64_t VoxelCount() const {
    return std::int64_t{dims.x()} * std::int64_t{dims.y()} * std::int64_t{dims.z()};
  }
};

// An upper bound (px) on how far the projection in `view` of a point of the grid's box moves when
// the point moves by up to one voxel along an axis (a voxel centre to its neighbour's). nullopt
// when some of the box is not seen by the view: a corner on or behind the camera plane, or whose
// nearest pixel lies outside the image.
std::optional<double> VoxelStepBoundPx(const VoxelGrid& grid, const View& view);

struct HullSurfaceOptions {
  // Each vertex at the exact crossing of its grid edge with the silhouette cones (true), or at
  // the edge's midpoint (false).
  bool sub_voxel = true;
  bool keep_largest_component = true;
  // The table plane: voxels whose centre lies below z = clip_below_z_mm are left out, and the
  // edges that reach below it are cut on the plane unless a silhouette cuts them sooner, so the
  // model's base is flat and closed there.
  std::optional<double> clip_below_z_mm;
  // The reference for tests and benchmarks: false walks every edge in every view instead of
  // only in the views whose silhouette boundary can cross it (same result, far slower).
  bool cull_views = true;
};

class VisualHull {
 public:
  // All voxels start occupied.
  explicit VisualHull(const VoxelGrid& grid);

  const VoxelGrid& grid() const { return grid_; }
  int view_count() const { return static_cast<int>(views_.size()); }

  // Carves with one view (hierarchical). `mask`: CV_8UC1, view.height_px x view.width_px,
  // non-zero = object. The mask is kept (as 0/1 bytes over the rectangle of its pixels, a few
  // pixels wider) for sub-voxel surface placement. Errors: bad_input for a wrong mask type or
  // size, or a non-finite projection.
  Expected<void> Integrate(const cv::Mat& mask, const View& view);

  // A view made ready for carving once: its mask as 0/1 bytes, the mask's bounding rectangle
  // and its packed bits. For one view integrated into several hulls (the
  // silhouette consensus's leave-one-out hulls): they share its pixels instead of each copying
  // and counting them again. Copies share the same data.
  class PreparedView;
  // Same contract and errors as Integrate's mask and view.
  static Expected<PreparedView> PrepareView(const cv::Mat& mask, const View& view);
  // The same, from a window of the mask: `window` (CV_8UC1) holds the view's mask from `origin`
  // on, within the view's image, and none of its non-zero pixels lies outside the window. The
  // same view as PrepareView(whole mask, view), without a mask of the image's size. Errors:
  // those of PrepareView, and bad_input when the window does not lie within the image.
  static Expected<PreparedView> PrepareView(const cv::Mat& window, cv::Point origin,
                                            const View& view);
  // Integrate with a prepared view: the same result as Integrate(mask, view). Precondition:
  // `view` came from PrepareView.
  void Integrate(const PreparedView& view);

  // The hulls of `views` with one view left out each (the silhouette consensus): Without(i)
  // equals VisualHull(grid) integrating every view but the i-th, in order (the same occupancy,
  // the same views for ExtractSurface). One carve per view instead of one per view and hull:
  // the carve is the point test per voxel whatever the hull held before, so each view carves
  // a full grid once (on all cores) and hull i is the intersection of the other views'
  // survivors, 1 bit per voxel and view (36 views at 64^3: 1.2 MB).
  class LeaveOneOut;

  // The reference: the point test on every still-occupied voxel. Same contract and same result
  // as Integrate, 20-30x slower at 256^3; used by tests and benchmarks.
  Expected<void> IntegrateNaive(const cv::Mat& mask, const View& view);

  // Frees the integrated views (their masks: width x height bytes each), keeping the occupancy:
  // for a caller done with ExtractSurface. Afterwards the hull is as if no view had been
  // integrated but for its occupancy (view_count() is 0).
  void ReleaseViews() { std::vector<ViewData>().swap(views_); }

  // Occupancy of voxel (i, j, k); false outside the grid.
  bool Occupied(int i, int j, int k) const;
  std::int64_t OccupiedCount() const;

  // The continuous hull: true iff `point_mm` lies in the grid's box and survives every
  // integrated view (the point test). Equals Occupied(i, j, k) at voxel centres.
  bool Contains(const Eigen::Vector3d& point_mm) const;
  // The point test against every integrated view, ignoring the grid's box.
  bool SurvivesAllViews(const Eigen::Vector3d& point_mm) const;

  // Marching cubes over the occupancy (samples at voxel centres, outside the grid empty), each
  // vertex placed on its grid edge where the edge, walked from its inside sample, first leaves
  // the continuous hull: per view, the edge's projection is walked pixel by pixel (the pixels'
  // borders are where the point test's nearest pixel changes) up to the first pixel off the
  // silhouette, found in closed form; the vertex takes the nearest of these over the views.
  // Only the views whose silhouette boundary can cross the edge's projection are walked, so
  // the result is that of walking every view: per view, a block of 16 voxels, a brick, then an
  // inside sample is left out when the pixels around its projection, as far as its edges can
  // move in the image (a bound from the projection's derivative), are all on the silhouette;
  // then an edge whose end pixels' rectangle is all on the silhouette. An edge leaving the grid (or
  // reaching below clip_below_z_mm) is cut at the grid's face (the plane) unless the silhouettes
  // cut it sooner, so the base on the plate is flat. The mesh is watertight, 2-manifold and
  // outward-oriented (reconstruct/hull/marching_cubes.h). Empty when no voxel is occupied.
  Mesh ExtractSurface(const HullSurfaceOptions& options = {}) const;

 private:
  struct ViewData {
    Matrix34d pixel_from_object;
    int width = 0;  // the image's size (px)
    int height = 0;
    cv::Rect roi;  // bounding rectangle of the non-zero pixels, in the image (empty: none)
    // mask01's rectangle in the image: roi grown by kWindowMarginPx, within the image (empty
    // when roi is). The mask is held over it alone: every pixel of the image outside it is 0.
    cv::Rect window;
    cv::Mat mask01;  // CV_8UC1, 0 or 1, window's size
    // mask01 over roi, one bit per pixel, in rows of packed_words words: the surface
    // placement's tests read it.
    std::vector<std::uint64_t> packed;
    int packed_words = 0;
  };
  struct Sat;  // per-view summed-area table, lives only during Integrate or ExtractSurface

 public:
  class PreparedView {
   public:
    // The rectangle of the mask's pixels set (MaskRect; empty when none), found in preparing.
    cv::Rect mask_rect() const;

   private:
    friend class VisualHull;
    std::shared_ptr<const ViewData> data_;
  };

  class LeaveOneOut {
   public:
    // Contract: every view from PrepareView.
    LeaveOneOut(const VoxelGrid& grid, std::vector<PreparedView> views);
    std::size_t size() const { return views_.size(); }
    // Precondition: i < size(). keep_views false: the views are left out of the hull (its
    // occupancy is the same; for ExtractSurface without sub_voxel, which does not read them).
    // `tolerated`: a voxel survives that many of the other views carving it (0: the hull of
    // the others; 1: one mask that lost part of the object does not carve it from the others').
    VisualHull Without(std::size_t i, bool keep_views = true, int tolerated = 0) const;

   private:
    VoxelGrid grid_;
    std::vector<PreparedView> views_;
    std::vector<std::vector<std::uint64_t>> survivors_;  // per view: the bricks it leaves
  };

 private:
  // kMixedInImage: kMixed, with every corner in front of the camera and the rectangle of
  // nearest pixels inside the image and inside the view's held window (so are those of every
  // point of the block).
  enum class BlockClass { kUnaffected, kCarve, kMixed, kMixedInImage };

  static Expected<ViewData> Prepare(const cv::Mat& mask, const View& view);
  // Prepare from a window of the mask (PrepareView's second form).
  static Expected<ViewData> PrepareWindow(const cv::Mat& window, cv::Point origin,
                                          const View& view);
  // Carves with a prepared view (Integrate's work after Prepare).
  void Carve(const ViewData& view, const Sat& sat);
  // The point test for voxel (i, j, k): true = survives `view`.
  bool VoxelSurvives(const ViewData& view, int i, int j, int k) const;
  bool PointSurvives(const ViewData& view, const Eigen::Vector3d& point_mm) const;
  static bool SurvivesProjected(const ViewData& view, double x, double y, double w);
  static Sat MakeSat(const ViewData& view);
  // A block's projection: the rectangle (px) that holds the projections of its points in front
  // of the camera, and whether some are behind it (in_front + behind > 0).
  struct ProjectedRect {
    double u_min = std::numeric_limits<double>::infinity();
    double u_max = -std::numeric_limits<double>::infinity();
    double v_min = std::numeric_limits<double>::infinity();
    double v_max = -std::numeric_limits<double>::infinity();
    int in_front = 0;
    int behind = 0;
  };
  // How `view` acts on a block whose points project as `rect` says.
  static BlockClass ClassifyRect(const ViewData& view, const Sat& sat, const ProjectedRect& rect);
  // Boxes of voxel centres (middle and half extents, mm), 8 at a time.
  struct BoxBatch {
    static constexpr int kSize = 8;
    double cx[kSize], cy[kSize], cz[kSize];
    double ex[kSize], ey[kSize], ez[kSize];
  };
  // Slot i of `boxes`: the box of the centres of voxels lo..hi (inclusive).
  void AddBox(BoxBatch* boxes, int i, const Eigen::Vector3i& lo, const Eigen::Vector3i& hi) const;
  // A rectangle (ProjectedRect) holding the projection of each box.
  static void RectsOfBoxes(const Matrix34d& p, const BoxBatch& boxes, ProjectedRect* rects);
  // Where every cut edge first leaves the hull (see ExtractSurface), by an EdgePlacer
  // (surface_placement.cc).
  class EdgePlacer;
  std::vector<double> PlaceOnEdges(const std::vector<GridEdge>& edges,
                                   std::optional<double> clip_below_z_mm, bool cull_views) const;
  // The first t in [0, t_max] where a + t d leaves `view`'s silhouette; t_max + 1 when it
  // does not (a is expected to survive the view).
  static double FirstExit(const ViewData& view, const Eigen::Vector3d& a, const Eigen::Vector3d& d,
                          double t_max);
  // FirstExit's walk for a segment in front of the camera: P * [a; 1] = (hx, hy, hw), P * [d; 0]
  // = hd, from the nearest pixel (iu, iv) of a to that (end_u, end_v) of a + t_max d.
  static double WalkCells(const ViewData& view, double hx, double hy, double hw, const double* hd,
                          double t_max, int iu, int iv, int end_u, int end_v);
  // Carves an occupied block whose class in this view is `block_class` (kMixed or
  // kMixedInImage): its children are classified together, and only the mixed ones visited.
  // Returns whether the block still holds occupied voxels.
  bool Visit(const ViewData& view, const Sat& sat, int level, const Eigen::Vector3i& node,
             BlockClass block_class);
  void ClearBlock(int level, const Eigen::Vector3i& node);
  // kInImage: every voxel centre's nearest pixel is known to lie inside the image.
  template <bool kInImage>
  bool CarveBrick(const ViewData& view, const Eigen::Vector3i& brick);
  void RebuildFlags();

  std::int64_t BrickIndex(const Eigen::Vector3i& b) const {
    return (std::int64_t{b.z()} * brick_dims_.y() + b.y()) * brick_dims_.x() + b.x();
  }
  std::int64_t NodeIndex(int level, const Eigen::Vector3i& n) const {
    const Eigen::Vector3i& d = level_dims_[level];
    return (std::int64_t{n.z()} * d.y() + n.y()) * d.x() + n.x();
  }

  VoxelGrid grid_;
  Eigen::Vector3i brick_dims_;
  std::vector<std::uint64_t> bricks_;
  // level_dims_[0] = brick_dims_; level l > 0 holds blocks of 4 << l voxels. alive_[l] (l > 0):
  // 1 when the block may still hold occupied voxels (exact after each Integrate).
  std::vector<Eigen::Vector3i> level_dims_;
  std::vector<std::vector<std::uint8_t>> alive_;
  std::vector<ViewData> views_;
};

}  // namespace revolve::reconstruct
