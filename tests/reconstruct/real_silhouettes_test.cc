// Accuracy on real photographs: `revolve reconstruct --images` with default options and no box
// on the Middlebury sparse rings (shared/data), its model reprojected into every view and
// compared with reference silhouettes made by another method (grabCut seeded and checked by hand,
// tests/data/reference_silhouettes/README.md).
//
// Bars (issue 17): dinoSparseRing, over the authors' good views, mean IoU >= 0.975;
// templeSparseRing >= 0.95; and revolve's own masks agree with its model at >= 0.95.
#include <gtest/gtest.h>

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
#include "reconstruct/metrics/reprojection.h"
#include "station/commands/reconstruct_images_command.h"
#include "station/commands/scan_command.h"

namespace revolve::station {
namespace {

namespace fs = std::filesystem;
namespace rc = revolve::reconstruct;

const fs::path kData = fs::path(REVOLVE_SHARED_DIR) / "data";
const fs::path kReference = fs::path(REVOLVE_SOURCE_DIR) / "tests/data/reference_silhouettes";

struct RealSet {
  std::string folder;     // under shared/data
  std::string reference;  // under tests/data/reference_silhouettes
  std::string cameras;
  std::string good_views;  // file listing the views to score; empty: all
  double min_mean_iou = 0.0;
};

std::vector<std::string> ReadLines(const fs::path& path) {
  std::vector<std::string> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (!line.empty()) lines.push_back(line);
  }
  return lines;
}

class RealSilhouettes : public ::testing::TestWithParam<RealSet> {
 protected:
  void SetUp() override {
    out_ = fs::temp_directory_path() /
           fmt::format("revolve_real_silhouettes_{}_{}", getpid(), GetParam().reference);
    fs::remove_all(out_);
  }
  void TearDown() override { fs::remove_all(out_); }
  fs::path out_;
};

TEST_P(RealSilhouettes, DefaultOptionsMeetTheReferenceSilhouettes) {
  const RealSet& set = GetParam();
  const fs::path dir = kData / set.folder;
  if (!fs::exists(dir)) GTEST_SKIP() << dir << " is missing";
  ReconstructImagesOptions options;
  options.images = dir;
  options.cameras = dir / set.cameras;
  options.formats = {"ply"};
  options.out = out_;
  std::ostringstream out, err;
  ASSERT_EQ(RunReconstructImages(options, out, err), kExitOk) << err.str();
  std::cout << out.str();

  std::ifstream report_in(out_ / "report.json");
  const nlohmann::json report = nlohmann::json::parse(report_in);
  EXPECT_NE(report["segmentation"]["method"], "auto");
  EXPECT_FALSE(report["segmentation"]["reason"].get<std::string>().empty());
  const double own = report["reprojection"]["mean_iou"].get<double>();

  Expected<rc::Mesh> mesh = rc::ReadPly(out_ / "model" / "model.ply");
  ASSERT_TRUE(mesh.has_value()) << mesh.error().ToString();
  Expected<rc::CameraFile> cameras = rc::ReadCameraFile(dir / set.cameras);
  ASSERT_TRUE(cameras.has_value()) << cameras.error().ToString();
  std::vector<std::string> names;
  for (const nlohmann::json& view : report["reprojection"]["per_view"]) {
    names.push_back(view["image"].get<std::string>());
    // The masks a person checks are written, one per image.
    EXPECT_TRUE(fs::exists(out_ / "masks" / (fs::path(names.back()).stem().string() + ".png")));
  }
  EXPECT_TRUE(fs::exists(out_ / "contact_sheet.png"));
  const cv::Mat first = cv::imread((dir / names.front()).string());
  Expected<std::vector<View>> views = rc::ViewsForImages(*cameras, names, first.cols, first.rows);
  ASSERT_TRUE(views.has_value()) << views.error().ToString();
  const auto& c = report["volume"]["centre"];
  const Eigen::Vector3d centre(c[0].get<double>(), c[1].get<double>(), c[2].get<double>());
  std::vector<std::string> scored =
      set.good_views.empty() ? names : ReadLines(dir / set.good_views);
  double sum = 0.0;
  int count = 0;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (std::find(scored.begin(), scored.end(), names[i]) == scored.end()) continue;
    const fs::path reference =
        kReference / set.reference / (fs::path(names[i]).stem().string() + ".png");
    const cv::Mat truth = cv::imread(reference.string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(truth.empty()) << reference;
    const View view = rc::NormaliseViewSign((*views)[i], centre);
    const double iou = rc::MaskIoU(rc::RenderSilhouette(*mesh, view), truth);
    std::cout << fmt::format("{} IoU against the reference {:.4f}\n", names[i], iou);
    sum += iou;
    ++count;
  }
  ASSERT_GT(count, 0);
  const double mean = sum / count;
  std::cout << fmt::format(
      "{}: mean IoU against the reference silhouettes {:.4f} ({} views); "
      "own masks against the model {:.4f}\n",
      set.folder, mean, count, own);
  EXPECT_GE(mean, set.min_mean_iou);
  EXPECT_GE(own, 0.95);
}

INSTANTIATE_TEST_SUITE_P(
    Middlebury, RealSilhouettes,
    ::testing::Values(RealSet{"middlebury-dinoSparseRing", "dinoSparseRing", "dinoSR_par.txt",
                              "dinoSR_good_silhouette_images.txt", 0.975},
                      RealSet{"middlebury-templeSparseRing", "templeSparseRing", "templeSR_par.txt",
                              "", 0.95}),
    [](const ::testing::TestParamInfo<RealSet>& p) { return p.param.reference; });

}  // namespace
}  // namespace revolve::station
