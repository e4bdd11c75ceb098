// Image folders as input (reconstruct/image_set.h): patterns, ordering, binary silhouettes of
// either polarity, cut-out photos, photo segmentation, and the errors that name the file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <unistd.h>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "reconstruct/image_set.h"
#include "tests/support/encoded_images.h"

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
  // Two levels are 0 and 1 or 255; a third anywhere, or another pair, is a photo.
  for (const auto& [other, at] :
       {std::pair{1, cv::Point(59, 39)}, std::pair{255, cv::Point(30, 20)},
        std::pair{7, cv::Point(5, 5)}}) {
    cv::Mat three = other == 255 ? ones.clone() : white_on_black.clone();
    three.at<std::uint8_t>(at) = static_cast<std::uint8_t>(other);
    EXPECT_FALSE(BinarySilhouette(three).has_value()) << other;
  }
  EXPECT_FALSE(BinarySilhouette(white_on_black / 255 * 7).has_value());  // 0 and 7
  cv::Mat no_zero = white_on_black.clone();
  no_zero.setTo(10, white_on_black == 0);
  EXPECT_FALSE(BinarySilhouette(no_zero).has_value());  // 10 and 255
  // One level: all object or all background, whatever the value.
  const std::optional<cv::Mat> flat = BinarySilhouette(cv::Mat(40, 60, CV_8UC1, cv::Scalar(37)));
  ASSERT_TRUE(flat.has_value());
  const std::optional<cv::Mat> none = BinarySilhouette(cv::Mat(40, 60, CV_8UC1, cv::Scalar(0)));
  ASSERT_TRUE(none.has_value());
  EXPECT_EQ(cv::countNonZero(*none), 0);
}

// SegmentPhoto as it was written first, on the whole image (the function now works on the
// object's rectangle).
cv::Mat SegmentWholeImage(const cv::Mat& image, const PhotoSegmentation& options) {
  const auto disc = [](int r) {
    return cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1));
  };
  cv::Mat mask(image.size(), CV_8UC1, cv::Scalar(0));
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      for (int c = 0; c < std::min(image.channels(), 3); ++c) {
        if (image.ptr<std::uint8_t>(v)[u * image.channels() + c] > options.threshold) {
          mask.at<std::uint8_t>(v, u) = 255;
        }
      }
    }
  }
  if (options.close_px > 0) cv::morphologyEx(mask, mask, cv::MORPH_CLOSE, disc(options.close_px));
  if (options.open_px > 0) cv::morphologyEx(mask, mask, cv::MORPH_OPEN, disc(options.open_px));
  if (options.min_component_fraction > 0.0) {
    cv::Mat labels, stats, centroids;
    const int count = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
    int largest = 0;
    for (int i = 1; i < count; ++i) largest = std::max(largest, stats.at<int>(i, cv::CC_STAT_AREA));
    for (int v = 0; v < mask.rows && count > 2; ++v) {
      for (int u = 0; u < mask.cols; ++u) {
        const int l = labels.at<int>(v, u);
        if (l > 0 &&
            stats.at<int>(l, cv::CC_STAT_AREA) < options.min_component_fraction * largest) {
          mask.at<std::uint8_t>(v, u) = 0;
        }
      }
    }
  }
  if (options.fill_holes) {
    cv::Mat padded;
    cv::copyMakeBorder(mask, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::Mat flood = padded.clone();
    cv::floodFill(flood, cv::Point(0, 0), cv::Scalar(255), nullptr, cv::Scalar(), cv::Scalar(), 4);
    cv::Mat holes = ~flood;
    if (options.max_hole_area_px > 0) {
      cv::Mat labels, stats, centroids;
      cv::connectedComponentsWithStats(holes, labels, stats, centroids, 4, CV_32S);
      for (int v = 0; v < holes.rows; ++v) {
        for (int u = 0; u < holes.cols; ++u) {
          const int l = labels.at<int>(v, u);
          if (l > 0 && stats.at<int>(l, cv::CC_STAT_AREA) > options.max_hole_area_px) {
            holes.at<std::uint8_t>(v, u) = 0;
          }
        }
      }
    }
    const cv::Mat filled = padded | holes;
    mask = filled(cv::Rect(1, 1, mask.cols, mask.rows)).clone();
  }
  return mask;
}

