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
  std::string method = "hull";  // hull
  int resolution = 192;         // voxels along the longest side of the volume, 16..1024
  // Carving volume in the object frame (mm). ParseOptions derives it from volume_radius_mm (r)
  // and volume_height_mm (h): the box [-r, r] x [-r, r] x [0, h] around a cylinder standing on
  // the plate, so nothing below the plate is ever part of the model.
  Eigen::Vector3d bbox_min_mm{-60.0, -60.0, 0.0};
  Eigen::Vector3d bbox_max_mm{60.0, 60.0, 120.0};
  std::vector<std::string> formats = {"ply", "wrl"};  // each one of ply | wrl
};

// Parses [reconstruct]: method ("hull"), resolution (16..1024), volume_radius_mm and
// volume_height_mm (1..10000 mm each), formats (a non-empty array of "ply" | "wrl"; duplicates
// are dropped). Absent keys keep the defaults above. Errors: bad_input naming file:line:column
// and the key, for a wrong type, a value out of range or an unknown key.
Expected<ReconstructOptions> ParseOptions(const config::Section& section);

class Reconstructor {
 public:
  virtual ~Reconstructor() = default;

  // Adds one view: `mask` is CV_8UC1 (non-zero = object) of the view's image size, `image` the
  // frame it came from (CV_8UC3 BGR, may be empty; used for colour). Errors: bad_input when the
  // mask size does not match the view.
  virtual Expected<void> Integrate(const cv::Mat& mask, const cv::Mat& image, const View& view) = 0;

  // Extracts the surface of everything integrated so far: a watertight, 2-manifold,
  // outward-oriented triangle mesh. Errors: bad_input when nothing remains (empty silhouettes or
  // a volume that misses the object).
  virtual Expected<Mesh> Finish() = 0;
};

// The reconstructor for `options.method` ("hull": incremental visual hull, surface by marching
// cubes with sub-voxel vertices; reconstruct/hull/visual_hull.h). `image` is not used yet.
// Errors: bad_input for an unknown method, a resolution outside 16..1024 or an empty volume.
Expected<std::unique_ptr<Reconstructor>> Create(const ReconstructOptions& options);

}  // namespace revolve::reconstruct
