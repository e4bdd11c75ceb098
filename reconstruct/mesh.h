// A triangle mesh in the object frame (base/rig.h), with optional vertex colours and an optional
// texture atlas.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace revolve::reconstruct {

using Color = Eigen::Matrix<std::uint8_t, 3, 1>;  // RGB

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

  bool HasColors() const { return !colors.empty() && colors.size() == vertices.size(); }
  bool HasNormals() const { return !normals.empty() && normals.size() == vertices.size(); }
  bool HasTexture() const {
    return !texture.empty() && !uvs.empty() && !faces.empty() && uv_faces.size() == faces.size();
  }
};

}  // namespace revolve::reconstruct