// Blobs, specks, holes of every size and shapes cut by the image border: the same mask as on
// the whole image, for each option.
TEST(SegmentPhoto, ObjectRectangleGivesTheWholeImagesResult) {
  cv::RNG rng(9);
  for (int trial = 0; trial < 12; ++trial) {
    cv::Mat image(120, 160, CV_8UC3, cv::Scalar(0, 0, 0));
    const int blobs = 1 + trial % 5;
    for (int b = 0; b < 3 * blobs; ++b) {
      const cv::Point centre(rng.uniform(-10, 170), rng.uniform(-10, 130));
      const int radius = b % 3 == 2 ? rng.uniform(1, 3) : rng.uniform(3, 30);
      const cv::Scalar colour =
          b % 4 == 3 ? cv::Scalar(0, 0, 0)
                     : cv::Scalar(rng.uniform(0, 256), rng.uniform(0, 256), rng.uniform(30, 256));
      cv::circle(image, centre, radius, colour, cv::FILLED);
    }
    PhotoSegmentation options;
    options.close_px = trial % 4;
    options.open_px = trial % 3;
    options.min_component_fraction = trial % 2 ? 0.05 : 0.0;
    options.max_hole_area_px = trial % 3 == 1 ? 40 : 0;
    options.fill_holes = trial % 5 != 4;
    const cv::Mat expected = SegmentWholeImage(image, options);
    EXPECT_EQ(cv::countNonZero(expected != SegmentPhoto(image, options)), 0) << "trial " << trial;
  }
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

// A cut-out photo (BGRA): an object opaque (a circle, its rim at half alpha), the rest transparent
// over colours that are not black (what a background remover leaves behind).
cv::Mat CutOut() {
  cv::Mat bgra(48, 64, CV_8UC4);
  cv::randu(bgra, cv::Scalar(0, 0, 0, 0), cv::Scalar(256, 256, 256, 1));  // alpha 0
  cv::circle(bgra, {30, 22}, 12, cv::Scalar(40, 120, 200, 255), cv::FILLED);
  cv::circle(bgra, {30, 22}, 12, cv::Scalar(40, 120, 200, 128), 1);  // the rim, half covered
  return bgra;
}

// `bgra` with its alpha set to `alpha` everywhere.
cv::Mat WithAlpha(const cv::Mat& bgra, int alpha) {
  cv::Mat channels[4];
  cv::split(bgra, channels);
  channels[3].setTo(alpha);
  cv::Mat out;
  cv::merge(channels, 4, out);
  return out;
}

TEST_F(ImageSetFolder, CutOutPhotosAreMaskedByTheirAlpha) {
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(cv::imwrite((dir_ / fmt::format("view{}.png", i)).string(), CutOut()));
  }
  ImageSetOptions options;
  options.segment_photos = false;  // as reconstruct --images loads a set
  Expected<ImageSet> set = LoadImageSet(dir_, options);
  ASSERT_TRUE(set.has_value()) << set.error().ToString();
  EXPECT_EQ(set->kind, ImageKind::kCutOut);
  const cv::Mat truth = [] {
    cv::Mat mask(48, 64, CV_8UC1, cv::Scalar(0));
    cv::circle(mask, {30, 22}, 12, cv::Scalar(255), cv::FILLED);
    return mask;
  }();
  for (const SetImage& image : set->images) {
    EXPECT_EQ(cv::countNonZero(image.mask != truth), 0) << image.file_name;  // the rim included
    ASSERT_EQ(image.image.type(), CV_8UC3);  // the colours kept for texture
    EXPECT_EQ(image.image.at<cv::Vec3b>(22, 30), cv::Vec3b(40, 120, 200));
  }
  // Opaque everywhere: an ordinary photo, its alpha ignored.
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(
        cv::imwrite((dir_ / fmt::format("view{}.png", i)).string(), WithAlpha(CutOut(), 255)));
  }
  set = LoadImageSet(dir_, options);
  ASSERT_TRUE(set.has_value()) << set.error().ToString();
  EXPECT_EQ(set->kind, ImageKind::kPhoto);
  // One cut-out among photos is named as such.
  ASSERT_TRUE(cv::imwrite((dir_ / "view2.png").string(), CutOut()));
  set = LoadImageSet(dir_, options);
  ASSERT_FALSE(set.has_value());
  EXPECT_NE(set.error().message.find("view2.png: a cut-out photo among photos"), std::string::npos)
      << set.error().message;
  // A cut-out transparent everywhere has no object.
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(cv::imwrite((dir_ / fmt::format("view{}.png", i)).string(), CutOut()));
  }
  ASSERT_TRUE(cv::imwrite((dir_ / "view1.png").string(), WithAlpha(CutOut(), 40)));
  set = LoadImageSet(dir_, options);
  ASSERT_FALSE(set.has_value());
  EXPECT_NE(set.error().message.find("view1.png: the silhouette is empty (no pixel's alpha"),
            std::string::npos)
      << set.error().message;
}

