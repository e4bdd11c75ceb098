// `revolve reconstruct --images DIR` end to end (station/reconstruct_images_command.h): the
// thesis's input (binary TIFF silhouettes named by angle), photos for texture, imported cameras,
// and the errors that must name the file at fault.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <unistd.h>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "reconstruct/image_set.h"
#include "station/commands/reconstruct_images_command.h"
#include "station/commands/scan_command.h"

namespace revolve::station {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 384;
constexpr int kHeight = 288;

// A bottle: radius (px) by height above the bottom row.
double BottleRadius(double z) { return z < 150.0 ? 60.0 : 60.0 - 0.4 * (z - 150.0); }

cv::Mat BottleMask() {
  cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
  const double u0 = 0.5 * (kWidth - 1);
  for (int v = 0; v < kHeight; ++v) {
    const double z = (kHeight - 1) - v;
    if (z < 20.0 || z > 260.0) continue;
    for (int u = 0; u < kWidth; ++u) {
      if (std::abs(u - u0) < BottleRadius(z)) mask.at<std::uint8_t>(v, u) = 255;
    }
  }
  return mask;
}

class ReconstructImages : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("revolve_reconstruct_images_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "images");
  }
  void TearDown() override { fs::remove_all(dir_); }

  // The thesis's input: 8-bit binary TIFFs, object white on black, bw_bottle0.tif ... 350.
  void WriteSilhouettes(int views, double step_deg) {
    const cv::Mat mask = BottleMask();
    for (int k = 0; k < views; ++k) {
      const std::string name = "bw_bottle" + std::to_string(std::lround(k * step_deg)) + ".tif";
      ASSERT_TRUE(cv::imwrite((dir_ / "images" / name).string(), mask));
    }
  }

  ReconstructImagesOptions Options() const {
    ReconstructImagesOptions options;
    options.images = dir_ / "images";
    options.pattern = "bw_bottle{angle}.tif";
    options.out = dir_ / "out";
    options.resolution = 64;
    return options;
  }

  int Run(const ReconstructImagesOptions& options) {
    out_.str("");
    err_.str("");
    return RunReconstructImages(options, out_, err_);
  }

  nlohmann::json Report() const {
    std::ifstream in(dir_ / "out" / "report.json");
    return nlohmann::json::parse(in);
  }

  fs::path dir_;
  std::ostringstream out_;
  std::ostringstream err_;
};

TEST_F(ReconstructImages, ThesisSilhouettesWithTheMeridianMethod) {
  WriteSilhouettes(36, 10.0);
  ReconstructImagesOptions options = Options();
  options.method = "meridian";
  options.formats = {"ply", "wrl", "stl"};
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  EXPECT_TRUE(fs::exists(dir_ / "out" / "model" / "model.ply"));
  EXPECT_TRUE(fs::exists(dir_ / "out" / "model" / "model.wrl"));
  EXPECT_TRUE(fs::exists(dir_ / "out" / "model" / "model.stl"));
  const nlohmann::json report = Report();
  EXPECT_EQ(report["units"], "px");
  EXPECT_NE(report["scale"].get<std::string>().find("unscaled"), std::string::npos);
  EXPECT_EQ(report["model"]["meridians"], 36);
  EXPECT_TRUE(report["model"]["watertight"].get<bool>());
  EXPECT_EQ(report["reprojection"]["per_view"].size(), 36u);
  EXPECT_GT(report["reprojection"]["mean_iou"].get<double>(), 0.97);
  // Dimensions: 120 px wide (2 x 60), 240 px tall (row centres of z = 20 .. 260).
  EXPECT_NEAR(report["model"]["dimensions"][0].get<double>(), 120.0, 2.0);
  EXPECT_NEAR(report["model"]["dimensions"][2].get<double>(), 240.0, 1.0);
  EXPECT_NE(out_.str().find("unscaled"), std::string::npos) << out_.str();
}

TEST_F(ReconstructImages, ThesisSilhouettesWithTheHull) {
  WriteSilhouettes(18, 20.0);
  ReconstructImagesOptions options = Options();
  options.step_deg = 20.0;
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  const nlohmann::json report = Report();
  EXPECT_EQ(report["volume"]["source"], "silhouettes");
  EXPECT_GT(report["reprojection"]["min_iou"].get<double>(), 0.95);
  // The hull of a surface of revolution from 18 views: close to pi r^2 h of the bottle.
  const double truth =
      M_PI * 60.0 * 60.0 * 130.0 + M_PI / 3.0 * (60.0 * 60.0 + 60.0 * 16.0 + 16.0 * 16.0) * 110.0;
  EXPECT_NEAR(report["model"]["volume"].get<double>(), truth, 0.05 * truth);
}

