// Posed pinhole cameras written for photogrammetry and neural-rendering tools: a COLMAP text model
// (cameras.txt, images.txt, points3D.txt: https://colmap.github.io/format.html) and a nerfstudio
// transforms.json (https://docs.nerf.studio/quickstart/data_conventions.html). Pure: text in,
// text out; station/commands/export_command.h writes the files.
//
// Conventions (revolve's, base/rig.h, on the left; what is written, on the right):
//  - world = the object frame (millimetres, z up the turntable axis, origin on the plate), so a
//    scan's model.ply lies where the cameras see it, at its true size.
//  - pixels: revolve puts the centre of the top-left pixel at (0, 0); COLMAP and nerfstudio put
//    the image's top-left CORNER there (that pixel's centre at (0.5, 0.5)): cx, cy are written
//    plus 0.5.
//  - COLMAP: one camera (id 1), one image per view (ids 1..N in the order given), each with its
//    world-to-camera pose as the unit quaternion QW QX QY QZ (Hamilton, QW >= 0) of R and the
//    translation T of cam_from_object (OpenCV camera axes: x right, y down, z forward).
//    PINHOLE (fx fy cx cy) without distortion, OPENCV (fx fy cx cy k1 k2 p1 p2) with it.
//  - nerfstudio: camera-to-world 4x4 "transform_matrix" per frame with OpenGL camera axes (x right,
//    y up, z back: the OpenCV axes with y and z negated), "fl_x", "fl_y", "cx", "cy", "w", "h",
//    "k1", "k2", "p1", "p2", "camera_model": "OPENCV"; "file_path" and "mask_path" relative to
//    the transforms.json.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "base/error.h"
#include "base/rig.h"

namespace revolve::reconstruct {

// A pinhole camera with OpenCV's radial-tangential distortion (all zero: none).
struct PinholeCamera {
  Intrinsics intrinsics;  // base/rig.h: pixel centres, (0, 0) = the top-left pixel's
  double k1 = 0.0;
  double k2 = 0.0;
  double p1 = 0.0;
  double p2 = 0.0;

  bool HasDistortion() const { return k1 != 0.0 || k2 != 0.0 || p1 != 0.0 || p2 != 0.0; }
};

// One image of the export: its file name (inside the export's images/ folder), its mask's file
// name (inside masks/; empty: none) and its pose.
struct PosedImage {
  std::string name;
  std::string mask_name;
  Eigen::Isometry3d cam_from_object = Eigen::Isometry3d::Identity();
};

// Splits a pinhole view's P = s K [R | t] (s > 0, R a rotation, K upper triangular with a
// positive diagonal and K(2,2) = 1). Errors: bad_input for an affine (orthographic) view, a
// mirrored one (det R < 0 after making K's diagonal positive), or skew beyond 1e-6 fx, which
// COLMAP's camera models cannot hold.
struct PinholeView {
  Intrinsics intrinsics;
  Eigen::Isometry3d cam_from_object = Eigen::Isometry3d::Identity();
};
Expected<PinholeView> DecomposeView(const View& view);

// The mask's name in COLMAP's convention: the image's full name plus ".png".
std::string ColmapMaskName(const std::string& image_name);

// cameras.txt: camera 1 (PINHOLE or OPENCV, see the file comment).
std::string ColmapCamerasText(const PinholeCamera& camera);
// images.txt: image k + 1 for images[k], camera 1, no 2D points (an empty second line).
std::string ColmapImagesText(const std::vector<PosedImage>& images);
// points3D.txt with no points.
std::string ColmapEmptyPointsText();

// transforms.json (see the file comment); frames in the order given; "images/<name>" and
// "masks/<mask_name>" as paths.
nlohmann::json NerfstudioTransforms(const PinholeCamera& camera,
                                    const std::vector<PosedImage>& images);

}  // namespace revolve::reconstruct
