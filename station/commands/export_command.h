// `revolve export SCAN_DIR --format colmap|nerfstudio --out DIR`: a scan as the input of
// photogrammetry and neural-rendering tools, with the cameras the turntable already knows.
//
// DIR/images/<name>          the scan's frames (as saved: undistorted with a calibration), copied
// DIR/masks/<name>.png       its silhouettes in COLMAP's convention (the image's full name plus
//                            .png; 0 = ignore, 255 = object), used by nerfstudio too
// colmap:     DIR/sparse/0/cameras.txt, images.txt, points3D.txt (no points): a COLMAP text model
// nerfstudio: DIR/transforms.json
// The cameras are the scan's own (station/scan_geometry.h: its calibration, else the camera's
// geometry) in the model's frame and units (millimetres): the scan's model.ply lines up with
// them. Conventions: reconstruct/cameras/camera_export.h. Every file is written atomically; DIR
// is created when missing, files already there are replaced.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>

namespace revolve::station {

struct ExportOptions {
  std::filesystem::path scan_dir;
  std::string format = "colmap";  // colmap | nerfstudio
  std::filesystem::path out;
};

// Returns station's exit codes (station/exit_codes.h): kExitOk; kExitUsage for an unknown format
// or no --out; kExitConfig when the scan's scan.toml or calibration.toml cannot be used;
// kExitFailed when the folder is not a scan, holds no readable stop, its cameras are not metric
// pinhole cameras (a thesis-mode or orthographic scan: calibrate the rig first), or a file cannot
// be written. Errors name the file or option at fault.
int RunExportCommand(const ExportOptions& options, std::ostream& out, std::ostream& err);

}  // namespace revolve::station
