// The masks a `reconstruct --images` run leaves for a person to check (masks/<stem>.png and
// contact_sheet.png): each mask whole, in place, nothing half-written left behind; a mask that
// cannot be put in place is an error naming its file.
#include "station/commands/set_masks.h"

#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace revolve::station {
namespace {

namespace fs = std::filesystem;
using testing::HasSubstr;

class WriteMasksTest : public testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("revolve_set_masks_" + std::to_string(::getpid()) + "_" +
                                     testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // Masks of 96x64 given as windows: a disc at a different place in each.
    for (int i = 0; i < 9; ++i) {
      cv::Mat whole = cv::Mat::zeros(kSize, CV_8UC1);
      cv::circle(whole, cv::Point(20 + 6 * i, 30), 12, cv::Scalar(255), cv::FILLED);
      const cv::Rect window(4 + 6 * i, 14, 34, 34);
      wholes_.push_back(whole);
      windows_.push_back(whole(window).clone());
      origins_.push_back(window.tl());
      names_.push_back("stop_" + std::to_string(100 + i) + ".jpg");
    }
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Every entry of the masks folder that is not a mask's PNG.
  std::vector<std::string> Strays() const {
    std::vector<std::string> strays;
    for (const fs::directory_entry& e : fs::directory_iterator(dir_ / "masks")) {
      if (e.path().extension() != ".png" || !e.is_regular_file()) {
        strays.push_back(e.path().filename().string());
      }
    }
    return strays;
  }

  static inline const cv::Size kSize{96, 64};
  fs::path dir_;
  std::vector<cv::Mat> wholes_, windows_;
  std::vector<cv::Point> origins_;
  std::vector<std::string> names_;
};

TEST_F(WriteMasksTest, EveryMaskWholeInPlaceAndTheContactSheet) {
  ASSERT_TRUE(WriteMasks(dir_, names_, {}, windows_, kSize, origins_));
  for (std::size_t i = 0; i < names_.size(); ++i) {
    const fs::path path = dir_ / "masks" / ("stop_" + std::to_string(100 + i) + ".png");
    const cv::Mat read = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(read.empty()) << path;
    EXPECT_EQ(cv::norm(read, wholes_[i], cv::NORM_INF), 0.0) << path;
  }
  EXPECT_FALSE(cv::imread((dir_ / "contact_sheet.png").string()).empty());
  EXPECT_THAT(Strays(), testing::IsEmpty());
}

// A view left out of the carving is marked on the contact sheet: an amber border on its tile
// (the sheet's second tile), none on the others.
TEST_F(WriteMasksTest, AViewLeftOutHasAnAmberTile) {
  std::vector<std::string> problems(names_.size());
  problems[1] = "its mask disagrees with the hull of the other views";
  ASSERT_TRUE(WriteMasks(dir_, names_, {}, windows_, kSize, origins_, problems));
  const cv::Mat sheet = cv::imread((dir_ / "contact_sheet.png").string());
  ASSERT_FALSE(sheet.empty());
  const int tile_width = sheet.cols / 6;  // 9 tiles: rows of 6
  const auto amber_at = [&](int tile, int x, int y) {
    const cv::Vec3b& p = sheet.at<cv::Vec3b>(y, tile * tile_width + x);
    return p == cv::Vec3b(0, 165, 255);
  };
  EXPECT_TRUE(amber_at(1, 1, sheet.rows / 4));               // its left border
  EXPECT_TRUE(amber_at(1, tile_width - 2, sheet.rows / 4));  // and its right
  EXPECT_FALSE(amber_at(0, 1, sheet.rows / 4));
  EXPECT_FALSE(amber_at(2, 1, sheet.rows / 4));
}

TEST_F(WriteMasksTest, AMaskThatCannotBePutInPlaceIsNamedAndLeavesNoTemporaryFile) {
  // A folder where the fifth mask goes: the rename over it fails (root or not).
  fs::create_directories(dir_ / "masks" / "stop_104.png" / "inside");
  const Expected<void> written = WriteMasks(dir_, names_, {}, windows_, kSize, origins_);
  ASSERT_FALSE(written);
  EXPECT_EQ(written.error().code, ErrorCode::kIo);
  EXPECT_THAT(written.error().message, HasSubstr("stop_104.png"));
  // Only the folder that was in the way is not a mask: no temporary file is left.
  EXPECT_THAT(Strays(), testing::ElementsAre("stop_104.png"));
  EXPECT_FALSE(fs::exists(dir_ / "contact_sheet.png"));
}

}  // namespace
}  // namespace revolve::station
