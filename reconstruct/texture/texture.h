// Colour for a reconstructed mesh from the views it was made from: vertex colours and a texture
// atlas, each surface point coloured by the views that see it best.
//
// Visibility comes from the mesh itself: per view, the vertices that face the camera are
// splatted into a coarse depth buffer (cells about 1.5 mean edge lengths wide, each holding the
// nearest depth; only the cells under the view's candidates are kept, and clusters of vertices
// that cannot face the view or land there are skipped), and a point is seen when it faces the
// camera, lies in the image and is not behind its cell's depth by more than a tolerance (two
// mean edge lengths, plus the depth a surface at that obliquity spans across two cells). "Best"
// is the largest cosine between the surface normal and the direction to the camera; the few
// best views of each face and vertex are ranked first by the direction from the mesh's centre,
// then tested exactly.
//
// Vertex colours: the blend of the ranked views that see the vertex at less than max_angle_deg
// from its normal, weighted by cos^8 (the best view dominates; neighbours soften the seams),
// sampled bilinearly. A vertex no view sees is mid-grey.
//
// Atlas (projective charts): each face takes the single best view that sees it, judged with
// normals smoothed over a few rings of faces, then relabelled a few times to the view that sees
// it maximising cosine + 0.1 per edge-neighbour with that view (islands merge into their
// surroundings); the connected groups of faces with the same view are the charts. A chart's uvs are
// its vertices' projections into its view, and its texels are that view's pixels over the chart's
// bounding rectangle plus a 2-pixel margin: at scale 1 (one texel per image pixel, the default when
// it fits) the atlas holds the frames' own pixels, untouched. Rectangles are shelf-packed into an
// atlas whose width is a power of two of at most texture_size_px; when they do not fit, the scale
// shrinks. Faces no view sees map to a mid-grey patch.
//
// The texture keeps each view's light: where the light moves with the camera (the synthetic
// camera's lamp), a point's colour is that of its best view, and another view sees it lit
// differently.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

struct TextureOptions {
  bool vertex_colors = true;
  bool atlas = true;
  int texture_size_px = 4096;  // largest atlas side, 64..16384
  // A view colours a point only when it sees it at less than this angle from its normal.
  double max_angle_deg = 85.0;
  // Told when the mesh reaches kColors (its normals and colours set) and, with an atlas, kUvs
  // (its uvs set; the texture image follows before TextureMesh returns), for a ModelWriter
  // (reconstruct/io/model_writer.h) to write those files meanwhile. Vertices and faces are never
  // changed.
  MeshStageHook on_stage;
};

// What TextureMesh did, for logs and reports.
struct TextureStats {
  int views_used = 0;
  int charts = 0;
  double atlas_scale = 0.0;  // texels per image pixel
  std::int64_t unseen_faces = 0;
  std::int64_t unseen_vertices = 0;
};

// How far beyond the projections of a mesh's vertices TextureMesh reads its images (px): the
// charts' margin and bilinear sampling's second pixel.
inline constexpr int kTextureReadMarginPx = 3;

// Fills mesh->colors (options.vertex_colors) and mesh->uvs, uv_faces and texture
// (options.atlas) from `images` (CV_8UC3 BGR, one per view, of the view's size; an empty image
// leaves its view out). `image_origins` (empty, or one per view): image k holds only a window of
// its view's frame, the frame's pixels from image_origins[k] on; the result is that of the whole
// frames when each window holds every pixel within kTextureReadMarginPx of the projections of
// the mesh's vertices (clamped to the frame; reconstruct/reconstructor.h's FrameWindow).
// Errors: bad_input when the counts differ, an image has the wrong type or size (or its window
// leaves the frame), or texture_size_px is out of range; the mesh is then unchanged.
Expected<TextureStats> TextureMesh(Mesh* mesh, const std::vector<View>& views,
                                   const std::vector<cv::Mat>& images,
                                   const TextureOptions& options = {},
                                   const std::vector<cv::Point>& image_origins = {});

// Draws the mesh as `view` sees it: z-buffered, textured (perspective-correct uvs, bilinear
// sampling) when it has a texture, else with its vertex colours (grey without), no lighting.
// `image`: CV_8UC3 BGR of the view's size, black where no face is drawn; `coverage`: CV_8UC1,
// 255 where a face is drawn. A pixel is drawn when its centre lies inside a face that faces the
// camera.
struct MeshRendering {
  cv::Mat image;
  cv::Mat coverage;
};
MeshRendering RenderMesh(const Mesh& mesh, const View& view);

}  // namespace revolve::reconstruct
