// End to end: the real `revolve` binary scanning the simulated rig.

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <utility>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "reconstruct/io/mesh_io.h"
#include "reconstruct/metrics/metrics.h"
#include "tests/support/test_files.h"

namespace fs = std::filesystem;

namespace {

using revolve::test_support::ReadAll;
using revolve::test_support::RunResult;

class ScanE2eTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = revolve::test_support::FreshTestDir("revolve_e2e"); }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  RunResult Run(const std::string& args) {
    return revolve::test_support::RunShell(std::string(REVOLVE_BIN) + " " + args, dir_);
  }

  fs::path WriteConfig(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p;
  }

  fs::path dir_;
};

// A sphere of radius 40 mm on the simulated rig, fast motion.
constexpr char kSphereConfig[] = R"(
[scan]
stops = 36
step_deg = 10.0
settle_ms = 0

[turntable]
backend = "mock"
[turntable.mock]
time_scale = 0.01

[camera]
backend = "synthetic"
[camera.synthetic]
object = "sphere"
radius_mm = 40.0
target_height_mm = 40.0
distance_mm = 450.0

[reconstruct]
resolution = 160
volume_radius_mm = 55.0
volume_height_mm = 90.0
formats = ["ply", "wrl"]
)";

TEST_F(ScanE2eTest, SphereScanIsAccurateAndWatertight) {
  const fs::path config = WriteConfig("sphere.toml", kSphereConfig);
  const fs::path scan = dir_ / "scan";
  const RunResult r = Run("scan --config " + config.string() + " --out " + scan.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;

  // A progress line per stop and the summary.
  EXPECT_NE(r.out.find("[ 36/36]"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("triangles"), std::string::npos) << r.out;

  // The scan folder.
  for (const char* f : {"scan.toml", "manifest.json", "report.json", "contact_sheet.png",
                        "model/model.ply", "model/model.wrl", "frames/stop_000.png",
                        "frames/stop_035.png", "masks/stop_000.png", "masks/stop_035.png"}) {
    EXPECT_TRUE(fs::exists(scan / f)) << f;
  }
  const auto manifest = nlohmann::json::parse(ReadAll(scan / "manifest.json"));
  EXPECT_EQ(manifest["state"], "complete");
  EXPECT_EQ(manifest["stops"].size(), 36u);
  EXPECT_NEAR(manifest["stops"][35]["readback_deg"].get<double>(), 350.0, 0.05);

  // Accuracy against the true sphere.
  const auto report = nlohmann::json::parse(ReadAll(scan / "report.json"));
  const double radius = report["accuracy"]["sphere_fitted_radius_mm"].get<double>();
  EXPECT_NEAR(radius, 40.0, 0.4) << report.dump(2);

  // The written model: every edge shared by exactly two triangles.
  auto mesh = revolve::reconstruct::ReadPly(scan / "model/model.ply");
  ASSERT_TRUE(mesh.has_value()) << mesh.error().message;
  const auto stats = revolve::reconstruct::ComputeStats(*mesh);
  EXPECT_GT(stats.triangle_count, 1000);
  EXPECT_TRUE(stats.closed);
  EXPECT_TRUE(stats.oriented);
  EXPECT_NEAR(revolve::reconstruct::FitSphere(*mesh).radius_mm, 40.0, 0.4);
  EXPECT_EQ(report["model"]["triangles"].get<std::int64_t>(), stats.triangle_count);

  // The VRML model holds the same mesh.
  auto wrl = revolve::reconstruct::ReadVrml(scan / "model/model.wrl");
  ASSERT_TRUE(wrl.has_value()) << wrl.error().message;
  EXPECT_EQ(wrl->faces.size(), mesh->faces.size());
}

TEST_F(ScanE2eTest, MissingConfigIsNamedAndNothingIsWritten) {
  const fs::path scan = dir_ / "scan";
  const RunResult r =
      Run("scan --config " + (dir_ / "nope.toml").string() + " --out " + scan.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("nope.toml"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(scan));
}

TEST_F(ScanE2eTest, SyntaxErrorNamesFileAndLine) {
  const fs::path config = WriteConfig("broken.toml", "[scan]\nstops = 36\nstep_deg = = 10\n");
  const fs::path scan = dir_ / "scan";
  const RunResult r = Run("scan --config " + config.string() + " --out " + scan.string());
  EXPECT_EQ(r.exit_code, 78);
  EXPECT_NE(r.err.find("broken.toml:3:"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(scan));
}

TEST_F(ScanE2eTest, UnknownKeyAndBadValueAreNamed) {
  const fs::path config = WriteConfig("typo.toml", "[scan]\nstops = 36\nsettle_msec = 5\n");
  const fs::path scan = dir_ / "scan";
  RunResult r = Run("scan --config " + config.string() + " --out " + scan.string());
  EXPECT_EQ(r.exit_code, 78);
  EXPECT_NE(r.err.find("typo.toml:3:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("scan.settle_msec"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(scan));

  const fs::path config2 = WriteConfig("range.toml", "[reconstruct]\nresolution = 3\n");
  r = Run("scan --config " + config2.string() + " --out " + scan.string());
  EXPECT_EQ(r.exit_code, 78);
  EXPECT_NE(r.err.find("range.toml:2:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("reconstruct.resolution"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(scan));
}

TEST_F(ScanE2eTest, ExistingScanIsNeverOverwritten) {
  const fs::path scan = dir_ / "scan";
  fs::create_directories(scan);
  std::ofstream(scan / "manifest.json") << "{\"earlier\": true}\n";
  const RunResult r = Run("scan --out " + scan.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("already exists"), std::string::npos) << r.err;
  EXPECT_EQ(ReadAll(scan / "manifest.json"), "{\"earlier\": true}\n");
}

// `revolve reconstruct --images`: the thesis's input (binary silhouettes named by angle) through
// the real command line, both methods, and the option mistakes a user makes.
class ReconstructImagesE2eTest : public ScanE2eTest {
 protected:
  // 36 silhouettes of an upright cylinder (radius 60 px, 200 px tall) on the middle column,
  // object white on black, as 8-bit TIFF named bw_can0.tif ... bw_can350.tif.
  fs::path WriteCylinderSilhouettes() {
    const fs::path images = dir_ / "images";
    fs::create_directories(images);
    for (int angle = 0; angle < 360; angle += 10) {
      cv::Mat mask(300, 320, CV_8UC1, cv::Scalar(0));
      cv::rectangle(mask, cv::Point(160 - 60, 50), cv::Point(160 + 59, 249), cv::Scalar(255),
                    cv::FILLED);
      cv::imwrite((images / ("bw_can" + std::to_string(angle) + ".tif")).string(), mask);
    }
    return images;
  }
};

TEST_F(ReconstructImagesE2eTest, BothMethodsWriteTheirModels) {
  const fs::path images = WriteCylinderSilhouettes();
  const fs::path meridian = dir_ / "meridian";
  RunResult r = Run("reconstruct --images " + images.string() +
                    " --pattern 'bw_can{angle}.tif' --step-deg 10 --method meridian --row-step 9"
                    " --formats wrl,ply --out " +
                    meridian.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(meridian / "model" / "model.wrl"));
  EXPECT_TRUE(fs::exists(meridian / "model" / "model.ply"));
  const nlohmann::json report = nlohmann::json::parse(ReadAll(meridian / "report.json"));
  EXPECT_EQ(report.dump().find("\"mm\""), std::string::npos) << "thesis mode has no scale";

  const fs::path hull = dir_ / "hull";
  r = Run("reconstruct --images " + images.string() +
          " --pattern 'bw_can{angle}.tif' --method hull --resolution 64 --formats ply --out " +
          hull.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto mesh = revolve::reconstruct::ReadPly(hull / "model" / "model.ply");
  ASSERT_TRUE(mesh.has_value()) << mesh.error().message;
  // A cylinder of radius 60 px and height 200 px (thesis units: pixels): the hull of 36 views
  // is within a few percent of it, and closed.
  const auto stats = revolve::reconstruct::ComputeStats(*mesh);
  EXPECT_TRUE(stats.closed);
  EXPECT_NEAR(stats.volume_mm3 / (M_PI * 60.0 * 60.0 * 200.0), 1.0, 0.05);
}

TEST_F(ReconstructImagesE2eTest, OptionMistakesAreNamed) {
  const fs::path images = WriteCylinderSilhouettes();
  RunResult r = Run("reconstruct " + dir_.string() + " --images " + images.string() + " --out " +
                    (dir_ / "x").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("not both"), std::string::npos) << r.err;

  r = Run("reconstruct " + dir_.string() + " --pattern 'a{angle}.png'");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--pattern applies to --images only"), std::string::npos) << r.err;

  r = Run("reconstruct --images " + images.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--out"), std::string::npos) << r.err;

  r = Run("reconstruct --images " + (dir_ / "missing").string() + " --out " +
          (dir_ / "y").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find((dir_ / "missing").string()), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "y" / "model"));
}

}  // namespace
