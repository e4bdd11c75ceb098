// The silhouette of a closed, consistently oriented mesh filled from its outline in one view
// (SilhouetteReprojection's fast path, reconstruct/metrics/reprojection.h), and the index that
// finds each view's outline without classifying every face. Internal to reconstruct/metrics;
// the tests and the benchmark compare the culled search with the exhaustive one through it.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/rig.h"
#include "reconstruct/mesh.h"
#include "reconstruct/metrics/reprojection.h"

namespace revolve::reconstruct::outline_internal {

// view.pixel_from_object * (vertex, 1) rounded as Eigen rounds `pixel_from_object.leftCols<3>() *
// vertex.cast<double>() + pixel_from_object.col(3)` (View::Project's expression, what the
// metrics used before): the first two rows as ((p0 x + p1 y) + p2 z) + p3, the third as
// (p0 x + (p1 y + p2 z)) + p3. Written out to be inlined (Eigen's is a call);
// Outline.HomogeneousIsEigensToTheBit checks it. Every path here projects with it.
[[gnu::always_inline]] inline Eigen::Vector3d Homogeneous(const View& view,
                                                          const Eigen::Vector3f& vertex) {
  const Matrix34d& p = view.pixel_from_object;
  const auto x = static_cast<double>(vertex.x());
  const auto y = static_cast<double>(vertex.y());
  const auto z = static_cast<double>(vertex.z());
  return {((p(0, 0) * x + p(0, 1) * y) + p(0, 2) * z) + p(0, 3),
          ((p(1, 0) * x + p(1, 1) * y) + p(1, 2) * z) + p(1, 3),
          (p(2, 0) * x + (p(2, 1) * y + p(2, 2) * z)) + p(2, 3)};
}

// An edge of a closed, consistently oriented mesh: a -> b as face `left` runs it, b -> a as
// face `right` does.
struct SharedEdge {
  int a, b, left, right;
};

// Every edge of `mesh` once (in the order of the faces that run them from the lower vertex
// index), with its two faces; empty when some edge is not used exactly once in each direction
// (the mesh is not closed and consistently oriented).
std::vector<SharedEdge> SharedEdges(const Mesh& mesh);

// Each face's neighbours: [e] is the face that runs its edge corner e -> corner e + 1 backwards.
// Empty when some edge is not used exactly once in each direction (the mesh is not closed and
// consistently oriented): SharedEdges(mesh) empty. Each edge is looked up once, from its lower
// vertex, on all cores. Precondition: fewer than 2^30 faces.
std::vector<Eigen::Vector3i> FaceNeighbours(const Mesh& mesh);

// The silhouette of a closed mesh from its outline, every edge looked at: the pixels whose
// centre the outline winds around (its edges between a face of positive projected area and one
// of another, directed as the positive face runs them: the boundary of the positive faces'
// union, which is the silhouette, RenderSilhouette's `closed`), and those on the outline. The
// same pixels as drawing the faces but for pixel centres within rounding of the outline (not on
// it). Within the rectangle of all projected vertices. nullopt when a vertex is not in front of
// the camera (the caller draws the faces then). `edges`: SharedEdges(mesh), not empty.
std::optional<BoxedSilhouette> SilhouetteFromEveryEdge(const Mesh& mesh,
                                                       const std::vector<SharedEdge>& edges,
                                                       const View& view);

// What a view needs of a closed, consistently oriented mesh beyond its vertices: its faces'
// neighbours and each face's plane (unit normal n and offset n . x, floats) and smallest altitude,
// from which a view decides most faces' orientation without projecting them (a face's projected
// area has the sign of (c - x) . n, c the camera's centre, times a sign of the camera's, or of
// d . n for an orthographic view along d). Built once per mesh, read by any number of views at
// once. The planes are measured when first read (on all cores, once; thread-safe): views that
// share their rows do without them (SilhouettesFromSlices). Holds a reference to `mesh`, which
// must outlive it.
class OutlineIndex {
 public:
  // Empty (closed() false) when the mesh is not closed and consistently oriented.
  explicit OutlineIndex(const Mesh& mesh);

  bool closed() const { return !neighbours_.empty(); }
  const std::vector<Eigen::Vector3i>& neighbours() const { return neighbours_; }
  // Per face: the unit normal (0 when the face is degenerate), n . (its first vertex), and its
  // smallest altitude (empty when finite() is false).
  const std::vector<float>& normal_x() const { return Planes().normal_x_; }
  const std::vector<float>& normal_y() const { return Planes().normal_y_; }
  const std::vector<float>& normal_z() const { return Planes().normal_z_; }
  const std::vector<float>& offset() const { return Planes().offset_; }
  const std::vector<float>& height() const { return Planes().height_; }
  // Per face: bit a set when its three corners share coordinate a, bit for bit.
  const std::vector<std::uint8_t>& shared_axes() const { return Planes().shared_axes_; }
  // A sphere around every vertex; finite() false when some vertex is not finite.
  const Eigen::Vector3d& mesh_centre() const { return mesh_centre_; }
  double mesh_radius() const { return mesh_radius_; }
  bool finite() const { return finite_; }

 private:
  // The sphere and finite_.
  void MeasureSphere(const Mesh& mesh);
  // Each face's plane, altitude and shared axes.
  void MeasureFaces() const;
  const OutlineIndex& Planes() const {
    std::call_once(planes_measured_, [this] { MeasureFaces(); });
    return *this;
  }