// Eighteen images of a whole turn taken without --step-deg: the default 10 degrees would lay them
// over half a turn. The run says so and says what to pass; at the right step it says nothing.
TEST_F(ReconstructImages, ImagesThatDoNotMakeOneTurnAtTheStepAreNoted) {
  WriteSilhouettes(18, 20.0);
  ReconstructImagesOptions options = Options();
  options.pattern.clear();  // in name order: the angles are the step's
  options.resolution = 32;
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  EXPECT_NE(out_.str().find("18 images 10 deg apart (--step-deg) cover 180 deg; if they make one "
                            "turn they are 20 deg apart: pass --step-deg 20"),
            std::string::npos)
      << out_.str();
  options.step_deg = 20.0;
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  EXPECT_EQ(out_.str().find("note:"), std::string::npos) << out_.str();
  options.step_deg = 40.0;
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  EXPECT_NE(out_.str().find("would turn 720 deg"), std::string::npos) << out_.str();
}

TEST_F(ReconstructImages, PhotosGiveATexturedVrml) {
  const cv::Mat mask = BottleMask();
  for (int k = 0; k < 36; ++k) {
    cv::Mat photo(mask.size(), CV_8UC3, cv::Scalar(0, 0, 0));
    photo.setTo(cv::Scalar(30 + 6 * k, 200, 90), mask);
    ASSERT_TRUE(
        cv::imwrite((dir_ / "images" / ("shot_" + std::to_string(k) + ".png")).string(), photo));
  }
  ReconstructImagesOptions options = Options();
  options.pattern = "shot_{index}.png";
  options.method = "meridian";
  options.formats = {"wrl"};
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  const nlohmann::json report = Report();
  EXPECT_EQ(report["input"]["kind"], "photos");
  EXPECT_GT(report["model"]["texture_images"].get<int>(), 0);
  std::ifstream in(dir_ / "out" / "model" / "model.wrl");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("ImageTexture"), std::string::npos);
  EXPECT_NE(text.find("texCoordIndex"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir_ / "out" / "model" / "model_tex00.jpg"));
}

// The hull's texture atlas is made when a format carries it (OBJ here: the photos' colour in the
// PNG it names), and not for the PLY alone, which carries the vertices' colours.
TEST_F(ReconstructImages, PhotosTextureTheObjAndColourThePly) {
  const cv::Mat mask = BottleMask();
  for (int k = 0; k < 18; ++k) {
    cv::Mat photo(mask.size(), CV_8UC3, cv::Scalar(0, 0, 0));
    photo.setTo(cv::Scalar(40, 200, 90), mask);
    ASSERT_TRUE(cv::imwrite((dir_ / "images" / fmt::format("shot_{:02}.png", k)).string(), photo));
  }
  ReconstructImagesOptions options = Options();
  options.pattern.clear();
  options.step_deg = 20.0;
  options.formats = {"obj", "ply"};
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  const fs::path model = dir_ / "out" / "model";
  const cv::Mat atlas = cv::imread((model / "model.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(atlas.empty());
  cv::Mat lit;
  cv::inRange(atlas, cv::Scalar(30, 180, 70), cv::Scalar(50, 220, 110), lit);
  EXPECT_GT(cv::countNonZero(lit), atlas.total() / 10);  // the photos' green, not grey
  std::ifstream mtl(model / "model.mtl");
  const std::string material((std::istreambuf_iterator<char>(mtl)),
                             std::istreambuf_iterator<char>());
  EXPECT_NE(material.find("map_Kd model.png"), std::string::npos) << material;
  fs::remove_all(dir_ / "out");
  options.formats = {"ply"};
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  EXPECT_TRUE(fs::exists(model / "model.ply"));
  EXPECT_FALSE(fs::exists(model / "model.png"));
}

TEST_F(ReconstructImages, PhotosAreSegmentedAndTheMasksKeptForAPersonToCheck) {
  // A bottle on an uneven dark cloth; one frame shows only the cloth (a failed shot).
  const cv::Mat mask = BottleMask();
  cv::Mat cloth(mask.size(), CV_8UC3);
  for (int v = 0; v < cloth.rows; ++v) {
    for (int u = 0; u < cloth.cols; ++u) {
      const int level =
          15 + static_cast<int>(25.0 * (1.0 + std::sin(u * 0.05) * std::cos(v * 0.04)));
      cloth.at<cv::Vec3b>(v, u) = cv::Vec3b(level, level, level + 4);
    }
  }
  for (int k = 0; k < 12; ++k) {
    cv::Mat photo = cloth.clone();
    if (k != 5) photo.setTo(cv::Scalar(90, 180, 210), mask);
    ASSERT_TRUE(
        cv::imwrite((dir_ / "images" / ("shot_" + std::to_string(k) + ".png")).string(), photo));
  }
  ReconstructImagesOptions options = Options();
  options.pattern = "shot_{index}.png";
  options.step_deg = 30.0;
  options.formats = {"ply"};
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  const nlohmann::json report = Report();
  EXPECT_NE(report["segmentation"]["method"], "auto");
  EXPECT_EQ(report["segmentation"]["requested"], "auto");
  EXPECT_FALSE(report["segmentation"]["reason"].get<std::string>().empty());
  const nlohmann::json& views = report["reprojection"]["per_view"];
  ASSERT_EQ(views.size(), 12u);
  for (int k = 0; k < 12; ++k) {
    const fs::path written = dir_ / "out" / "masks" / ("shot_" + std::to_string(k) + ".png");
    ASSERT_TRUE(fs::exists(written)) << written;
    const cv::Mat saved = cv::imread(written.string(), cv::IMREAD_GRAYSCALE);
    EXPECT_EQ(views[k]["mask_area_px"].get<int>(), cv::countNonZero(saved));
    if (k == 5) {
      EXPECT_TRUE(views[k]["disagrees"].get<bool>());
      EXPECT_FALSE(views[k].value("left_out", "").empty()) << views[k].dump();
      continue;
    }
    EXPECT_FALSE(views[k]["disagrees"].get<bool>()) << views[k].dump();
    EXPECT_GE(views[k]["hull_iou"].get<double>(), 0.95) << views[k].dump();
  }
  EXPECT_TRUE(fs::exists(dir_ / "out" / "contact_sheet.png"));
  EXPECT_NE(out_.str().find("shot_5.png: left out"), std::string::npos) << out_.str();

  // --segment names an unknown method; --config's [segment] is checked like a scan's.
  options.segment = "magic";
  EXPECT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("magic"), std::string::npos) << err_.str();
  options.segment.clear();
  std::ofstream(dir_ / "seg.toml") << "[segment]\nmethod = \"graphcut\"\nopen_px = 99\n";
  options.config = dir_ / "seg.toml";
  EXPECT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("open_px"), std::string::npos) << err_.str();
  std::ofstream(dir_ / "seg.toml") << "[segment]\nmethod = \"graphcut\"\n";
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  EXPECT_EQ(Report()["segmentation"]["method"], "graphcut");
}

