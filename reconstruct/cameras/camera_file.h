// Per-view cameras imported from a text file (`revolve reconstruct --cameras FILE`), so calibrated
// image sets made by others reconstruct as they come.
//
// Two formats, one view a line, blank lines and `#` comments ignored, an optional first line
// holding only the view count:
//  - Middlebury `*_par.txt`: `name k11 k12 k13 k21 k22 k23 k31 k32 k33 r11 … r33 t1 t2 t3`
//    (21 numbers; the projection is K·[R t]);
//  - projection matrices: `name p11 p12 p13 p14 p21 … p34` (12 numbers, row-major 3×4 P, any
//    scale and sign).
// The format is told by the count of numbers on the first view line; every line must agree.
// Pixel (0, 0) is the centre of the top-left pixel (as in base/rig.h). Units are the file's
// (Middlebury: metres). A matrix need not split into a sensible K, R, t (real sets have skew and
// mirrored frames): reconstruction projects with P itself; CheckProjection says what is odd.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"
#include "base/rig.h"

namespace revolve::reconstruct {

enum class CameraFileFormat { kMiddlebury, kProjection };

struct ImportedCamera {
  std::string name;  // the image file name as written in the file
  Matrix34d pixel_from_object = Matrix34d::Zero();
  int line = 0;  // 1-based line in the file, for messages
};

struct CameraFile {
  std::string origin;  // the file's path (or a label), for messages
  CameraFileFormat format = CameraFileFormat::kMiddlebury;
  std::vector<ImportedCamera> cameras;  // in file order

  // The camera for an image file: the entry whose name equals `image_file_name`, else the one
  // whose name without its extension equals the image's name without its extension
  // ("dinoSR0001" matches "dinoSR0001.png"). nullptr when none does.
  const ImportedCamera* Find(std::string_view image_file_name) const;
};

// Parses a camera file's text. `origin` names it in errors. Errors: bad_input naming
// origin:line and what is wrong (a wrong count of numbers, a number that does not parse or is not
// finite, lines of both formats, a view count that disagrees with the lines, a name given
// twice, a matrix whose left 3x3 block is singular (not a pinhole or affine camera at all), no
// view at all).
Expected<CameraFile> ParseCameraFile(std::string_view text, std::string origin);

// Reads and parses `path`. Errors: not_found / io naming the file, and ParseCameraFile's.
Expected<CameraFile> ReadCameraFile(const std::filesystem::path& path);

// One view per image, in the order of `image_file_names` (CameraFile::Find), each of
// width_px x height_px; P as given (its sign is fixed later, NormaliseViewSign). Errors:
// bad_input naming the first image that has no camera in the file (fewer cameras than images).
Expected<std::vector<View>> ViewsForImages(const CameraFile& file,
                                           const std::vector<std::string>& image_file_names,
                                           int width_px, int height_px);

// What a projection matrix says about the camera behind it (RQ decomposition of its left 3x3
// block M = K·R, K upper triangular with a positive diagonal).
struct ProjectionCheck {
  bool affine = false;    // last row of P is [0 0 0 s]
  bool mirrored = false;  // det(M) < 0 after the depth sign is fixed: a left-handed frame
  double skew = 0.0;      // K(0,1) / K(0,0)
  double aspect = 1.0;    // K(1,1) / K(0,0)
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // proper rotation (det +1), or -R when mirrored
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  // Empty when P is a plain pinhole K·[R t] with square pixels (|skew| and |aspect - 1| under
  // 1e-3); otherwise a short description ("skew 0.012, mirrored frame").
  std::string oddities;
};

// Decomposes a pinhole P, whose left 3x3 block must be non-singular (an affine P is reported as
// affine with K, R, t left as identity and zero). K is scaled to K(2,2) = 1 and t = K^-1 p4 at
// that scale. `mirrored` is meaningful once P's sign is fixed so that points in front have a
// positive depth (NormaliseViewSign in reconstruct/cameras/views.h).
ProjectionCheck CheckProjection(const Matrix34d& pixel_from_object);

}  // namespace revolve::reconstruct