  const Mesh* mesh_;
  std::vector<Eigen::Vector3i> neighbours_;
  mutable std::once_flag planes_measured_;
  mutable std::vector<float> normal_x_, normal_y_, normal_z_, offset_, height_;
  mutable std::vector<std::uint8_t> shared_axes_;
  Eigen::Vector3d mesh_centre_ = Eigen::Vector3d::Zero();
  double mesh_radius_ = 0.0;
  bool finite_ = false;
};

// What SilhouetteFromOutline did in one view.
struct OutlineCounts {
  int faces = 0;            // faces of the mesh
  int decided = 0;          // their orientation decided by their planes (not projected)
  int outline_edges = 0;    // edges between a positive face and another
  bool every_face = false;  // every vertex projected (not decided in front by the sphere)
};

// An outline edge in a view, p -> q as its positive face runs it.
struct OutlineSegment {
  Eigen::Vector2d p, q;
};

// SilhouetteFromOutline's working memory, kept from view to view by one thread (fewer pages to
// fault in); any content on entry.
struct OutlineScratch {
  std::vector<std::uint8_t> positive;
  std::vector<std::uint32_t> undecided;
  std::vector<OutlineSegment> segments;
  std::vector<std::int32_t> winding;
  std::vector<cv::Point> on_outline;
};

// SilhouetteFromEveryEdge's result (the same pixels set, IoUs equal to the bit), with most faces
// never projected: a face whose camera-facing side is certain in `view` (its plane at least
// kGrazingMarginRad off the camera's rays to it, and its altitude far above the projection's
// rounding) has the orientation its plane says; the others are projected and signed with the
// same floating-point expressions. Only the outline's ends are projected; the box is their
// rectangle (no pixel outside it is the silhouette's). Where a vertex may lie on or behind the
// camera plane (not decided by the mesh's sphere), or a vertex is not finite, every vertex is
// projected and every face signed, as SilhouetteFromEveryEdge does (nullopt likewise).
// Precondition: index.closed(), built from `mesh`.
// `scratch`: null, or kept by the caller between calls on one thread.
std::optional<BoxedSilhouette> SilhouetteFromOutline(const Mesh& mesh, const OutlineIndex& index,
                                                     const View& view,
                                                     OutlineCounts* counts = nullptr,
                                                     OutlineScratch* scratch = nullptr);

// Receives view i's silhouette (nullopt: as SilhouetteFromOutline's).
using SilhouetteSink = std::function<void(std::size_t i, std::optional<BoxedSilhouette>)>;

// SilhouetteFromOutline(mesh, index, views[i]) for every view (the same pixels; the same box
// but for views that share their rows, below), on all cores: `use` is called once per view, from
// any thread, for several views at once. The views whose faces the planes decide (every vertex in
// front, decided by the mesh's sphere) are taken together: when they all share their rows (the
// thesis's), from the mesh's slices along those rows (SilhouettesFromSlices; the box is then the
// set pixels' rectangle, within the outline's); else 32 at a time: each face is signed in all of
// them with its plane read once, and the outlines of all of them come from one pass over the
// faces and their neighbours (one bit per view), instead of one pass per view. The other views
// one by one. Precondition: index.closed(), built from `mesh`.
void SilhouettesFromOutline(const Mesh& mesh, const OutlineIndex& index,
                            const std::vector<View>& views, const SilhouetteSink& use);

// Whether views[i] for every i in `which` puts a vertex on the same row: orthographic (third row
// (0, 0, 0, 1)) with one second row, finite, as the thesis's views are (the row is
// (height - 1) - z in each).
bool ShareTheirRows(const std::vector<View>& views, const std::vector<std::size_t>& which);

// SilhouetteFromOutline's pixels for the views `which` (ShareTheirRows), from the mesh's slices
// along the rows they share: a row crosses the faces in closed loops (the fill's rule: an edge
// crosses row r when its ends' rows are min <= r < max), each loop the boundary of one part of
// the mesh's cross-section there, and a view's silhouette on that row is, for each loop, the
// pixels from its least to its greatest u (each loop's points' u computed as Homogeneous's first
// row, in the 3D points where the edges cross the row). The slices are cut once for all the
// views; each view then reads only the loops' points. The box is the set pixels' rectangle. The
// same pixels but for pixel centres within rounding of the outline (the loops' points are found
// in 3D, the fill's crossings in the image; none differed on 60 M pixels of real models).
// Where a vertex or an edge lies exactly on a row with nothing of the mesh just below it (a
// bottom, or a flat part facing down), the fill also sets the pixels the outline runs through
// there: a view in which such a pixel is not the slices' is searched for its outline instead
// (SilhouetteFromOutline). `use` is called once per view, from any thread. False, with `use` not
// called, when the views do not share their rows, the mesh is not closed and consistently
// oriented (`index`) or not finite, or a loop does not close.
bool SilhouettesFromSlices(const Mesh& mesh, const OutlineIndex& index,
                           const std::vector<View>& views, const std::vector<std::size_t>& which,
                           const SilhouetteSink& use);

// How SilhouetteReprojectionBy finds a closed mesh's silhouettes: SilhouetteFromEveryEdge (what
// it did before the outline index, for the benchmark), SilhouetteFromOutline one view at a time,
// or SilhouettesFromOutline (SilhouetteReprojection's).
enum class OutlineSearch { kEveryEdge, kEachView, kBatched };

// SilhouetteReprojection, its closed meshes' silhouettes found by `search`.
ReprojectionStats SilhouetteReprojectionBy(const Mesh& mesh, const std::vector<View>& views,
                                           const std::vector<cv::Mat>& masks,
                                           const std::vector<cv::Point>& mask_origins,
                                           OutlineSearch search);

}  // namespace revolve::reconstruct::outline_internal