// 16-bit images (a raw converter's TIFF, a 16-bit PNG) load as their 8-bit selves, cut-outs
// included; floating-point samples are refused by name.
// Photos from a camera turned on its side: the JPEGs hold the pixels as the sensor saw them
// (the turntable's axis across the picture) and EXIF says to turn them a quarter. The set is the
// photos as a viewer shows them: upright, the object standing, in the photos' upright size, with
// the count of turned images for the log; one photo saved upright without EXIF fits in.
TEST_F(ImageSetFolder, JpegPhotosAreTurnedUprightByTheirExif) {
  cv::Mat upright(48, 64, CV_8UC3, cv::Scalar(0, 0, 0));
  cv::rectangle(upright, {26, 8}, {37, 39}, cv::Scalar(60, 160, 220), cv::FILLED);  // standing
  cv::Mat stored;
  cv::rotate(upright, stored, cv::ROTATE_90_COUNTERCLOCKWISE);  // 6: a quarter clockwise to show
  std::vector<std::uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", stored, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}));
  const std::vector<std::uint8_t> turned = test_support::WithExifOrientation(jpeg, 6);
  for (int i = 0; i < 4; ++i) {
    std::ofstream(dir_ / fmt::format("view{}.jpg", i), std::ios::binary)
        .write(reinterpret_cast<const char*>(turned.data()),
               static_cast<std::streamsize>(turned.size()));
  }
  ASSERT_TRUE(cv::imwrite((dir_ / "view4.jpg").string(), upright, {cv::IMWRITE_JPEG_QUALITY, 95}));
  const Expected<ImageSet> set = LoadImageSet(dir_, ImageSetOptions{});
  ASSERT_TRUE(set.has_value()) << set.error().ToString();
  EXPECT_EQ(set->kind, ImageKind::kPhoto);
  EXPECT_EQ(cv::Size(set->width_px, set->height_px), cv::Size(64, 48));
  EXPECT_EQ(set->exif_turned, 4);
  for (const SetImage& image : set->images) {
    const cv::Rect object = cv::boundingRect(image.mask);
    EXPECT_NEAR(object.x, 26, 1) << image.file_name;
    EXPECT_NEAR(object.y, 8, 1) << image.file_name;
    EXPECT_NEAR(object.width, 12, 2) << image.file_name;
    EXPECT_NEAR(object.height, 32, 2) << image.file_name;
  }
  // Read through ReadImage8 (as a photo is read again for texture): upright too.
  const Expected<cv::Mat> again = ReadImage8(dir_ / "view0.jpg");
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(again->size(), cv::Size(64, 48));
}

