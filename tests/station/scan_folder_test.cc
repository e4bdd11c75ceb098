#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "station/contact_sheet.h"
#include "station/scan_folder.h"

namespace revolve::station {
namespace {

namespace fs = std::filesystem;

fs::path FreshDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("revolve_station_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(dir);
  return dir;
}

TEST(ScanFolderTest, CreatesLayoutAndWritesFilesWithoutTemporaries) {
  const fs::path dir = FreshDir("layout");
  auto folder = ScanFolder::Create(dir);
  ASSERT_TRUE(folder.has_value()) << folder.error().message;
  EXPECT_TRUE(fs::is_directory(dir / "frames"));
  EXPECT_TRUE(fs::is_directory(dir / "masks"));
  EXPECT_TRUE(fs::is_directory(dir / "model"));

  cv::Mat image(8, 12, CV_8UC3, cv::Scalar(1, 2, 3));
  ASSERT_TRUE(folder->WriteImage("frames/" + StopFileName(7), image).has_value());
  ASSERT_TRUE(folder->WriteJson("manifest.json", {{"state", "running"}}).has_value());
  ASSERT_TRUE(folder->WriteJson("manifest.json", {{"state", "complete"}}).has_value());

  const cv::Mat back = cv::imread((dir / "frames/stop_007.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(back.empty());
  EXPECT_EQ(cv::norm(back, image, cv::NORM_INF), 0.0);
  std::ifstream in(dir / "manifest.json");
  std::stringstream s;
  s << in.rdbuf();
  EXPECT_NE(s.str().find("complete"), std::string::npos);
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();
  }
  fs::remove_all(dir);
}

TEST(ScanFolderTest, RefusesANonEmptyFolder) {
  const fs::path dir = FreshDir("nonempty");
  fs::create_directories(dir);
  std::ofstream(dir / "keep.txt") << "earlier scan";
  auto folder = ScanFolder::Create(dir);
  ASSERT_FALSE(folder.has_value());
  EXPECT_EQ(folder.error().code, ErrorCode::kBadInput);
  EXPECT_NE(folder.error().message.find(dir.string()), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "keep.txt"));
  fs::remove_all(dir);
}

TEST(ScanFolderTest, AcceptsAnEmptyExistingFolder) {
  const fs::path dir = FreshDir("empty");
  fs::create_directories(dir);
  EXPECT_TRUE(ScanFolder::Create(dir).has_value());
  fs::remove_all(dir);
}

TEST(ScanFolderTest, WriteIntoAMissingDirectoryNamesThePath) {
  const fs::path dir = FreshDir("gone");
  auto folder = ScanFolder::Create(dir);
  ASSERT_TRUE(folder.has_value());
  fs::remove_all(dir);
  auto written = folder->WriteText("manifest.json", "{}");
  ASSERT_FALSE(written.has_value());
  EXPECT_NE(written.error().message.find("manifest.json"), std::string::npos);
}

TEST(ContactSheetTest, OutlinesTheSilhouetteAndTilesEveryStop) {
  cv::Mat frame(120, 160, CV_8UC3, cv::Scalar::all(20));
  cv::Mat mask(120, 160, CV_8UC1, cv::Scalar(0));
  cv::circle(mask, {80, 60}, 30, cv::Scalar(255), cv::FILLED);
  const cv::Mat tile = ContactSheetTile(frame, mask);
  // The outline is green somewhere on the circle's rim.
  cv::Mat green;
  cv::inRange(tile, cv::Scalar(0, 200, 0), cv::Scalar(80, 255, 80), green);
  EXPECT_GT(cv::countNonZero(green), 50);

  std::vector<cv::Mat> tiles(8, tile);
  const cv::Mat sheet = AssembleContactSheet(tiles);
  EXPECT_EQ(sheet.cols, 6 * tile.cols);
  EXPECT_EQ(sheet.rows, 2 * tile.rows);
}

// A silhouette set's tiles are shrunk in grey and coloured after (set_masks.cc): the same pixels
// as shrinking the colour copy, for masks of camera sizes (whole and fractional scales).
TEST(ContactSheetTest, AGreyThumbnailInColourIsTheThumbnailOfTheColourCopy) {
  cv::RNG rng(7);
  for (const cv::Size size :
       {cv::Size(720, 576), cv::Size(1280, 960), cv::Size(641, 479), cv::Size(2592, 1944)}) {
    cv::Mat mask(size, CV_8UC1, cv::Scalar(0));
    for (int k = 0; k < 6; ++k) {
      cv::ellipse(mask, {rng.uniform(0, size.width), rng.uniform(0, size.height)},
                  {rng.uniform(5, size.width / 3), rng.uniform(5, size.height / 3)},
                  rng.uniform(0.0, 180.0), 0, 360, cv::Scalar(255), cv::FILLED);
    }
    cv::Mat colour;
    cv::cvtColor(mask, colour, cv::COLOR_GRAY2BGR);
    cv::Mat grey_then_colour;
    cv::cvtColor(ContactSheetThumbnail(mask), grey_then_colour, cv::COLOR_GRAY2BGR);
    const cv::Mat expected = ContactSheetThumbnail(colour);
    ASSERT_EQ(grey_then_colour.size(), expected.size()) << size;
    EXPECT_EQ(cv::norm(grey_then_colour, expected, cv::NORM_INF), 0.0) << size;
  }
}

}  // namespace
}  // namespace revolve::station
