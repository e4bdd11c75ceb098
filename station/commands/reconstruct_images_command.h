// `revolve reconstruct --images DIR`: a model from a folder of images made anywhere, with the
// thesis's calibration-free geometry or with per-view cameras from a file.
//
// Output in `out` (created when missing; files in it are replaced atomically):
//   model/model.<format>   one per --formats entry (the meridian method's .wrl is the thesis's
//                          textured VRML with model_texNN.jpg beside it when the inputs are photos)
//   masks/<stem>.png       the mask of every input image (1-bit PNG), as carved
//   contact_sheet.png      every image with its mask outlined
//   report.json            inputs, segmentation (method, why, backdrop), camera model, units and
//                          scale, carving volume, dimensions and volume, per view the mask area,
//                          the silhouette reprojection IoU and whether the view disagrees or was
//                          left out (and why), time per stage
#pragma once

#include <array>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

namespace revolve::station {

struct ReconstructImagesOptions {
  std::filesystem::path images;  // --images DIR (required)
  std::string pattern;     // --pattern, e.g. "bw_shoe{angle}.tif"; empty: every image, by name
  double step_deg = 10.0;  // --step-deg: angle between stops (thesis mode, {index})
  std::optional<std::filesystem::path> cameras;  // --cameras FILE: Middlebury *_par.txt or 3x4 P
  std::string method = "hull";                   // --method hull | meridian
  int resolution = 192;                          // --resolution: hull voxels on the longest side
  // --bbox X0 Y0 Z0 X1 Y1 Z1: carving volume in the object frame (thesis mode: pixels, z up from
  // the bottom row; --cameras: the file's units); absent: found from the silhouettes.
  std::optional<std::array<double, 6>> bbox;
  std::vector<std::string> formats = {"ply", "wrl"};  // --formats ply,obj,stl,glb,wrl
  std::filesystem::path out;                          // --out DIR (required)
  // --segment: how photos are segmented: a [segment] method (auto, graphcut, background, otsu,
  // fixed, chroma; capture/segmenter.h) or "threshold" (object where any channel exceeds
  // --threshold: the old rule for photos on black). Empty: the --config file's method, else auto.
  std::string segment;
  // --config FILE: a TOML file whose [segment] table configures the segmentation.
  std::optional<std::filesystem::path> config;
  // --threshold: with --segment threshold: object where any channel exceeds it (0..254).
  int threshold = 20;
  int row_step_px = 9;      // --row-step: meridian feature points every k-th row (h_RANGE)
  bool both_sides = false;  // --both-sides: meridian from both sides of the axis (T/2 images)
  // --max-image-mp: larger images are refused from their headers, before decoding.
  double max_image_mp = 100.0;
};

// Runs the reconstruction: progress and a summary to `out`, errors to `err` (each naming the file
// or option at fault). Returns station's exit codes (scan_command.h): kExitOk, kExitUsage for an
// option out of range, kExitFailed when an input is missing, unreadable or inconsistent (image
// sizes differ, fewer cameras than images, an empty silhouette) or the model cannot be written.
int RunReconstructImages(const ReconstructImagesOptions& options, std::ostream& out,
                         std::ostream& err);

}  // namespace revolve::station
