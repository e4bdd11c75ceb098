// Checks of a model against the images it came from, and against a known truth: the silhouette a
// mesh casts into a view, its IoU with the view's mask, and the volume IoU of two solids.
#pragma once

#include <functional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/rig.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

// The silhouette of `mesh` seen by `view`: CV_8UC1 of the view's size, 255 where the pixel's
// centre lies inside the projection of some triangle (edges inclusive), 0 elsewhere. This is the
// visual hull's point test read backwards: a pixel is set iff its ray meets the mesh. Triangles
// with a vertex on or behind the camera plane are skipped (the view's contract: depth > 0 in
// front).
//
// `closed`: the caller knows the mesh closed and consistently oriented (MeshStats::closed and
// ::oriented), and only the faces whose projection winds one way (positive signed area) are
// drawn, half the work: along any ray from a camera outside the solid, the surface is entered
// as often as it is left, so every pixel whose ray meets it is covered by a face of each
// winding. When some vertex is not in front of the camera, every face is drawn.
cv::Mat RenderSilhouette(const Mesh& mesh, const View& view, bool closed = false);

// A silhouette within a rectangle of its image: `pixels` (CV_8UC1 0/255, the rectangle's size)
// are the image's pixels in `box`; none outside is set. An empty box: no pixel set.
struct BoxedSilhouette {
  cv::Rect box;
  cv::Mat pixels;
};

// RenderSilhouette's pixels within the rectangle of the pixel centres its drawn vertices reach
// (clipped to the view's image; empty when none): the same pixels, without an image of the
// view's size to clear.
BoxedSilhouette RenderSilhouetteInBox(const Mesh& mesh, const View& view, bool closed = false);

// |a and b| / |a or b| over non-zero pixels of two CV_8UC1 images of one size; 1 when both are
// empty. Precondition: same size and type.
double MaskIoU(const cv::Mat& a, const cv::Mat& b);

struct ReprojectionStats {
  std::vector<double> iou;  // per view, in the order given
  double mean = 0.0;
  double min = 0.0;
  int worst_view = -1;
  // The mesh was found closed and consistently oriented (every edge run once each way: MeshStats'
  // closed and oriented both true); false when it is not.
  bool closed_and_oriented = false;
};

// RenderSilhouette + MaskIoU for every view, on all cores. The silhouette of a closed,
// consistently oriented mesh (each edge run once in each direction, found here) is filled from
// its outline instead, the edges between faces of either winding (the same pixels but for pixel
// centres within rounding of the outline; a few percent of drawing every face), in views that
// see every vertex in front. Precondition: masks.size() == views.size(), each mask of its view's
// size, or (mask_origins not empty) a window of it: mask i holds its view's mask from
// mask_origins[i] on, within the view's image, and none of the mask lies outside.
ReprojectionStats SilhouetteReprojection(const Mesh& mesh, const std::vector<View>& views,
                                         const std::vector<cv::Mat>& masks,
                                         const std::vector<cv::Point>& mask_origins = {});

// Inside test of a solid (true = inside).
using InsideTest = std::function<bool(const Eigen::Vector3d&)>;

// Inside test of a closed, outward-oriented mesh by its winding number along a vertical ray (the
// crossings' orientations are summed, so a consistently oriented mesh is handled even where
// parity would be fooled by a doubled surface). Builds a column index once; each call is
// O(triangles in the point's column).
InsideTest MeshInsideTest(const Mesh& mesh);

// Volume IoU of two solids sampled at the cell centres of a grid with `resolution` cells along the
// longest side of [box_min, box_max]: |A and B| / |A or B| (1 when both are empty).
double VolumeIoU(const InsideTest& a, const InsideTest& b, const Eigen::Vector3d& box_min,
                 const Eigen::Vector3d& box_max, int resolution);

}  // namespace revolve::reconstruct
