#include <unistd.h>

#include <algorithm>
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

// A frame's thumbnail is cv::resize's area average at the thumbnail's whole factor, to the bit:
// photos of common sizes, sizes no factor divides (the blocks the right and bottom borders cut
// short), grey and colour, a frame that needs no shrinking, and a factor OpenCV does not treat
// as whole (49: 1 / (1 / 49) is not 49).
TEST(ContactSheetTest, AThumbnailIsOpenCvsAreaAverage) {
  cv::RNG rng(5);
  for (const cv::Size size : {cv::Size(1280, 960), cv::Size(720, 576), cv::Size(641, 479),
                              cv::Size(1283, 967), cv::Size(4000, 3000), cv::Size(385, 13),
                              cv::Size(193, 2), cv::Size(150, 100), cv::Size(9300, 60)}) {
    for (const int type : {CV_8UC3, CV_8UC1}) {
      cv::Mat frame(size, type);
      rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
      if (size.width > 600) frame(cv::Rect(0, 0, 300, size.height / 2)).setTo(cv::Scalar::all(255));
      const double fx = 1.0 / std::max(1, (size.width + 191) / 192);
      cv::Mat expected;
      cv::resize(frame, expected, cv::Size(), fx, fx, cv::INTER_AREA);
      const cv::Mat thumbnail = ContactSheetThumbnail(frame);
      ASSERT_EQ(thumbnail.size(), expected.size()) << size;
      ASSERT_EQ(thumbnail.type(), expected.type()) << size;
      EXPECT_EQ(cv::norm(thumbnail, expected, cv::NORM_INF), 0.0) << size << " type " << type;
    }
  }
}

// A silhouette's thumbnail from the part around its rectangle is the whole mask's thumbnail, to
// the bit: at widths whose shrinking factor repeats exactly (720: 15 px to 4; 768: 4 to 1; 960:
// 5 to 1) and at the others (the whole mask shrunk), for blobs anywhere, at the borders included,
// for tight and loose rectangles, and for an empty one.
TEST(ContactSheetTest, AThumbnailFromTheSilhouettesRectangleIsTheWholeMasksThumbnail) {
  cv::RNG rng(11);
  int cases = 0;
  for (const cv::Size size : {cv::Size(720, 576), cv::Size(768, 576), cv::Size(960, 720),
                              cv::Size(1280, 960), cv::Size(641, 479), cv::Size(150, 100)}) {
    for (int k = 0; k < 12; ++k) {
      cv::Mat mask(size, CV_8UC1, cv::Scalar(0));
      const cv::Point centre(rng.uniform(0, size.width), rng.uniform(0, size.height));
      cv::ellipse(mask, centre, {rng.uniform(2, size.width / 4), rng.uniform(2, size.height / 4)},
                  rng.uniform(0.0, 180.0), 0, 360, cv::Scalar(255), cv::FILLED);
      if (k % 4 == 0) mask.row(size.height - 1).setTo(255);  // to the bottom border
      if (k % 4 == 1) mask.col(size.width - 1).setTo(255);   // to the right border
      cv::Rect content = cv::boundingRect(mask);
      if (k % 3 == 0) {  // a window with zeros around the silhouette
        content = cv::Rect(content.x - 7, content.y - 5, content.width + 20, content.height + 9) &
                  cv::Rect(cv::Point(), size);
      }
      const cv::Mat expected = ContactSheetThumbnail(mask);
      const cv::Mat shrunk = ContactSheetThumbnail(mask, content);
      ASSERT_EQ(shrunk.size(), expected.size()) << size << " " << k;
      ASSERT_EQ(shrunk.type(), expected.type());
      EXPECT_EQ(cv::norm(shrunk, expected, cv::NORM_INF), 0.0) << size << " " << k;
      ++cases;
    }
    const cv::Mat none(size, CV_8UC1, cv::Scalar(0));
    EXPECT_EQ(cv::norm(ContactSheetThumbnail(none, cv::Rect()), ContactSheetThumbnail(none),
                       cv::NORM_INF),
              0.0);
  }
  EXPECT_EQ(cases, 72);
}

}  // namespace
}  // namespace revolve::station