// The masks are written once, after the consensus; a run that stops before it (here: a
// cameras file that is not there) still leaves the segmentation's masks and contact sheet for
// a person to check, and says why it stopped.
TEST_F(ReconstructImages, ARunStoppedBeforeTheConsensusStillWritesTheMasks) {
  const cv::Mat mask = BottleMask();
  for (int k = 0; k < 6; ++k) {
    cv::Mat photo(mask.size(), CV_8UC3, cv::Scalar(0, 0, 0));
    photo.setTo(cv::Scalar(40, 190, 120), mask);
    ASSERT_TRUE(
        cv::imwrite((dir_ / "images" / ("shot_" + std::to_string(k) + ".png")).string(), photo));
  }
  ReconstructImagesOptions options = Options();
  options.pattern = "shot_{index}.png";
  options.segment = "threshold";
  options.cameras = dir_ / "no_such_cameras.txt";
  ASSERT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("no_such_cameras.txt"), std::string::npos) << err_.str();
  for (int k = 0; k < 6; ++k) {
    const fs::path written = dir_ / "out" / "masks" / ("shot_" + std::to_string(k) + ".png");
    ASSERT_TRUE(fs::exists(written)) << written;
    // The threshold's mask (reconstruct/image_set.h), as segmented: no consensus cut it.
    cv::Mat photo(mask.size(), CV_8UC3, cv::Scalar(0, 0, 0));
    photo.setTo(cv::Scalar(40, 190, 120), mask);
    reconstruct::PhotoSegmentation segmentation;
    segmentation.threshold = options.threshold;
    EXPECT_EQ(cv::countNonZero(cv::imread(written.string(), cv::IMREAD_GRAYSCALE) !=
                               reconstruct::SegmentPhoto(photo, segmentation)),
              0);
  }
  EXPECT_TRUE(fs::exists(dir_ / "out" / "contact_sheet.png"));
  EXPECT_FALSE(fs::exists(dir_ / "out" / "report.json"));
}

