// OpenCV's image codecs are loaded only when an image needs them (base/image_codecs.h): revolve
// starts without their ~140 libraries, and the common kinds never load them.
#include "base/image_codecs.h"

#include <filesystem>
#include <fstream>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "base/image_read.h"
#include "tests/support/encoded_images.h"
#include "tests/support/test_files.h"

namespace revolve {
namespace {

using testing::HasSubstr;
using Bytes = std::vector<std::uint8_t>;

void Write(const std::filesystem::path& path, const Bytes& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
}

// ctest runs each test in a process of its own: the first reads here are the process's first.
TEST(ImageCodecs, PngAndJpegAreReadWithoutThemAndABmpLoadsThem) {
  const test_support::TempDir dir;
  const cv::Mat picture = test_support::TexturedPicture(64, 48);
  for (const char* ext : {".png", ".jpg", ".bmp"}) {
    Write(dir.path() / (std::string("picture") + ext), test_support::EncodeImage(ext, picture));
  }
  ImageReadOptions colour;
  colour.imread_flags = cv::IMREAD_COLOR;
  ASSERT_TRUE(ReadImageFile(dir.path() / "picture.png", colour));
  ASSERT_TRUE(ReadImageFile(dir.path() / "picture.jpg", colour));
  EXPECT_FALSE(ImageCodecsLoaded());
  const Expected<cv::Mat> bmp = ReadImageFile(dir.path() / "picture.bmp", colour);
  ASSERT_TRUE(bmp) << bmp.error().message;
  EXPECT_TRUE(ImageCodecsLoaded());
  EXPECT_EQ(cv::norm(*bmp, picture, cv::NORM_INF), 0.0);
}

TEST(ImageCodecs, EncodeAndWriteSayWhatFailed) {
  const cv::Mat picture = test_support::TexturedPicture(32, 24);
  const Expected<std::vector<std::uint8_t>> jpeg =
      EncodeImage(".jpg", picture, {cv::IMWRITE_JPEG_QUALITY, 95});
  ASSERT_TRUE(jpeg) << jpeg.error().message;
  EXPECT_EQ(DecodeImage(*jpeg, cv::IMREAD_COLOR)->size(), picture.size());

  const Expected<std::vector<std::uint8_t>> unknown = EncodeImage(".nope", picture);
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error().code, ErrorCode::kBadInput);

  const Bytes junk = {1, 2, 3, 4, 5, 6, 7, 8};
  const Expected<cv::Mat> undecodable = DecodeImage(junk, cv::IMREAD_COLOR);
  ASSERT_FALSE(undecodable);
  EXPECT_EQ(undecodable.error().code, ErrorCode::kBadInput);

  const test_support::TempDir dir;
  const std::filesystem::path odd = dir.path() / "board.xyz";
  const Expected<void> refused = WriteImageFile(odd, picture);
  ASSERT_FALSE(refused);
  EXPECT_THAT(refused.error().message, HasSubstr(odd.string()));
  EXPECT_FALSE(std::filesystem::exists(odd));

  const std::filesystem::path missing = dir.path() / "no" / "such" / "board.png";
  const Expected<void> nowhere = WriteImageFile(missing, picture);
  ASSERT_FALSE(nowhere);
  EXPECT_THAT(nowhere.error().message, HasSubstr(missing.parent_path().string()));

  const std::filesystem::path good = dir.path() / "board.png";
  ASSERT_TRUE(WriteImageFile(good, picture));
  const Expected<cv::Mat> back = ReadImageFile(good);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(cv::norm(*back, picture, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace revolve
