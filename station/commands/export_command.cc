#include "station/commands/export_command.h"

#include <fstream>
#include <ostream>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ostream.h>

#include "base/atomic_file.h"
#include "base/png_encode.h"
#include "reconstruct/cameras/camera_export.h"
#include "station/exit_codes.h"
#include "station/saved_stops.h"
#include "station/scan_folder.h"
#include "station/scan_geometry.h"
#include "station/station_config.h"

namespace revolve::station {
namespace {

namespace fs = std::filesystem;
namespace rc = revolve::reconstruct;

// A failure and the exit code it maps to.
struct Failure {
  int code = kExitFailed;
  std::string message;
};

template <typename T>
using Result = std::expected<T, Failure>;

Failure Fail(int code, std::string message) { return Failure{code, std::move(message)}; }

// The scan's cameras and images, ready to write.
struct ScanCameras {
  rc::PinholeCamera camera;
  std::vector<rc::PosedImage> images;
  std::vector<fs::path> frame_files;  // absolute, one per image
  std::vector<cv::Mat> masks;         // CV_8UC1, one per image
};

bool SameIntrinsics(const Intrinsics& a, const Intrinsics& b) {
  const double tolerance = 1e-6 * a.fx_px;
  return a.width_px == b.width_px && a.height_px == b.height_px &&
         std::abs(a.fx_px - b.fx_px) <= tolerance && std::abs(a.fy_px - b.fy_px) <= tolerance &&
         std::abs(a.cx_px - b.cx_px) <= tolerance && std::abs(a.cy_px - b.cy_px) <= tolerance;
}

Result<ScanCameras> LoadScanCameras(const fs::path& dir) {
  auto manifest = ReadManifest(dir);
  if (!manifest) return std::unexpected(Fail(kExitFailed, manifest.error().message));
  auto config = LoadStationConfig(dir / "scan.toml");
  if (!config) return std::unexpected(Fail(kExitConfig, config.error().message));
  auto camera = capture::Create(config->camera, std::make_shared<SimulatedPlate>());
  if (!camera) {
    return std::unexpected(Fail(
        kExitConfig, fmt::format("{}: {}", (dir / "scan.toml").string(), camera.error().message)));
  }
  std::error_code ec;
  const fs::path calibration_file =
      fs::exists(dir / "calibration.toml", ec) ? dir / "calibration.toml" : "";
  auto geometry = ScanGeometry::Create(config->reconstruct, **camera, calibration_file);
  if (!geometry) return std::unexpected(Fail(kExitConfig, geometry.error().message));
  if (!geometry->metric()) {
    return std::unexpected(
        Fail(kExitFailed,
             fmt::format("{}: the scan has no calibrated camera (thesis mode: orthographic, scale "
                         "unknown); photogrammetry tools need pinhole cameras: calibrate the rig "
                         "(`revolve calibrate`) and scan again",
                         dir.string())));
  }
  std::vector<std::string> skipped;
  auto stops = ReadSavedStops(dir, *manifest, false, &skipped);
  if (!stops) return std::unexpected(Fail(kExitFailed, stops.error().message));
  if (stops->empty()) {
    return std::unexpected(Fail(
        kExitFailed,
        skipped.empty() ? fmt::format("{}: stops: lists no stop (nothing was captured): nothing to "
                                      "export",
                                      (dir / "manifest.json").string())
                        : fmt::format("{}: no stop with a readable mask", dir.string())));
  }
  ScanCameras result;
  for (SavedStop& stop : *stops) {
    const View view = geometry->ViewAt(stop.readback_deg, stop.mask.cols, stop.mask.rows);
    auto pinhole = rc::DecomposeView(view);
    if (!pinhole) {
      return std::unexpected(Fail(kExitFailed, fmt::format("{}: stop {}: {}", dir.string(),
                                                           stop.index, pinhole.error().message)));
    }
    if (result.images.empty()) {
      result.camera.intrinsics = pinhole->intrinsics;
    } else if (!SameIntrinsics(result.camera.intrinsics, pinhole->intrinsics)) {
      return std::unexpected(
          Fail(kExitFailed, fmt::format("{}: stop {}: the camera's intrinsics differ from the "
                                        "first stop's",
                                        dir.string(), stop.index)));
    }
    const std::string name = fs::path(stop.frame_file).filename().string();
    result.images.push_back(
        rc::PosedImage{name, rc::ColmapMaskName(name), pinhole->cam_from_object});
    result.frame_files.push_back(dir / stop.frame_file);
    result.masks.push_back(stop.mask);
  }
  return result;
}

Result<void> Write(const fs::path& path, std::string_view bytes) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (ec) {
    return std::unexpected(
        Fail(kExitFailed, fmt::format("{}: cannot create the folder: {}",
                                      path.parent_path().string(), ec.message())));
  }
  if (Expected<void> w = WriteFileAtomically(path, bytes); !w) {
    return std::unexpected(Fail(kExitFailed, w.error().message));
  }
  return {};
}

// images/ and masks/ (shared by both formats).
Result<void> WriteImagesAndMasks(const ScanCameras& scan, const fs::path& out) {
  for (std::size_t i = 0; i < scan.images.size(); ++i) {
    std::ifstream in(scan.frame_files[i], std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    if (!in || bytes.str().empty()) {
      return std::unexpected(
          Fail(kExitFailed, fmt::format("{}: cannot be read", scan.frame_files[i].string())));
    }
    if (auto w = Write(out / "images" / scan.images[i].name, bytes.str()); !w) return w;
    cv::Mat binary = scan.masks[i] != 0;  // 255 object, 0 ignore
    const Expected<std::string> png = EncodePng(binary);
    if (!png) {
      return std::unexpected(
          Fail(kExitFailed, fmt::format("{}: the mask cannot be encoded: {}",
                                        scan.images[i].mask_name, png.error().message)));
    }
    if (auto w = Write(out / "masks" / scan.images[i].mask_name, std::string_view(*png)); !w) {
      return w;
    }
  }
  return {};
}

Result<std::vector<fs::path>> WriteExport(const ExportOptions& options) {
  auto scan = LoadScanCameras(options.scan_dir);
  if (!scan) return std::unexpected(scan.error());
  if (auto w = WriteImagesAndMasks(*scan, options.out); !w) return std::unexpected(w.error());
  std::vector<fs::path> files;
  if (options.format == "colmap") {
    const fs::path sparse = options.out / "sparse" / "0";
    const std::pair<fs::path, std::string> texts[] = {
        {sparse / "cameras.txt", rc::ColmapCamerasText(scan->camera)},
        {sparse / "images.txt", rc::ColmapImagesText(scan->images)},
        {sparse / "points3D.txt", rc::ColmapEmptyPointsText()}};
    for (const auto& [path, text] : texts) {
      if (auto w = Write(path, text); !w) return std::unexpected(w.error());
      files.push_back(path);
    }
  } else {
    const fs::path path = options.out / "transforms.json";
    if (auto w = Write(path, rc::NerfstudioTransforms(scan->camera, scan->images).dump(2) + "\n");
        !w) {
      return std::unexpected(w.error());
    }
    files.push_back(path);
  }
  return files;
}

}  // namespace

int RunExportCommand(const ExportOptions& options, std::ostream& out, std::ostream& err) {
  if (options.format != "colmap" && options.format != "nerfstudio") {
    fmt::print(err, "revolve export: --format {}: expected colmap or nerfstudio\n", options.format);
    return kExitUsage;
  }
  if (options.out.empty()) {
    fmt::print(err, "revolve export: --out DIR is required\n");
    return kExitUsage;
  }
  auto files = WriteExport(options);
  if (!files) {
    fmt::print(err, "revolve export: {}\n", files.error().message);
    return files.error().code;
  }
  fmt::print(out, "revolve export: {} -> {} ({})\n", options.scan_dir.string(),
             options.out.string(), options.format);
  for (const fs::path& f : *files) fmt::print(out, "  {}\n", f.string());
  fmt::print(out, "  {} and {}\n", (options.out / "images").string(),
             (options.out / "masks").string());
  return kExitOk;
}

}  // namespace revolve::station