TEST_F(ReconstructImages, ImportedProjectionMatricesOfAnySign) {
  // The thesis views written as 3x4 matrices, every other one negated: the sign is fixed from
  // the silhouettes' centre, and the hull comes out as with thesis mode.
  WriteSilhouettes(12, 30.0);
  std::ofstream cameras(dir_ / "cameras.txt");
  cameras << "# name p11 .. p34\n12\n";
  for (int k = 0; k < 12; ++k) {
    const double a = k * 30.0 * M_PI / 180.0;
    const double s = k % 2 == 0 ? 1.0 : -1.0;
    cameras << "bw_bottle" << k * 30 << ".tif " << s * std::cos(a) << " " << -s * std::sin(a)
            << " 0 " << s * 0.5 * (kWidth - 1) << " 0 0 " << -s << " " << s * (kHeight - 1)
            << " 0 0 0 " << s << "\n";
  }
  cameras.close();
  ReconstructImagesOptions options = Options();
  options.step_deg = 30.0;
  options.cameras = dir_ / "cameras.txt";
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  const nlohmann::json report = Report();
  EXPECT_GT(report["reprojection"]["min_iou"].get<double>(), 0.95);
  EXPECT_EQ(report["units"], "as in the cameras file");
}

TEST_F(ReconstructImages, ErrorsNameTheFile) {
  WriteSilhouettes(36, 10.0);
  ReconstructImagesOptions options = Options();

  // A stop missing in the sequence.
  fs::rename(dir_ / "images" / "bw_bottle40.tif", dir_ / "bw_bottle40.tif");
  EXPECT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("bw_bottle40.tif"), std::string::npos) << err_.str();
  fs::rename(dir_ / "bw_bottle40.tif", dir_ / "images" / "bw_bottle40.tif");

  // An image of another size.
  ASSERT_TRUE(cv::imwrite((dir_ / "images" / "bw_bottle70.tif").string(),
                          cv::Mat(100, 100, CV_8UC1, cv::Scalar(0))));
  EXPECT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("bw_bottle70.tif"), std::string::npos) << err_.str();

  // An empty silhouette.
  ASSERT_TRUE(cv::imwrite((dir_ / "images" / "bw_bottle70.tif").string(),
                          cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(0))));
  EXPECT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("bw_bottle70.tif"), std::string::npos) << err_.str();
  EXPECT_NE(err_.str().find("empty"), std::string::npos) << err_.str();
  ASSERT_TRUE(cv::imwrite((dir_ / "images" / "bw_bottle70.tif").string(), BottleMask()));

  // An unreadable image.
  std::ofstream(dir_ / "images" / "bw_bottle80.tif") << "not a tiff";
  EXPECT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("bw_bottle80.tif"), std::string::npos) << err_.str();
  ASSERT_TRUE(cv::imwrite((dir_ / "images" / "bw_bottle80.tif").string(), BottleMask()));

  // Fewer cameras than images.
  std::ofstream(dir_ / "cameras.txt") << "bw_bottle0.tif 1 0 0 0 0 0 -1 287 0 0 0 1\n"
                                      << "bw_bottle10.tif 1 0 0 0 0 0 -1 287 0 0 0 1\n";
  options.cameras = dir_ / "cameras.txt";
  EXPECT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("bw_bottle20.tif"), std::string::npos) << err_.str();
  EXPECT_NE(err_.str().find("cameras.txt"), std::string::npos) << err_.str();

  // A camera file that does not parse.
  std::ofstream(dir_ / "cameras.txt") << "bw_bottle0.tif 1 0 0\n";
  EXPECT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("cameras.txt:1"), std::string::npos) << err_.str();

  // Options out of range are usage errors.
  options = Options();
  options.method = "voxels";
  EXPECT_EQ(Run(options), kExitUsage);
  options = Options();
  options.formats = {"dxf"};
  EXPECT_EQ(Run(options), kExitUsage);
  options = Options();
  options.images = dir_ / "nowhere";
  EXPECT_EQ(Run(options), kExitFailed);
  EXPECT_NE(err_.str().find("nowhere"), std::string::npos) << err_.str();
}

TEST_F(ReconstructImages, MiddleburyDinoWithItsCameras) {
  const fs::path set = fs::path(REVOLVE_SHARED_DIR) / "data" / "middlebury-dinoSparseRing";
  if (!fs::exists(set)) GTEST_SKIP() << set << " is missing";
  ReconstructImagesOptions options;
  options.images = set;
  options.cameras = set / "dinoSR_par.txt";
  options.threshold = 40;
  options.resolution = 128;
  options.formats = {"ply"};
  options.out = dir_ / "out";
  ASSERT_EQ(Run(options), kExitOk) << err_.str();
  const nlohmann::json report = Report();
  EXPECT_EQ(report["reprojection"]["per_view"].size(), 16u);
  EXPECT_GE(report["reprojection"]["mean_iou"].get<double>(), 0.95);
}

}  // namespace
}  // namespace revolve::station
