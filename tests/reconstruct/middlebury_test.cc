// Real calibrated image sets made by others (shared/data, Middlebury multi-view stereo, Seitz et
// al. CVPR 2006) through the path a user takes: `revolve reconstruct --images DIR --cameras PAR`
// with default options: segmentation `auto` (capture/segment), silhouette consensus, the carving
// volume found from the silhouettes (no box given). The model is reprojected into every view and
// compared with the reference silhouettes kept with the tests (tests/data/reference_silhouettes,
// made by another method: its README), and its volume and carving box with the sets' published
// figures: a blob (a carving volume that is not tight, backdrop taken for object) fails both.
//
// Bars (issue 17): dinoSparseRing, over the authors' good views, mean IoU >= 0.975;
// templeSparseRing >= 0.95.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "reconstruct/cameras/camera_file.h"
#include "reconstruct/cameras/views.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/metrics/metrics.h"
#include "reconstruct/metrics/reprojection.h"
#include "station/commands/reconstruct_images_command.h"
#include "station/commands/scan_command.h"
#include "tests/support/test_files.h"

namespace revolve::reconstruct {
namespace {

namespace fs = std::filesystem;
using test_support::ReadLines;

const fs::path kData = fs::path(REVOLVE_SHARED_DIR) / "data";
const fs::path kReference = fs::path(REVOLVE_SOURCE_DIR) / "tests/data/reference_silhouettes";

struct SetResult {
  nlohmann::json report;
  MeshStats stats;
  Box volume;
  std::vector<double> reference_iou;  // per scored view: the model against the reference
  double mean_reference_iou = 0.0;
  double min_reference_iou = 1.0;
};

Eigen::Vector3d Vec3(const nlohmann::json& j) {
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

// `revolve reconstruct --images dir --cameras dir/par --out OUT --formats ply`, then the model
// against the reference silhouettes of the views listed in `good_views` (empty: all).
SetResult Reconstruct(const std::string& set, const std::string& reference, const std::string& par,
                      const std::string& good_views) {
  SetResult result;
  const fs::path dir = kData / set;
  const fs::path out = fs::temp_directory_path() / fmt::format("revolve_middlebury_{}", getpid());
  fs::remove_all(out);
  station::ReconstructImagesOptions options;
  options.images = dir;
  options.cameras = dir / par;
  options.formats = {"ply"};
  options.out = out;
  std::ostringstream log, err;
  EXPECT_EQ(station::RunReconstructImages(options, log, err), station::kExitOk) << err.str();
  std::ifstream report_in(out / "report.json");
  result.report = nlohmann::json::parse(report_in, nullptr, false);
  Expected<Mesh> mesh = ReadPly(out / "model" / "model.ply");
  if (!result.report.is_discarded()) {
    // auto says what it picked and why; the masks a person checks are written, one per image.
    EXPECT_NE(result.report["segmentation"]["method"], "auto");
    EXPECT_FALSE(result.report["segmentation"]["reason"].get<std::string>().empty());
    for (const nlohmann::json& view : result.report["reprojection"]["per_view"]) {
      const fs::path image = view["image"].get<std::string>();
      EXPECT_TRUE(fs::exists(out / "masks" / (image.stem().string() + ".png"))) << image;
    }
    EXPECT_TRUE(fs::exists(out / "contact_sheet.png"));
  }
  fs::remove_all(out);
  EXPECT_TRUE(mesh.has_value()) << (mesh ? "" : mesh.error().ToString()) << err.str();
  if (!mesh || result.report.is_discarded()) return result;
  result.stats = ComputeStats(*mesh);
  result.volume = Box{Vec3(result.report["volume"]["min"]), Vec3(result.report["volume"]["max"])};

  Expected<CameraFile> cameras = ReadCameraFile(dir / par);
  EXPECT_TRUE(cameras.has_value()) << cameras.error().ToString();
  if (!cameras) return result;
  std::vector<std::string> names;
  for (const nlohmann::json& view : result.report["reprojection"]["per_view"]) {
    names.push_back(view["image"].get<std::string>());
  }
  const cv::Mat first = cv::imread((dir / names.front()).string());
  Expected<std::vector<View>> views = ViewsForImages(*cameras, names, first.cols, first.rows);
  EXPECT_TRUE(views.has_value()) << views.error().ToString();
  if (!views) return result;
  const Eigen::Vector3d centre = Vec3(result.report["volume"]["centre"]);
  const std::vector<std::string> scored = good_views.empty() ? names : ReadLines(dir / good_views);
  double sum = 0.0;
  std::printf("%s: model against the reference silhouettes:", set.c_str());
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (std::find(scored.begin(), scored.end(), names[i]) == scored.end()) continue;
    const fs::path truth_file =
        kReference / reference / (fs::path(names[i]).stem().string() + ".png");
    const cv::Mat truth = cv::imread(truth_file.string(), cv::IMREAD_GRAYSCALE);
    EXPECT_FALSE(truth.empty()) << truth_file;
    if (truth.empty()) continue;
    const double iou =
        MaskIoU(RenderSilhouette(*mesh, NormaliseViewSign((*views)[i], centre)), truth);
    std::printf(" %.3f", iou);
    result.reference_iou.push_back(iou);
    sum += iou;
    result.min_reference_iou = std::min(result.min_reference_iou, iou);
  }
  if (!result.reference_iou.empty()) {
    result.mean_reference_iou = sum / static_cast<double>(result.reference_iou.size());
  }
  std::printf(
      "\n  mean %.4f min %.4f over %zu views (segmentation %s); own masks %.4f; "
      "volume box (%.4f %.4f %.4f)..(%.4f %.4f %.4f) m; %.1f cm3\n",
      result.mean_reference_iou, result.min_reference_iou, result.reference_iou.size(),
      result.report["segmentation"]["method"].get<std::string>().c_str(),
      result.report["reprojection"]["mean_iou"].get<double>(), result.volume.min.x(),
      result.volume.min.y(), result.volume.min.z(), result.volume.max.x(), result.volume.max.y(),
      result.volume.max.z(), result.stats.volume_mm3 * 1e6);
  return result;
}

// The volume found from the silhouettes holds the object's tight box (the set's README, metres)
// within 5 mm, and is at most 1.5 cm larger on a side. (The dino's published box reaches 4.5 mm
// above what its views carve: the volume found from the reference silhouettes themselves ends at
// z = 0.0109, the published box at 0.0155.)
void ExpectHolds(const Box& found, const Box& tight) {
  constexpr double kTolerance = 0.005;  // m
  constexpr double kSlack = 0.015;      // m
  for (int a = 0; a < 3; ++a) {
    EXPECT_LE(found.min[a], tight.min[a] + kTolerance) << "axis " << a;
    EXPECT_GE(found.max[a], tight.max[a] - kTolerance) << "axis " << a;
    EXPECT_GE(found.min[a], tight.min[a] - kSlack) << "axis " << a;
    EXPECT_LE(found.max[a], tight.max[a] + kSlack) << "axis " << a;
  }
}

TEST(Middlebury, DinoSparseRingByDefaultMeetsItsReferenceSilhouettes) {
  if (!fs::exists(kData / "middlebury-dinoSparseRing")) GTEST_SKIP() << "no dinoSparseRing";
  const SetResult result = Reconstruct("middlebury-dinoSparseRing", "dinoSparseRing",
                                       "dinoSR_par.txt", "dinoSR_good_silhouette_images.txt");
  ASSERT_EQ(result.reference_iou.size(), 15u);  // the authors' good views
  EXPECT_GE(result.mean_reference_iou, 0.975);
  EXPECT_GE(result.min_reference_iou, 0.94);
  EXPECT_GE(result.report["reprojection"]["mean_iou"].get<double>(), 0.95);
  EXPECT_TRUE(result.stats.closed);
  // 16 views: the hull is larger than the object (README: a careful carve of 15 views, 112 cm3).
  EXPECT_NEAR(result.stats.volume_mm3 * 1e6, 112.0, 15.0);
  ExpectHolds(result.volume, Box{Eigen::Vector3d(-0.061897, -0.018874, -0.057845),
                                 Eigen::Vector3d(0.010897, 0.068227, 0.015495)});
}

TEST(Middlebury, TempleSparseRingByDefaultMeetsItsReferenceSilhouettes) {
  if (!fs::exists(kData / "middlebury-templeSparseRing")) GTEST_SKIP() << "no templeSparseRing";
  const SetResult result =
      Reconstruct("middlebury-templeSparseRing", "templeSparseRing", "templeSR_par.txt", "");
  ASSERT_EQ(result.reference_iou.size(), 16u);
  EXPECT_GE(result.mean_reference_iou, 0.95);
  EXPECT_GE(result.min_reference_iou, 0.93);
  EXPECT_GE(result.report["reprojection"]["mean_iou"].get<double>(), 0.95);
  EXPECT_TRUE(result.stats.closed);
  EXPECT_NEAR(result.stats.volume_mm3 * 1e6, 325.0, 40.0);  // README: about 325 cm3
  ExpectHolds(result.volume, Box{Eigen::Vector3d(-0.073568, 0.021728, -0.012445),
                                 Eigen::Vector3d(0.028855, 0.181892, 0.062736)});
}

}  // namespace
}  // namespace revolve::reconstruct
