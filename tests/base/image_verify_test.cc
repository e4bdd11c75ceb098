// Issue 21, cause 4: every warning of libjpeg, libpng and libtiff is an error naming the file,
// not only "Premature end of JPEG file". Each case is a file OpenCV decodes without complaint
// (it prints the library's warning and goes on), generated here by damaging a good one.
#include "base/image_verify.h"

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "base/image_header.h"
#include "base/image_read.h"
#include "base/png_encode.h"
#include "tests/support/encoded_images.h"
#include "tests/support/test_files.h"

namespace revolve {
namespace {

using testing::HasSubstr;
using Bytes = std::vector<std::uint8_t>;
using test_support::EncodeImage;
using test_support::TexturedPicture;

// The offset of the JPEG end-of-image marker (the file's last two bytes).
std::size_t JpegEnd(const Bytes& jpeg) { return jpeg.size() - 2; }

// The offset of the first byte of entropy-coded data (after the SOS segment).
std::size_t JpegScanStart(const Bytes& jpeg) {
  for (std::size_t i = 2; i + 3 < jpeg.size();) {
    const std::size_t length = (jpeg[i + 2] << 8) | jpeg[i + 3];
    if (jpeg[i + 1] == 0xDA) return i + 2 + length;
    i += 2 + length;
  }
  return 0;
}

void Write(const std::filesystem::path& path, const Bytes& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
}

class ImageVerifyTest : public testing::Test {
 protected:
  // Writes `bytes`, checks OpenCV alone decodes them (the damage is silent without the check),
  // and returns ReadImageFile's error message.
  std::string RefusedMessage(const std::string& name, const Bytes& bytes) {
    EXPECT_FALSE(cv::imdecode(bytes, cv::IMREAD_UNCHANGED).empty())
        << name << ": OpenCV refuses it too, so the case proves nothing";
    const std::filesystem::path path = dir_.path() / name;
    Write(path, bytes);
    const Expected<cv::Mat> image = ReadImageFile(path);
    EXPECT_FALSE(image) << name << " was decoded";
    if (image) return "";
    EXPECT_EQ(image.error().code, ErrorCode::kBadInput);
    EXPECT_THAT(image.error().message, HasSubstr(path.string()));
    return image.error().message;
  }
  test_support::TempDir dir_;
};

TEST_F(ImageVerifyTest, ExtraneousBytesBeforeAJpegMarkerAreRefused) {
  // After the last block's bits (the decoder reads a few bytes ahead, so more than a few).
  Bytes jpeg = EncodeImage(".jpg", TexturedPicture(96, 64));
  const Bytes junk(64, 0x5A);
  jpeg.insert(jpeg.begin() + static_cast<std::ptrdiff_t>(JpegEnd(jpeg)), junk.begin(), junk.end());
  EXPECT_THAT(RefusedMessage("extraneous.jpg", jpeg),
              testing::ContainsRegex("Corrupt JPEG data: [0-9]+ extraneous bytes before marker "
                                     "0xd9"));
}

TEST_F(ImageVerifyTest, DamagedJpegEntropyDataIsRefused) {
  // Overwrites a stretch of the scan data with bytes that are no marker: libjpeg warns (bad
  // Huffman code, or a marker where it expected data) and decodes rubbish.
  const Bytes good = EncodeImage(".jpg", TexturedPicture(160, 120));
  const std::size_t start = JpegScanStart(good);
  ASSERT_GT(start, 0u);
  int refused = 0;
  for (std::uint8_t fill : {0x00, 0xFE, 0x7F, 0xA5}) {
    Bytes jpeg = good;
    std::fill(jpeg.begin() + static_cast<std::ptrdiff_t>(start + 40),
              jpeg.begin() + static_cast<std::ptrdiff_t>(start + 400), fill);
    if (cv::imdecode(jpeg, cv::IMREAD_UNCHANGED).empty()) continue;
    const std::string message = RefusedMessage("huffman.jpg", jpeg);
    EXPECT_THAT(message, HasSubstr("libjpeg warns")) << int{fill};
    ++refused;
  }
  EXPECT_GT(refused, 0);
}

TEST_F(ImageVerifyTest, AJpegWithAStrayMarkerInItsScanIsRefused) {
  Bytes jpeg = EncodeImage(".jpg", TexturedPicture(160, 120));
  const std::size_t at = JpegScanStart(jpeg) + 100;
  const Bytes marker = {0xFF, 0xD3};  // RST3 where no restart interval was declared
  jpeg.insert(jpeg.begin() + static_cast<std::ptrdiff_t>(at), marker.begin(), marker.end());
  EXPECT_THAT(RefusedMessage("stray_marker.jpg", jpeg), HasSubstr("libjpeg"));
}

// A PNG whose compressed image data is damaged, its chunk CRC recomputed so that only the
// decoder can tell.
TEST_F(ImageVerifyTest, DamagedPngImageDataWithAValidCrcIsRefused) {
  const cv::Mat image(60, 80, CV_8UC1, cv::Scalar(9));
  Bytes png = EncodeImage(".png", image);
  // The first IDAT chunk: 8 signature bytes, then chunks of length, type, data, CRC.
  std::size_t at = 8;
  while (std::string(png.begin() + static_cast<std::ptrdiff_t>(at + 4),
                     png.begin() + static_cast<std::ptrdiff_t>(at + 8)) != "IDAT") {
    at += 12 + ((png[at] << 24) | (png[at + 1] << 16) | (png[at + 2] << 8) | png[at + 3]);
  }
  const std::uint32_t length =
      (png[at] << 24) | (png[at + 1] << 16) | (png[at + 2] << 8) | png[at + 3];
  ASSERT_GT(length, 8u);
  // The zlib stream's Adler-32 checksum (its last four bytes) no longer matches the data.
  png[at + 8 + length - 1] ^= 0x5A;
  const auto crc = static_cast<std::uint32_t>(crc32(0L, &png[at + 4], length + 4));
  for (int i = 0; i < 4; ++i)
    png[at + 8 + length + i] = static_cast<std::uint8_t>(crc >> (24 - 8 * i));
  const std::filesystem::path path = dir_.path() / "adler.png";
  Write(path, png);
  const Expected<cv::Mat> decoded = ReadImageFile(path);
  ASSERT_FALSE(decoded);
  EXPECT_THAT(decoded.error().message, HasSubstr(path.string()));
  EXPECT_THAT(decoded.error().message, HasSubstr("libpng"));
}

TEST_F(ImageVerifyTest, DamagedLzwTiffStripsAreRefused) {
  const Bytes good = EncodeImage(".tif", TexturedPicture(64, 48));  // OpenCV writes LZW
  ASSERT_TRUE(VerifyImageData(ImageFormat::kTiff, good));
  int refused = 0;
  // The strips follow the 8-byte header; the directory is at the end.
  for (std::size_t at = 16; at + 64 < good.size() / 2; at += 97) {
    Bytes tiff = good;
    std::fill(tiff.begin() + static_cast<std::ptrdiff_t>(at),
              tiff.begin() + static_cast<std::ptrdiff_t>(at + 48), 0xFF);
    if (!VerifyImageData(ImageFormat::kTiff, tiff)) ++refused;
  }
  EXPECT_GT(refused, 0);
}

// An uncompressed TIFF whose strip byte count is less than its rows need: libtiff would read
// what is there; the header check refuses it.
TEST_F(ImageVerifyTest, AnUncompressedTiffWithShortStripsIsRefused) {
  const Bytes good =
      EncodeImage(".tif", TexturedPicture(40, 30), {cv::IMWRITE_TIFF_COMPRESSION, 1});
  ASSERT_TRUE(CheckImageBytes(good));
  // StripByteCounts (tag 279) entries: halve each.
  Bytes tiff = good;
  const std::size_t ifd = tiff[4] | (tiff[5] << 8) | (tiff[6] << 16) | (tiff[7] << 24);
  const std::size_t count = tiff[ifd] | (tiff[ifd + 1] << 8);
  bool found = false;
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t entry = ifd + 2 + i * 12;
    if ((tiff[entry] | (tiff[entry + 1] << 8)) != 279) continue;
    const std::uint32_t n = tiff[entry + 4] | (tiff[entry + 5] << 8);
    const std::uint16_t type = tiff[entry + 2] | (tiff[entry + 3] << 8);
    const std::size_t size = type == 3 ? 2 : 4;
    std::size_t values = entry + 8;
    if (n * size > 4) values = tiff[entry + 8] | (tiff[entry + 9] << 8) | (tiff[entry + 10] << 16);
    for (std::uint32_t k = 0; k < n; ++k) {
      const std::size_t v = values + k * size;
      const std::uint32_t bytes = tiff[v] | (tiff[v + 1] << 8);
      tiff[v] = static_cast<std::uint8_t>((bytes / 2) & 0xFF);
      tiff[v + 1] = static_cast<std::uint8_t>((bytes / 2) >> 8);
    }
    found = true;
  }
  ASSERT_TRUE(found);
  const Expected<ImageHeader> header = CheckImageBytes(tiff);
  ASSERT_FALSE(header);
  EXPECT_THAT(header.error().message, HasSubstr("uncompressed pixels"));
}

TEST_F(ImageVerifyTest, GoodImagesOfEveryFormatPass) {
  const cv::Mat image = TexturedPicture(77, 51);
  for (const std::string ext : {".png", ".jpg", ".tif", ".bmp", ".ppm"}) {
    const Bytes bytes = EncodeImage(ext, image);
    const Expected<ImageHeader> header = CheckImageBytes(bytes);
    ASSERT_TRUE(header) << ext << ": " << header.error().message;
    const Expected<void> verified = VerifyImageData(header->format, bytes);
    EXPECT_TRUE(verified) << ext << ": " << (verified ? "" : verified.error().message);
  }
  // Progressive JPEG, interlaced PNG, 16-bit PNG and TIFF, grey JPEG.
  const std::vector<std::pair<std::string, std::vector<int>>> variants = {
      {".jpg", {cv::IMWRITE_JPEG_PROGRESSIVE, 1}},
      {".png", {cv::IMWRITE_PNG_COMPRESSION, 9}},
  };
  for (const auto& [ext, params] : variants) {
    const Bytes bytes = EncodeImage(ext, image, params);
    const Expected<ImageHeader> header = CheckImageBytes(bytes);
    ASSERT_TRUE(header) << ext;
    EXPECT_TRUE(VerifyImageData(header->format, bytes)) << ext;
  }
  cv::Mat deep;
  image.convertTo(deep, CV_16UC3, 257.0);
  for (const std::string ext : {".png", ".tif"}) {
    const Bytes bytes = EncodeImage(ext, deep);
    EXPECT_TRUE(VerifyImageData(CheckImageBytes(bytes)->format, bytes)) << ext << " 16-bit";
  }
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  const Bytes bytes = EncodeImage(".jpg", grey);
  EXPECT_TRUE(VerifyImageData(ImageFormat::kJpeg, bytes));
}

// The one-pass PNG decoder gives what OpenCV gives, pixel for pixel, for every kind it takes.
TEST(DecodeVerifiedPng, MatchesOpenCvForGreyRgbAndRgbaUnderEveryFlag) {
  const cv::Mat bgr = TexturedPicture(61, 47);
  cv::Mat grey, bgra;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
  bgra.forEach<cv::Vec4b>(
      [](cv::Vec4b& p, const int* at) { p[3] = static_cast<uchar>(at[1] * 4); });
  int decoded = 0;
  for (const cv::Mat& image : {grey, bgr, bgra}) {
    const Bytes bytes = EncodeImage(".png", image);
    for (const int flags : {cv::IMREAD_UNCHANGED, cv::IMREAD_COLOR, cv::IMREAD_GRAYSCALE}) {
      const cv::Mat expected = cv::imdecode(bytes, flags);
      const std::optional<Expected<cv::Mat>> mine = DecodeVerifiedPng(bytes, flags);
      if (!mine) continue;  // left to OpenCV
      ASSERT_TRUE(*mine) << (*mine).error().message;
      ++decoded;
      ASSERT_EQ((*mine)->type(), expected.type()) << image.channels() << " channels, " << flags;
      ASSERT_EQ((*mine)->size(), expected.size());
      EXPECT_EQ(cv::norm(**mine, expected, cv::NORM_INF), 0.0)
          << image.channels() << " channels, flags " << flags;
    }
  }
  EXPECT_GE(decoded, 7);  // all but RGB(A) read as grey
  // Damage is refused as by VerifyImageData.
  Bytes cut = EncodeImage(".png", grey);
  cut.resize(cut.size() - 30);
  cut.insert(cut.end(), 30, 0);
  const std::optional<Expected<cv::Mat>> refused = DecodeVerifiedPng(cut, cv::IMREAD_GRAYSCALE);
  ASSERT_TRUE(refused);
  EXPECT_FALSE(*refused);
}

// Masks (only 0 and 255) are written one bit a pixel (base/png_encode.h): OpenCV and the one-pass
// decoder read them back as the mask, under every flag; one grey level more keeps 8 bits.
TEST(DecodeVerifiedPng, ReadsOneBitMasksAsWrittenAndAsOpenCvDoes) {
  for (const cv::Size size : {cv::Size(61, 47), cv::Size(720, 576), cv::Size(1, 3)}) {
    cv::Mat mask(size, CV_8UC1, cv::Scalar(0));
    cv::ellipse(mask, {size.width / 2, size.height / 2}, {size.width / 3 + 1, size.height / 4 + 1},
                30.0, 0, 360, cv::Scalar(255), cv::FILLED);
    mask.at<std::uint8_t>(0, size.width - 1) = 255;  // the last pixel of a partial byte
    const Expected<std::string> png = EncodePng(mask);
    ASSERT_TRUE(png);
    const Bytes bytes(png->begin(), png->end());
    EXPECT_EQ(bytes[24], 1) << "bit depth, " << size;
    for (const int flags : {cv::IMREAD_UNCHANGED, cv::IMREAD_COLOR, cv::IMREAD_GRAYSCALE}) {
      const cv::Mat expected = cv::imdecode(bytes, flags);
      ASSERT_FALSE(expected.empty());
      const std::optional<Expected<cv::Mat>> mine = DecodeVerifiedPng(bytes, flags);
      ASSERT_TRUE(mine) << flags;
      ASSERT_TRUE(*mine) << (*mine).error().message;
      ASSERT_EQ((*mine)->type(), expected.type()) << flags;
      EXPECT_EQ(cv::norm(**mine, expected, cv::NORM_INF), 0.0) << size << ", flags " << flags;
      if (flags != cv::IMREAD_COLOR) {
        EXPECT_EQ(cv::norm(**mine, mask, cv::NORM_INF), 0.0);
      }
    }
    cv::Mat grey = mask.clone();
    grey.at<std::uint8_t>(size.height - 1, 0) = 254;
    const Expected<std::string> eight = EncodePng(grey);
    ASSERT_TRUE(eight);
    EXPECT_EQ(static_cast<int>((*eight)[24]), 8) << size;
    const cv::Mat back = cv::imdecode(Bytes(eight->begin(), eight->end()), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(cv::norm(back, grey, cv::NORM_INF), 0.0);
  }
}

// The one-pass JPEG decoder gives what OpenCV gives, pixel for pixel: colour (4:2:0 and
// progressive) and grey files under every flag it takes.
TEST(DecodeVerifiedJpeg, MatchesOpenCvForColourGreyAndProgressiveUnderEveryFlag) {
  const cv::Mat bgr = TexturedPicture(83, 61);  // odd sizes: partial MCUs at both edges
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  const std::vector<Bytes> files = {EncodeImage(".jpg", bgr), EncodeImage(".jpg", grey),
                                    EncodeImage(".jpg", bgr, {cv::IMWRITE_JPEG_PROGRESSIVE, 1}),
                                    EncodeImage(".jpg", bgr, {cv::IMWRITE_JPEG_QUALITY, 100})};
  int decoded = 0;
  for (std::size_t f = 0; f < files.size(); ++f) {
    for (const int flags : {cv::IMREAD_UNCHANGED, cv::IMREAD_COLOR, cv::IMREAD_GRAYSCALE}) {
      const cv::Mat expected = cv::imdecode(files[f], flags);
      const std::optional<Expected<cv::Mat>> mine = DecodeVerifiedJpeg(files[f], flags);
      ASSERT_TRUE(mine) << "file " << f << ", flags " << flags;
      ASSERT_TRUE(*mine) << (*mine).error().message;
      ++decoded;
      ASSERT_EQ((*mine)->type(), expected.type()) << "file " << f << ", flags " << flags;
      ASSERT_EQ((*mine)->size(), expected.size());
      EXPECT_EQ(cv::norm(**mine, expected, cv::NORM_INF), 0.0) << "file " << f << ", " << flags;
    }
  }
  EXPECT_EQ(decoded, 12);
}

// A JPEG whose EXIF says "turn a quarter" is left to OpenCV (which turns it), except when the
// caller asked for the file unchanged.
TEST(DecodeVerifiedJpeg, AnExifTurnIsLeftToOpenCvUnlessUnchanged) {
  const Bytes turned =
      test_support::WithExifOrientation(EncodeImage(".jpg", TexturedPicture(40, 24)), 6);
  ASSERT_EQ(cv::imdecode(turned, cv::IMREAD_COLOR).size(), cv::Size(24, 40));  // OpenCV turns
  EXPECT_FALSE(DecodeVerifiedJpeg(turned, cv::IMREAD_COLOR));
  EXPECT_FALSE(DecodeVerifiedJpeg(turned, cv::IMREAD_GRAYSCALE));
  const std::optional<Expected<cv::Mat>> unchanged =
      DecodeVerifiedJpeg(turned, cv::IMREAD_UNCHANGED);
  ASSERT_TRUE(unchanged && *unchanged);
  EXPECT_EQ(cv::norm(**unchanged, cv::imdecode(turned, cv::IMREAD_UNCHANGED), cv::NORM_INF), 0.0);
  // Through ReadImageFile the turned picture arrives turned, as before.
  const test_support::TempDir dir;
  Write(dir.path() / "turned.jpg", turned);
  ImageReadOptions options;
  options.imread_flags = cv::IMREAD_COLOR;
  const Expected<cv::Mat> read = ReadImageFile(dir.path() / "turned.jpg", options);
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_EQ(read->size(), cv::Size(24, 40));
}

// A photo from a camera held sideways: its pixels stored as the sensor saw them, and the EXIF
// orientation saying how to show them. ReadImageFile's `upright` shows each of the eight as
// cv::imread's default (and a viewer) does, in either byte order of the EXIF block; the header
// tells the orientation and the size the picture will have before it is decoded.
TEST(ReadImageFile, UprightTurnsEachExifOrientationAsOpenCvDoes) {
  const test_support::TempDir dir;
  const Bytes plain = EncodeImage(".jpg", TexturedPicture(40, 24));
  for (int orientation = 1; orientation <= 8; ++orientation) {
    for (const bool big_endian : {false, true}) {
      const std::string what =
          fmt::format("orientation {}, {} endian", orientation, big_endian ? "big" : "little");
      const Bytes bytes = test_support::WithExifOrientation(plain, orientation, big_endian);
      const Expected<ImageHeader> header = CheckImageBytes(bytes);
      ASSERT_TRUE(header) << header.error().message;
      EXPECT_EQ(header->orientation, orientation) << what;
      EXPECT_EQ(header->width_px, 40) << what;  // as stored
      const std::filesystem::path path = dir.path() / "photo.jpg";
      Write(path, bytes);
      ImageReadOptions options;
      options.upright = true;
      const Expected<cv::Mat> upright = ReadImageFile(path, options);
      ASSERT_TRUE(upright) << upright.error().message;
      const cv::Mat shown = cv::imdecode(bytes, cv::IMREAD_COLOR);
      ASSERT_EQ(upright->size(), shown.size()) << what;
      EXPECT_EQ(upright->size(), DecodedSize(*header, options)) << what;
      EXPECT_EQ(cv::norm(*upright, shown, cv::NORM_INF), 0.0) << what;
      // Without it, IMREAD_UNCHANGED keeps the pixels as stored (as cv::imread does).
      const Expected<cv::Mat> stored = ReadImageFile(path);
      ASSERT_TRUE(stored) << stored.error().message;
      EXPECT_EQ(stored->size(), cv::Size(40, 24)) << what;
      // A set's size is the size as shown: the stored one is refused, naming the turn.
      options.expected_size = cv::Size(40, 24);
      const Expected<cv::Mat> refused = ReadImageFile(path, options);
      EXPECT_EQ(refused.has_value(), orientation < 5) << what;
      if (!refused) {
        EXPECT_THAT(refused.error().message, HasSubstr("turned by its EXIF")) << what;
      }
    }
  }
}

// What a viewer ignores is upright: an orientation out of range, an EXIF block that cannot be
// read, one without the tag; only the first EXIF block counts, and an XMP block before it is
// passed over.
TEST(ImageHeader, ExifOrientationOnlyFromTheFirstReadableExifBlock) {
  const Bytes plain = EncodeImage(".jpg", TexturedPicture(40, 24));
  EXPECT_EQ(CheckImageBytes(plain)->orientation, 1);
  EXPECT_EQ(CheckImageBytes(test_support::WithExifOrientation(plain, 9))->orientation, 1);
  EXPECT_EQ(CheckImageBytes(test_support::WithExifOrientation(plain, 0))->orientation, 1);
  Bytes unreadable = test_support::WithExifOrientation(plain, 6);
  unreadable[2 + 4 + 6 + 4] = 0xF0;  // IFD0's offset far past the block
  EXPECT_EQ(CheckImageBytes(unreadable)->orientation, 1);
  // Two EXIF blocks: the first one's orientation.
  const Bytes twice =
      test_support::WithExifOrientation(test_support::WithExifOrientation(plain, 3), 8);
  EXPECT_EQ(CheckImageBytes(twice)->orientation, 8);
  // An XMP block first.
  const std::string xmp = "http://ns.adobe.com/xap/1.0/";
  Bytes with_xmp = test_support::WithExifOrientation(plain, 6);
  Bytes segment = {0xFF, 0xE1, 0, static_cast<std::uint8_t>(2 + xmp.size() + 1)};
  segment.insert(segment.end(), xmp.begin(), xmp.end());
  segment.push_back(0);
  with_xmp.insert(with_xmp.begin() + 2, segment.begin(), segment.end());
  EXPECT_EQ(CheckImageBytes(with_xmp)->orientation, 6);
  // Other formats have none.
  EXPECT_EQ(CheckImageBytes(EncodeImage(".png", TexturedPicture(40, 24)))->orientation, 1);
}

// An RLE8 bitmap cut before its end-of-bitmap mark.
TEST(ImageHeaderRle, ABmpWhoseRunLengthDataIsCutShortIsRefused) {
  Bytes bmp(54 + 1024, 0);
  bmp[0] = 'B';
  bmp[1] = 'M';
  const auto put32 = [&](std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) bmp[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
  };
  put32(10, 54 + 1024);  // pixels after a 256-colour palette
  put32(14, 40);
  put32(18, 16);  // width
  put32(22, 4);   // height
  bmp[26] = 1;    // planes
  bmp[28] = 8;    // bits
  put32(30, 1);   // RLE8
  for (int row = 0; row < 4; ++row) {
    for (std::uint8_t b : {16, 3, 0, 0}) bmp.push_back(b);  // 16 pixels of colour 3, end of line
  }
  Bytes whole = bmp;
  whole.push_back(0);
  whole.push_back(1);  // end of bitmap
  EXPECT_TRUE(CheckImageBytes(whole));
  const Expected<ImageHeader> cut = CheckImageBytes(bmp);
  ASSERT_FALSE(cut);
  EXPECT_THAT(cut.error().message, HasSubstr("end-of-bitmap"));
}

}  // namespace
}  // namespace revolve
