// Image folders as input (reconstruct/image_set.h): patterns, ordering, binary silhouettes of
// either polarity, photo segmentation, and the errors that name the file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "reconstruct/image_set.h"

namespace revolve::reconstruct {
namespace {

namespace fs = std::filesystem;

TEST(NamePattern, AngleAndIndex) {
  const Expected<NamePattern> shoe = NamePattern::Parse("bw_shoe{angle}.tif");
  ASSERT_TRUE(shoe.has_value());
  EXPECT_TRUE(shoe->is_angle());
  EXPECT_EQ(shoe->Match("bw_shoe350.tif")->value, 350);
  EXPECT_FALSE(shoe->Match("bw_shoe.tif").has_value());
  EXPECT_FALSE(shoe->Match("bw_shoe3a.tif").has_value());
  EXPECT_FALSE(shoe->Match("color_shoe10.tif").has_value());
  EXPECT_EQ(shoe->Format(40), "bw_shoe40.tif");
  const Expected<NamePattern> dino = NamePattern::Parse("dinoSR{index}.png");
  ASSERT_TRUE(dino.has_value());
  EXPECT_EQ(dino->Match("dinoSR0012.png")->value, 12);
  EXPECT_EQ(dino->Match("dinoSR0012.png")->digits, 4);
  EXPECT_EQ(dino->Format(7, 4), "dinoSR0007.png");
  for (const char* bad :
       {"", "a{angle}{index}.png", "plain.png", "a{frame}.png", "d/x{index}.png", "a{index.png"}) {
    EXPECT_FALSE(NamePattern::Parse(bad).has_value()) << bad;
  }
}

TEST(BinarySilhouette, EitherPolarityFromTheBorder) {
  cv::Mat white_on_black(40, 60, CV_8UC1, cv::Scalar(0));
  cv::circle(white_on_black, {30, 20}, 10, cv::Scalar(255), cv::FILLED);
  const std::optional<cv::Mat> a = BinarySilhouette(white_on_black);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(cv::countNonZero(*a), cv::countNonZero(white_on_black));
  cv::Mat black_on_white;
  cv::bitwise_not(white_on_black, black_on_white);
  const std::optional<cv::Mat> b = BinarySilhouette(black_on_white);
  ASSERT_TRUE(b.has_value());
  EXPECT_EQ(cv::countNonZero(*a != *b), 0);
  cv::Mat ones = white_on_black / 255;  // 0/1 images
  ASSERT_TRUE(BinarySilhouette(ones).has_value());
  cv::Mat grey = white_on_black.clone();
  grey.at<std::uint8_t>(0, 0) = 128;
  EXPECT_FALSE(BinarySilhouette(grey).has_value());
}

// The threshold alone (no morphology), on random grey, colour and four-channel images, at the
// edges of the range: object where any of the first three channels exceeds it.
TEST(SegmentPhoto, ThresholdIsAnyOfTheFirstThreeChannelsAbove) {
  PhotoSegmentation options;
  options.close_px = 0;
  options.open_px = 0;
  options.min_component_fraction = 0.0;
  options.fill_holes = false;
  cv::RNG rng(5);
  for (int channels : {1, 3, 4}) {
    cv::Mat image(37, 53, CV_8UC(channels));
    rng.fill(image, cv::RNG::UNIFORM, 0, 256);
    for (int threshold : {0, 20, 128, 254}) {
      options.threshold = threshold;
      const cv::Mat mask = SegmentPhoto(image, options);
      for (int v = 0; v < image.rows; ++v) {
        for (int u = 0; u < image.cols; ++u) {
          bool object = false;
          for (int c = 0; c < std::min(channels, 3); ++c) {
            object |= image.ptr<std::uint8_t>(v)[u * channels + c] > threshold;
          }
          ASSERT_EQ(mask.at<std::uint8_t>(v, u), object ? 255 : 0)
              << channels << " channels, threshold " << threshold << " at " << u << "," << v;
        }
      }
    }
  }
}

TEST(SegmentPhoto, AnyChannelAboveTheThresholdHolesFilled) {
  cv::Mat photo(60, 80, CV_8UC3, cv::Scalar(5, 5, 5));
  cv::circle(photo, {40, 30}, 20, cv::Scalar(10, 10, 120), cv::FILLED);  // red object
  cv::circle(photo, {40, 30}, 4, cv::Scalar(0, 0, 0), cv::FILLED);       // a dark spot in it
  photo.at<cv::Vec3b>(5, 5) = cv::Vec3b(200, 200, 200);                  // a speck
  const cv::Mat mask = SegmentPhoto(photo, PhotoSegmentation{});
  EXPECT_EQ(mask.at<std::uint8_t>(30, 40), 255);  // the hole is filled
  EXPECT_EQ(mask.at<std::uint8_t>(5, 5), 0);      // the speck is gone
  EXPECT_NEAR(cv::countNonZero(mask), M_PI * 20 * 20, 60.0);
  PhotoSegmentation keep_holes;
  keep_holes.max_hole_area_px = 10;
  EXPECT_EQ(SegmentPhoto(photo, keep_holes).at<std::uint8_t>(30, 40), 0);
}

class ImageSetFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("revolve_image_set_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  void Silhouette(const std::string& name, int width = 64, int height = 48) {
    cv::Mat mask(height, width, CV_8UC1, cv::Scalar(0));
    cv::rectangle(mask, {20, 10}, {40, 40}, cv::Scalar(255), cv::FILLED);
    ASSERT_TRUE(cv::imwrite((dir_ / name).string(), mask));
  }
  fs::path dir_;
};

TEST_F(ImageSetFolder, ThesisNamesInAngleOrder) {
  for (int a = 0; a < 360; a += 20) Silhouette("bw_shoe" + std::to_string(a) + ".tif");
  Silhouette("colored_shoe.tif");  // not matched by the pattern
  std::ofstream(dir_ / "notes.txt") << "not an image";
  ImageSetOptions options;
  options.pattern = "bw_shoe{angle}.tif";
  options.step_deg = 20.0;
  const Expected<ImageSet> set = LoadImageSet(dir_, options);
  ASSERT_TRUE(set.has_value()) << set.error().ToString();
  EXPECT_EQ(set->kind, ImageKind::kSilhouette);
  ASSERT_EQ(set->images.size(), 18u);
  EXPECT_EQ(set->images[2].file_name, "bw_shoe40.tif");  // numeric, not name, order
  EXPECT_EQ(set->images[2].index, 2);
  EXPECT_DOUBLE_EQ(set->images[17].angle_deg, 340.0);
  EXPECT_TRUE(set->images[0].image.empty());
  EXPECT_EQ(cv::countNonZero(set->images[0].mask), 21 * 31);
}

TEST_F(ImageSetFolder, ErrorsNameTheFile) {
  for (int i = 1; i <= 4; ++i)
    Silhouette("view" + std::string(i < 10 ? "0" : "") + std::to_string(i) + ".png");
  ImageSetOptions options;
  options.pattern = "view{index}.png";
  ASSERT_TRUE(LoadImageSet(dir_, options).has_value());
  fs::remove(dir_ / "view03.png");
  Expected<ImageSet> set = LoadImageSet(dir_, options);
  ASSERT_FALSE(set.has_value());
  EXPECT_NE(set.error().message.find("view03.png"), std::string::npos) << set.error().message;
  Silhouette("view03.png", 32, 48);
  set = LoadImageSet(dir_, options);
  ASSERT_FALSE(set.has_value());
  EXPECT_NE(set.error().message.find("view03.png"), std::string::npos) << set.error().message;
  ASSERT_TRUE(cv::imwrite((dir_ / "view03.png").string(), cv::Mat(48, 64, CV_8UC1, cv::Scalar(0))));
  set = LoadImageSet(dir_, options);
  ASSERT_FALSE(set.has_value());
  EXPECT_NE(set.error().message.find("view03.png"), std::string::npos);
  EXPECT_NE(set.error().message.find("empty"), std::string::npos);
  cv::Mat photo(48, 64, CV_8UC3, cv::Scalar(0, 0, 0));
  cv::circle(photo, {30, 20}, 8, cv::Scalar(30, 140, 200), cv::FILLED);
  ASSERT_TRUE(cv::imwrite((dir_ / "view03.png").string(), photo));
  set = LoadImageSet(dir_, options);
  ASSERT_FALSE(set.has_value());
  EXPECT_NE(set.error().message.find("view03.png"), std::string::npos);
  std::ofstream(dir_ / "view03.png") << "garbage";
  set = LoadImageSet(dir_, options);
  ASSERT_FALSE(set.has_value());
  EXPECT_NE(set.error().message.find("view03.png"), std::string::npos);
  options.pattern = "shot{index}.png";
  set = LoadImageSet(dir_, options);
  ASSERT_FALSE(set.has_value());
  EXPECT_EQ(set.error().code, ErrorCode::kNotFound);
  EXPECT_FALSE(LoadImageSet(dir_ / "missing", ImageSetOptions{}).has_value());
}

}  // namespace
}  // namespace revolve::reconstruct