// A folder with no image revolve reads says what it holds instead: phone or raw photos to
// convert, a folder of images one level down, or nothing.
TEST_F(ImageSetFolder, AFolderWithoutImagesSaysWhatItHolds) {
  const auto message = [&] {
    const Expected<ImageSet> set = LoadImageSet(dir_, ImageSetOptions{});
    EXPECT_FALSE(set.has_value());
    return set.has_value() ? std::string() : set.error().message;
  };
  EXPECT_NE(message().find("it is empty"), std::string::npos) << message();
  for (int i = 0; i < 3; ++i) std::ofstream(dir_ / fmt::format("IMG_{}.HEIC", i)) << "ftypheic";
  std::ofstream(dir_ / "notes.txt") << "turntable, 10 degrees";
  EXPECT_NE(message().find("it holds 3 .heic files, a format revolve does not read: convert them "
                           "to JPEG, PNG or TIFF first"),
            std::string::npos)
      << message();
  for (int i = 0; i < 3; ++i) fs::remove(dir_ / fmt::format("IMG_{}.HEIC", i));
  fs::create_directories(dir_ / "shots");
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(cv::imwrite((dir_ / "shots" / fmt::format("view{}.png", i)).string(),
                            cv::Mat(48, 64, CV_8UC1, cv::Scalar(0))));
  }
  EXPECT_NE(message().find("its folder shots/ holds 4 images: pass that folder"), std::string::npos)
      << message();
}

TEST_F(ImageSetFolder, SixteenBitImagesAreScaledToEightBits) {
  cv::Mat photo(48, 64, CV_8UC3, cv::Scalar(0, 0, 0));
  cv::circle(photo, {30, 20}, 8, cv::Scalar(30, 140, 200), cv::FILLED);
  cv::Mat deep;
  photo.convertTo(deep, CV_16UC3, 257.0);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(cv::imwrite((dir_ / fmt::format("view{}.tif", i)).string(), deep));
  }
  ImageSetOptions options;
  options.segment_photos = false;
  Expected<ImageSet> set = LoadImageSet(dir_, options);
  ASSERT_TRUE(set.has_value()) << set.error().ToString();
  EXPECT_EQ(set->kind, ImageKind::kPhoto);
  ASSERT_EQ(set->images[0].image.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(set->images[0].image, photo, cv::NORM_INF), 0.0);

  cv::Mat cut_out;
  CutOut().convertTo(cut_out, CV_16UC4, 257.0);
  for (int i = 0; i < 3; ++i) {
    fs::remove(dir_ / fmt::format("view{}.tif", i));
    ASSERT_TRUE(cv::imwrite((dir_ / fmt::format("view{}.png", i)).string(), cut_out));
  }
  set = LoadImageSet(dir_, options);
  ASSERT_TRUE(set.has_value()) << set.error().ToString();
  EXPECT_EQ(set->kind, ImageKind::kCutOut);
  cv::Mat circle(48, 64, CV_8UC1, cv::Scalar(0));
  cv::circle(circle, {30, 22}, 12, cv::Scalar(255), cv::FILLED);
  EXPECT_EQ(cv::countNonZero(set->images[1].mask != circle), 0);

  cv::Mat floating;
  photo.convertTo(floating, CV_32FC3, 1.0 / 255.0);
  fs::remove(dir_ / "view1.png");
  ASSERT_TRUE(cv::imwrite((dir_ / "view1.tif").string(), floating));
  set = LoadImageSet(dir_, options);
  ASSERT_FALSE(set.has_value());
  EXPECT_NE(set.error().message.find("view1.tif: 32-bit floating-point samples"), std::string::npos)
      << set.error().message;
}

}  // namespace
}  // namespace revolve::reconstruct
