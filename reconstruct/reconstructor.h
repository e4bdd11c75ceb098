// The reconstruction core's entry point: silhouettes in, one view at a time; a mesh out.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/rig.h"
#include "config/config.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

// [reconstruct]
struct ReconstructOptions {
  std::string method = "hull";  // hull | meridian
  int resolution = 192;         // voxels along the longest side of the volume, 16..1024
  // Carving volume in the object frame (mm). ParseOptions derives it from volume_radius_mm (r)
  // and volume_height_mm (h): the box [-r, r] x [-r, r] x [0, h] around a cylinder standing on
  // the plate, so nothing below the plate is ever part of the model.
  Eigen::Vector3d bbox_min_mm{-60.0, -60.0, 0.0};
  Eigen::Vector3d bbox_max_mm{60.0, 60.0, 120.0};
  // The unit the log gives lengths in: mm for a scan; `reconstruct --images` sets the cameras
  // file's unit ("units") or "px" (thesis mode), as the *_mm lengths are then in those.
  std::string length_unit = "mm";
  // each one of ply | obj | stl | glb | wrl
  std::vector<std::string> formats = {"ply", "obj", "stl", "glb", "wrl"};
  // hull: colour from the frames (reconstruct/texture/texture.h): vertex colours always, and a
  // texture atlas (for OBJ and glTF) when `texture`; texture_size_px bounds the atlas's side
  // (64..16384). meridian: the view-dependent texture always (VRML), packed into an atlas (OBJ,
  // glTF) when `texture`.
  bool texture = true;
  int texture_size_px = 4096;
  // hull: cut the model at the table plane (z = 0) and close it there with a flat face, so it
  // stands and prints; false keeps whatever part of the carving box lies below the plate.
  bool flat_bottom = true;
  // meridian: feature points on every k-th image row (the thesis's h_RANGE), 1..256.
  int meridian_row_step_px = 9;
  // meridian: also take the rightmost pixel as the meridian at theta + 180 deg (thesis 6.2).
  bool meridian_both_sides = false;
  // hull: keep a reference to each frame given to Integrate rather than a copy, for callers that
  // never write to a frame afterwards (reconstruct --images); a camera may reuse its buffers, so
  // the scan keeps copies. Not a configuration key.
  bool share_frames = false;
  // hull: Finish is called once, after the last Integrate: the hull frees its copies of the masks
  // once the surface is placed, before the colours are made (reconstruct --images: less memory
  // at the peak). Not a configuration key.
  bool finish_once = false;
};

// Parses [reconstruct]: method ("hull" | "meridian"), meridian_row_step_px (1..256),
// meridian_both_sides (bool), resolution (16..1024), volume_radius_mm and
// volume_height_mm (1..10000 mm each), formats (a non-empty array of "ply" | "obj" | "stl" |
// "glb" | "wrl"; duplicates are dropped), texture (bool), texture_size_px (64..16384),
// flat_bottom (bool). Absent keys keep the defaults above. Errors: bad_input naming
// file:line:column and the key, for a wrong type, a value out of range or an unknown key.
Expected<ReconstructOptions> ParseOptions(const config::Section& section);

// The descriptions of the keys of [reconstruct], for the configuration reference
// (config/reference.h).
config::OptionDocs ReferenceDocs();

class Reconstructor {
 public:
  virtual ~Reconstructor() = default;

  // Adds one view: `mask` is CV_8UC1 (non-zero = object) of the view's image size, `image` the
  // frame it came from (CV_8UC3 BGR, may be empty; used for colour). Errors: bad_input when the
  // mask size (or a non-empty frame's size) does not match the view. The hull takes frames of
  // 1, 3 (BGR) or 4 (BGRA) 8-bit channels; a frame of another type is not used for colour.
  virtual Expected<void> Integrate(const cv::Mat& mask, const cv::Mat& image, const View& view) = 0;

  // The rectangle of a frame of `view` that the model's colours may be read from, for a view
  // integrated with `mask`. The hull: the mask's bounding rectangle widened by how far a surface
  // vertex can project from it (one voxel's projection at most: each lies on a grid edge from a
  // voxel centre inside the silhouette) and by the texture's reach (kTextureReadMarginPx), within
  // the frame; the whole frame when some of the volume lies outside the view (it keeps what it
  // cannot see). Default: the whole frame.
  virtual cv::Rect FrameWindow(const cv::Mat& mask, const View& view) const;

  // Integrate with a window of the frame only: `image` holds the frame's pixels from
  // `image_origin` on, and covers FrameWindow(mask, view). The model is the one the whole frame
  // gives. Errors: Integrate's, and bad_input for a window that leaves the frame or does not
  // cover FrameWindow (the meridian method reads whole frames).
  virtual Expected<void> IntegrateWindow(const cv::Mat& mask, const cv::Mat& image,
                                         cv::Point image_origin, const View& view);

  // Extracts the surface of everything integrated so far: a watertight, 2-manifold,
  // outward-oriented triangle mesh. Errors: bad_input when nothing remains (empty silhouettes or
  // a volume that misses the object).
  virtual Expected<Mesh> Finish() = 0;

  // Finish into `*mesh` (which stays at its address), telling `on_stage` of each MeshStage as
  // the mesh reaches it (reconstruct/mesh.h; kDone last, on success), so that a ModelWriter
  // (reconstruct/io/model_writer.h) writes each file as soon as what it holds is final. On an
  // error the stages told stand, but the mesh is not finished. The hull: kSurface once the
  // surface is placed, kColors and kUvs as TextureMesh sets them. Default: Finish, then kDone.
  virtual Expected<void> FinishStaged(Mesh* mesh, const MeshStageHook& on_stage);
};

// The reconstructor for `options.method` ("hull": incremental visual hull, surface by marching
// cubes with sub-voxel vertices; reconstruct/hull/visual_hull.h; "meridian": the thesis's
// meridian feature points and strips, reconstruct/meridian/meridian.h, which ignores the volume
// and resolution). The hull keeps a copy of each non-empty frame (1.3 MB at 768x576) and colours
// the mesh from them in Finish (vertex colours, and a texture atlas when options.texture); with
// options.share_frames, a reference to each BGR frame instead.
// Errors: bad_input for an unknown method, a resolution outside 16..1024 or an empty volume.
Expected<std::unique_ptr<Reconstructor>> Create(const ReconstructOptions& options);

}  // namespace revolve::reconstruct
