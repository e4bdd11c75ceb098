// The thesis's method (chapters 4-6): meridian feature points, triangle strips between adjacent
// meridians, view-dependent texture.
//
// Feature points (4.3.2, 5.2): in every h_RANGE-th image row (`row_step_px`, default 9) the
// leftmost object pixel left of the imaged rotation axis gives the meridian point of that row. The
// rows are counted from the object's top row (the first row holding an object pixel in any view;
// the thesis counts from the image's top) and the object's bottom row is always added, so the
// model spans the object's full height whatever the step. The silhouette's edge is taken at that
// pixel's outer edge (u - 0.5: the boundary lies between the last background and the first object
// pixel centre), its ray is back-projected and the point of the ray closest to the rotation axis
// (the object frame's z axis) is the feature point. In the thesis's orthographic views
// (reconstruct/cameras/views.h ThesisView) that is exactly eq. 4.9-4.11: radius r = u0 - (u - 0.5),
// height from the row, the point on the meridian plane facing the camera. In a calibrated pinhole
// view it is the point where the ray passes closest to the axis (exact for a cylinder, a close
// approximation for a surface of revolution seen from far). A row with object pixels but none left
// of the axis gives a point on the axis (r = 0). Both-sides mode (6.2): the rightmost object pixel
// right of the axis also gives a meridian, the one at theta + 180 deg, so the first half of a turn
// (T/2 images) gives the whole object; a right meridian within a quarter step of a left one is
// dropped (the left is kept).
//
// Surface (4.3.3, 5.3.3): meridians sorted by azimuth around the axis and closed into a ring; the
// quad between meridians i, i+1 and rows j, j+1 is split into the triangles
// (X[i][j], X[i][j+1], X[i+1][j]) and (X[i+1][j], X[i][j+1], X[i+1][j+1]). A meridian without an
// object pixel in a chosen row gets the axis point of that row. Unlike the thesis's open strips,
// the top and bottom rows are closed by fans to a point on the axis, so the mesh is watertight,
// 2-manifold and outward-oriented like every Reconstructor's.
//
// Texture (4.3.4, 5.4): view-dependent: each strip (the quads between two adjacent meridians) is
// textured from one view's image, the view that faces the strip most squarely, and the texture
// coordinates of its vertices are their projections into that image. (The thesis approximates
// that projection from the silhouette edge: u_i = W/2 - r, u_{i+1} = u_i + chord; near the
// contour the surface is seen at a grazing angle, so the exact projection into the facing view is
// used instead.) Caps are textured the same way when some view sees them at more than ~25 deg,
// else left untextured.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "reconstruct/mesh.h"
#include "reconstruct/reconstructor.h"

namespace revolve::reconstruct {

struct MeridianOptions {
  int row_step_px = 9;      // h_RANGE: feature points on every k-th image row, 1..256
  bool both_sides = false;  // also take the rightmost pixel, as the meridian at theta + 180 deg
  // Largest side of the texture atlas (64..16384); 0: no atlas (the view-dependent texture only).
  int atlas_size_px = 4096;
};

// The textured result of the meridian method: the mesh with its view-dependent texture
// (mesh.view_texture: only the images used, untextured faces -1) and, when
// MeridianOptions::atlas_size_px > 0, the same texture packed into an atlas (mesh.texture, uvs,
// uv_faces: reconstruct/texture/view_atlas.h) for the formats that hold one image (OBJ, glTF).
struct MeridianModel {
  Mesh mesh;
  int meridian_count = 0;
  int row_count = 0;

  bool HasTexture() const { return mesh.HasViewTexture(); }
};

class MeridianReconstructor final : public Reconstructor {
 public:
  // Precondition: options in range (Create checks; 1 <= row_step_px <= 256).
  explicit MeridianReconstructor(const MeridianOptions& options);

  // Extracts the view's meridian(s). `mask`: CV_8UC1 of the view's size, non-zero = object;
  // `image`: its photo (CV_8UC3 BGR or CV_8UC1 grey, same size) for texture, or empty. Errors:
  // bad_input for a wrong mask or image size or type, a view looking along the rotation axis
  // (the axis does not cross the image rows), or a non-finite projection.
  Expected<void> Integrate(const cv::Mat& mask, const cv::Mat& image, const View& view) override;

  // FinishModel().mesh (with its view-dependent texture and atlas).
  Expected<Mesh> Finish() override;

  // The mesh with its texture. Errors: bad_input when fewer than 3 distinct meridians were
  // integrated, no row holds an object pixel (empty silhouettes) or only one does.
  Expected<MeridianModel> FinishModel() const;

  int view_count() const { return static_cast<int>(views_.size()); }

 private:
  struct Meridian {
    double azimuth_rad = 0.0;  // of the half-plane through the axis holding its points
    bool left = true;
    int view = 0;
    // Per image row: the feature point, or nullopt (no object pixel in that row).
    std::vector<std::optional<Eigen::Vector3d>> points;
    std::vector<Eigen::Vector3d> axis_points;  // per image row: where the row meets the axis
  };
  struct ViewData {
    View view;
    cv::Mat image;  // BGR or empty
  };

  // The steps of FinishModel. The meridians in azimuth order: the left ones (duplicates of one
  // azimuth dropped), then the right ones not within a quarter step of a left one; bad_input
  // when fewer than 3.
  Expected<std::vector<const Meridian*>> ChooseMeridians() const;
  // The image rows sampled: every row_step_px-th from the object's top row, and its bottom row
  // (at least two rows); bad_input when no row or only one holds an object pixel.
  Expected<std::vector<int>> SampledRows(const std::vector<const Meridian*>& chosen) const;
  // model->mesh from the meridians' points on `rows` (model's meridian_count and row_count set):
  // strips of quads between neighbouring meridians and the two caps, outward; returns each
  // face's strip (meridian_count: the top cap, + 1: the bottom cap).
  static std::vector<int> BuildMesh(const std::vector<const Meridian*>& chosen,
                                    const std::vector<int>& rows, MeridianModel* model);
  // The texture (when any view has an image): per strip and cap the view facing it most
  // squarely, its image, and each face's uvs in it (mesh.view_texture), then its atlas when
  // atlas_size_px > 0. Errors: those of AtlasFromViewTexture.
  Expected<void> TextureStrips(const std::vector<int>& face_strip, MeridianModel* model) const;

  MeridianOptions options_;
  int width_px_ = 0;
  int height_px_ = 0;
  std::vector<ViewData> views_;
  std::vector<Meridian> meridians_;
};

}  // namespace revolve::reconstruct
