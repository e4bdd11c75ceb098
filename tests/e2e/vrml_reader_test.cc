// Every VRML file revolve writes, read by a parser no one here wrote: Debian view3dscene's
// `tovrmlx3d` (Castle Game Engine's VRML 2.0 / X3D reader) converts it to X3D XML and names any
// parse error. Both methods, every path: `revolve scan`, `revolve reconstruct SCAN_DIR` and
// `revolve reconstruct --images`; each texture the file references exists beside it. The meridian
// method's texture (thesis 4.3.4: view-dependent, one image per strip's view) is in every path,
// and in its OBJ/MTL and glTF too.
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "reconstruct/meridian/meridian_vrml.h"
#include "tests/support/test_files.h"

namespace fs = std::filesystem;

namespace {

using revolve::test_support::ReadAll;
using revolve::test_support::RunResult;

// A textured vase on the simulated rig; few stops and a coarse hull keep the test quick.
constexpr char kConfig[] = R"(
[scan]
stops = 12
step_deg = 30.0
settle_ms = 0

[turntable]
backend = "mock"
[turntable.mock]
time_scale = 0.01

[camera]
backend = "synthetic"
[camera.synthetic]
object = "vase"
radius_mm = 35.0
height_mm = 90.0
target_height_mm = 45.0
width_px = 384
height_px = 288
backdrop_grey = 0
noise_sigma = 0.0

[reconstruct]
method = "meridian"
resolution = 64
volume_radius_mm = 55.0
volume_height_mm = 100.0
formats = ["wrl", "obj", "glb"]
texture_size_px = 1024
)";

class VrmlReaderTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = revolve::test_support::FreshTestDir("revolve_vrml"); }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  RunResult Run(const std::string& command) {
    return revolve::test_support::RunShell(command, dir_);
  }

  // Parses `wrl` with tovrmlx3d; checks that each ImageTexture url names a file beside it and
  // that a textured file holds texture coordinates. Returns the number of ImageTexture nodes.
  int CheckVrml(const fs::path& wrl) {
    SCOPED_TRACE(wrl.string());
    const RunResult r = Run("tovrmlx3d --encoding xml '" + wrl.string() + "'");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    // tovrmlx3d reports a parse error as a warning on stderr and stops reading there.
    EXPECT_EQ(r.err.find("Error"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("Warning"), std::string::npos) << r.err;
    EXPECT_NE(r.out.find("<IndexedFaceSet"), std::string::npos) << r.out.substr(0, 2000);
    const std::regex url_re("<ImageTexture[^>]*url='\"([^\"]+)\"'");
    int textures = 0;
    for (auto it = std::sregex_iterator(r.out.begin(), r.out.end(), url_re);
         it != std::sregex_iterator(); ++it) {
      ++textures;
      const fs::path image = wrl.parent_path() / (*it)[1].str();
      EXPECT_TRUE(fs::exists(image)) << image;
      EXPECT_FALSE(cv::imread(image.string()).empty()) << image;
    }
    // Our own reader agrees on the urls.
    const auto urls = revolve::reconstruct::ReadVrmlTextureUrls(wrl);
    EXPECT_TRUE(urls.has_value());
    if (urls) {
      EXPECT_EQ(static_cast<int>(urls->size()), textures);
    }
    if (textures > 0) {
      EXPECT_NE(r.out.find("<TextureCoordinate"), std::string::npos);
      EXPECT_NE(r.out.find("texCoordIndex="), std::string::npos);
    }
    return textures;
  }

  // Every .wrl under `dir`, sorted.
  static std::vector<fs::path> Wrls(const fs::path& dir) {
    std::vector<fs::path> files;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
      if (e.path().extension() == ".wrl") files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
    return files;
  }

  fs::path dir_;
};

TEST_F(VrmlReaderTest, EveryPathWritesVrmlAnIndependentReaderParses) {
  if (Run("command -v tovrmlx3d").exit_code != 0) {
    GTEST_SKIP() << "tovrmlx3d (Debian view3dscene) is not installed; ./run installs it";
  }
  const std::string revolve = REVOLVE_BIN;
  const fs::path config = dir_ / "meridian.toml";
  std::ofstream(config) << kConfig;

  // revolve scan, meridian: the textured VRML, and the texture in OBJ/MTL and glTF.
  const fs::path scan = dir_ / "scan";
  RunResult r = Run(revolve + " scan --config " + config.string() + " --out " + scan.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_GT(CheckVrml(scan / "model" / "model.wrl"), 1) << "one texture per strip's view";
  const std::string mtl = ReadAll(scan / "model" / "model.mtl");
  EXPECT_NE(mtl.find("map_Kd model.png"), std::string::npos) << mtl;
  EXPECT_FALSE(cv::imread((scan / "model" / "model.png").string()).empty());
  EXPECT_NE(ReadAll(scan / "model" / "model.obj").find("\nvt "), std::string::npos);
  const std::string glb = ReadAll(scan / "model" / "model.glb");
  EXPECT_NE(glb.find("\"TEXCOORD_0\""), std::string::npos);
  EXPECT_NE(glb.find("\"image/png\""), std::string::npos);
  const nlohmann::json report = nlohmann::json::parse(ReadAll(scan / "report.json"));
  for (const auto& file : report["model"]["files"]) {
    EXPECT_TRUE(fs::exists(scan / file.get<std::string>())) << file;
  }

  // revolve reconstruct SCAN_DIR, both methods.
  for (const std::string method : {"meridian", "hull"}) {
    const fs::path out = dir_ / ("again_" + method);
    r = Run(revolve + " reconstruct " + scan.string() + " --method " + method +
            " --resolution 64 --formats wrl --out " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    const int textures = CheckVrml(out / "model.wrl");
    if (method == "meridian") {
      EXPECT_GT(textures, 1);
    }
  }

  // revolve reconstruct --images, both methods, with photos (the scan's frames, on black).
  for (const std::string method : {"meridian", "hull"}) {
    const fs::path out = dir_ / ("images_" + method);
    r = Run(revolve + " reconstruct --images " + (scan / "frames").string() +
            " --pattern 'stop_{index}.png' --step-deg 30 --method " + method +
            " --resolution 64 --formats wrl --out " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    const int textures = CheckVrml(out / "model" / "model.wrl");
    if (method == "meridian") {
      EXPECT_GT(textures, 1);
    }
  }

  // Every VRML file written above was checked.
  EXPECT_EQ(Wrls(dir_).size(), 5u);
}

}  // namespace
