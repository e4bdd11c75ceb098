// A triangle mesh in the object frame (base/rig.h), with optional vertex colours and an optional
// texture atlas.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace revolve::reconstruct {

using Color = Eigen::Matrix<std::uint8_t, 3, 1>;  // RGB

// View-dependent texture (the thesis's 4.3.4, made by the meridian method): each face is textured
// straight from one view's image, at its vertices' projections into that image. `images` are the
// frames used (CV_8UC3 BGR; copies share their pixels); `uvs` are points on them in VRML's
// convention: s from the left edge, t from the BOTTOM edge, both in [0, 1] of the image's size.
// `uv_faces` and `face_image` are empty or one per face: corner c of face f samples
// images[face_image[f]] at uvs[uv_faces[f][c]]; face_image -1 marks an untextured face (its
// uv_faces entry is unused).
struct ViewTexture {
  std::vector<cv::Mat> images;
  std::vector<Eigen::Vector2f> uvs;
  std::vector<Eigen::Vector3i> uv_faces;
  std::vector<int> face_image;
};

struct Mesh {
  std::vector<Eigen::Vector3f> vertices;
  // Counter-clockwise seen from outside (normals point outward).
  std::vector<Eigen::Vector3i> faces;
  // Empty, or one per vertex.
  std::vector<Color> colors;
  // Empty, or one unit normal per vertex: the area-weighted mean of its faces' normals, +z where
  // that is zero (as the writers compute them when they are absent). TextureMesh fills them from
  // the normals it chooses views with; whoever moves the vertices or changes the faces clears
  // them.
  std::vector<Eigen::Vector3f> normals;

  // Texture: `texture` is the atlas image (CV_8UC3, BGR as OpenCV keeps images; copies of a Mesh
  // share its pixels). `uvs` are points on it: u from the left edge, v from the TOP edge, both in
  // [0, 1] of the image's size (glTF's convention; pixel (x, y) of the atlas has its centre at
  // ((x + 0.5) / cols, (y + 0.5) / rows)). `uv_faces` is empty or one triple per face: corner c
  // of faces[f] samples the texture at uvs[uv_faces[f][c]]. A vertex may carry different uvs in
  // different faces (a seam between charts).
  std::vector<Eigen::Vector2f> uvs;
  std::vector<Eigen::Vector3i> uv_faces;
  cv::Mat texture;

  // The view-dependent texture the VRML writer writes (reconstruct/meridian/meridian_vrml.h);
  // the other writers use the atlas above. Whoever changes the faces clears it.
  ViewTexture view_texture;

  bool HasColors() const { return !colors.empty() && colors.size() == vertices.size(); }
  bool HasNormals() const { return !normals.empty() && normals.size() == vertices.size(); }
  bool HasTexture() const {
    return !texture.empty() && !uvs.empty() && !faces.empty() && uv_faces.size() == faces.size();
  }
  bool HasViewTexture() const {
    return !view_texture.images.empty() && !faces.empty() &&
           view_texture.face_image.size() == faces.size() &&
           view_texture.uv_faces.size() == faces.size();
  }
};

// How much of a mesh being made is final. Each stage includes those before it:
//   kSurface  vertices, faces and view_texture;
//   kColors   normals and colors too (each empty or one per vertex);
//   kUvs      uvs and uv_faces too, and a non-empty texture follows at kDone (reached only on the
//             way to a textured mesh);
//   kDone     everything.
// A field is final when no one writes it again; whoever is told of a stage may read that stage's
// fields from any thread while the maker goes on writing the others.
enum class MeshStage { kSurface, kColors, kUvs, kDone };

// Told of each stage a mesh reaches, in order, each at most once (stages may be skipped), on the
// thread that makes the mesh; it must return quickly (start work, not do it). The mesh stays at
// its address meanwhile. An empty hook is never called.
using MeshStageHook = std::function<void(MeshStage)>;

}  // namespace revolve::reconstruct
