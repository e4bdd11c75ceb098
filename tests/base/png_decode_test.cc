// Issue 18: the plain PNGs decoded without libpng (base/png_decode.h) give OpenCV's pixels, for
// every row filter, one and three channels, odd widths, image data split over chunks and skipped
// ancillary chunks between them; and anything amiss is left to libpng, which still refuses it.
#include "base/png_decode.h"

#include <zlib.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "base/image_verify.h"

namespace revolve {
namespace {

using Bytes = std::vector<std::uint8_t>;

void Put32(Bytes* out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<std::uint8_t>(v >> (24 - 8 * i)));
}

void Chunk(Bytes* out, const std::string& type, const Bytes& data) {
  Put32(out, static_cast<std::uint32_t>(data.size()));
  const std::size_t start = out->size();
  out->insert(out->end(), type.begin(), type.end());
  out->insert(out->end(), data.begin(), data.end());
  Put32(out, static_cast<std::uint32_t>(crc32(0L, out->data() + start, 4 + data.size())));
}

int PaethOf(int a, int b, int c) {
  const int p = a + b - c;
  const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return pa <= pb && pa <= pc ? a : (pb <= pc ? b : c);
}

// How a plain PNG is made (and, for the refused cases, damaged).
struct Plan {
  int channels = 1;       // 1 grey, 3 RGB
  int filter = -1;        // every row's filter, or -1: row y takes y % 5
  int parts = 1;          // IDAT chunks
  bool ancillary = true;  // gAMA before the data, tEXt after it
  std::uint8_t depth = 8, colour = 0, interlace = 0;  // IHDR as written (colour 0 or 2 by channels)
};

// `pixels` (rows of width * channels bytes, RGB order) as a PNG.
Bytes MakePng(const std::vector<Bytes>& rows, int width, const Plan& plan) {
  const std::size_t row_bytes = static_cast<std::size_t>(width * plan.channels);
  Bytes raw;
  const Bytes zeros(row_bytes, 0);
  for (std::size_t y = 0; y < rows.size(); ++y) {
    const Bytes& x = rows[y];
    const Bytes& above = y == 0 ? zeros : rows[y - 1];
    const int filter = plan.filter >= 0 ? plan.filter : static_cast<int>(y % 5);
    raw.push_back(static_cast<std::uint8_t>(filter));
    for (std::size_t i = 0; i < row_bytes; ++i) {
      const std::size_t bpp = static_cast<std::size_t>(plan.channels);
      const int a = i >= bpp ? x[i - bpp] : 0;
      const int b = above[i];
      const int c = i >= bpp ? above[i - bpp] : 0;
      const int predicted = filter == 1   ? a
                            : filter == 2 ? b
                            : filter == 3 ? (a + b) / 2
                            : filter == 4 ? PaethOf(a, b, c)
                                          : 0;
      raw.push_back(static_cast<std::uint8_t>(x[i] - predicted));
    }
  }
  uLongf size = compressBound(raw.size());
  Bytes stream(size);
  EXPECT_EQ(compress2(stream.data(), &size, raw.data(), raw.size(), 6), Z_OK);
  stream.resize(size);
  Bytes png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  Bytes ihdr;
  Put32(&ihdr, static_cast<std::uint32_t>(width));
  Put32(&ihdr, static_cast<std::uint32_t>(rows.size()));
  ihdr.insert(ihdr.end(), {plan.depth, plan.colour, 0, 0, plan.interlace});
  Chunk(&png, "IHDR", ihdr);
  if (plan.ancillary) Chunk(&png, "gAMA", {0, 0, 0xb1, 0x8f});
  const std::size_t part = stream.size() / static_cast<std::size_t>(plan.parts) + 1;
  for (std::size_t at = 0; at < stream.size(); at += part) {
    Chunk(&png, "IDAT",
          Bytes(stream.begin() + static_cast<std::ptrdiff_t>(at),
                stream.begin() + static_cast<std::ptrdiff_t>(std::min(stream.size(), at + part))));
  }
  if (plan.ancillary) Chunk(&png, "tEXt", {'a', 0, 'b'});
  Chunk(&png, "IEND", {});
  return png;
}

std::vector<Bytes> RandomRows(int width, int height, int channels, std::uint32_t seed) {
  std::mt19937 random(seed);
  std::vector<Bytes> rows(static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) {
    for (int i = 0; i < width * channels; ++i) {
      // Runs and noise: long equal stretches (a silhouette's) and every byte value.
      rows[static_cast<std::size_t>(y)].push_back(
          static_cast<std::uint8_t>((i / 7) % 3 == 0 ? 255 : random() % 256));
    }
  }
  return rows;
}

TEST(DecodePlainPng, EveryFilterGivesOpenCvsPixels) {
  int compared = 0;
  for (const int channels : {1, 3}) {
    for (const int width : {1, 2, 3, 5, 16, 17, 720}) {
      for (const int filter : {-1, 0, 1, 2, 3, 4}) {
        Plan plan;
        plan.channels = channels;
        plan.colour = channels == 1 ? 0 : 2;
        plan.filter = filter;
        plan.parts = 1 + (width % 3);
        plan.ancillary = width % 2 == 1;
        const Bytes png =
            MakePng(RandomRows(width, 9, channels, 7u * width + filter + 9), width, plan);
        for (const int flags : {cv::IMREAD_UNCHANGED, cv::IMREAD_COLOR, cv::IMREAD_GRAYSCALE}) {
          const std::string what = std::to_string(channels) + " channels, width " +
                                   std::to_string(width) + ", filter " + std::to_string(filter) +
                                   ", flags " + std::to_string(flags);
          const std::optional<cv::Mat> mine = DecodePlainPng(png, flags);
          if (channels == 3 && flags == cv::IMREAD_GRAYSCALE) {
            EXPECT_FALSE(mine) << what;  // OpenCV's own conversion
            continue;
          }
          ASSERT_TRUE(mine) << what;
          const cv::Mat expected = cv::imdecode(png, flags);
          ASSERT_EQ(mine->type(), expected.type()) << what;
          ASSERT_EQ(mine->size(), expected.size()) << what;
          EXPECT_EQ(cv::norm(*mine, expected, cv::NORM_INF), 0.0) << what;
          ++compared;
        }
      }
    }
  }
  EXPECT_EQ(compared, 2 * 7 * 6 * 3 - 7 * 6);
}

// Each damage or unusual kind: not decoded here; libpng decides, and refuses the damage.
TEST(DecodePlainPng, AnythingAmissIsLeftToLibpng) {
  const std::vector<Bytes> rows = RandomRows(33, 12, 1, 3);
  const Bytes good = MakePng(rows, 33, Plan{});
  ASSERT_TRUE(DecodePlainPng(good, cv::IMREAD_UNCHANGED));
  // The first IDAT chunk's data offset and length.
  std::size_t idat = 8;
  while (std::string(good.begin() + static_cast<std::ptrdiff_t>(idat + 4),
                     good.begin() + static_cast<std::ptrdiff_t>(idat + 8)) != "IDAT") {
    idat +=
        12 + ((good[idat] << 24) | (good[idat + 1] << 16) | (good[idat + 2] << 8) | good[idat + 3]);
  }
  struct Case {
    std::string name;
    Bytes png;
    bool libpng_refuses;
  };
  std::vector<Case> cases;
  Bytes crc = good;
  crc[idat + 8] ^= 1;  // the zlib header, under the chunk's CRC
  cases.push_back({"a chunk's CRC", crc, true});
  Bytes text_crc = good;
  text_crc[text_crc.size() - 12 - 3 - 1] ^= 1;  // tEXt's data, before IEND
  cases.push_back({"an ancillary chunk's CRC", text_crc, true});
  {
    // Row 0's filter byte set to 5: the stream made again around it.
    Bytes raw;
    for (const Bytes& row : rows) {
      raw.push_back(raw.empty() ? 5 : 0);
      raw.insert(raw.end(), row.begin(), row.end());
    }
    uLongf size = compressBound(raw.size());
    Bytes stream(size);
    compress2(stream.data(), &size, raw.data(), raw.size(), 6);
    stream.resize(size);
    Bytes png(good.begin(), good.begin() + 8 + 25);
    Chunk(&png, "IDAT", stream);
    Chunk(&png, "IEND", {});
    cases.push_back({"filter type 5", png, true});
  }
  {
    // The IHDR says 12 rows, the data holds 11.
    Bytes short_rows = MakePng(std::vector<Bytes>(rows.begin(), rows.begin() + 11), 33, Plan{});
    short_rows[8 + 8 + 7] = 12;  // height's low byte
    const auto c = static_cast<std::uint32_t>(crc32(0L, &short_rows[8 + 4], 17));
    for (int i = 0; i < 4; ++i)
      short_rows[8 + 21 + i] = static_cast<std::uint8_t>(c >> (24 - 8 * i));
    cases.push_back({"rows missing", short_rows, true});
  }
  Bytes after = good;
  after.push_back(0);
  cases.push_back({"a byte after IEND", after, false});
  Plan split;
  split.parts = 2;
  split.ancillary = false;
  {
    Bytes two = MakePng(rows, 33, split);
    // tEXt between the two IDAT chunks.
    std::size_t second = 8 + 25;
    second += 12 + ((two[second] << 24) | (two[second + 1] << 16) | (two[second + 2] << 8) |
                    two[second + 3]);
    Bytes text;
    Chunk(&text, "tEXt", {'a', 0, 'b'});
    two.insert(two.begin() + static_cast<std::ptrdiff_t>(second), text.begin(), text.end());
    cases.push_back({"image data split by a text chunk", two, true});
  }
  for (const std::string& type : {std::string("tRNS"), std::string("prVt")}) {
    Bytes extra(good.begin(), good.begin() + 8 + 25);
    Chunk(&extra, type, {0, 1});
    extra.insert(extra.end(), good.begin() + 8 + 25, good.end());
    cases.push_back({type + " chunk", extra, false});
  }
  {
    // A 512-byte window declared (zlib's header): libpng holds the stream to it, so it decides.
    Bytes raw;
    for (const Bytes& row : rows) {
      raw.push_back(0);
      raw.insert(raw.end(), row.begin(), row.end());
    }
    z_stream z{};
    EXPECT_EQ(deflateInit2(&z, 6, Z_DEFLATED, 9, 8, Z_DEFAULT_STRATEGY), Z_OK);
    Bytes stream(deflateBound(&z, raw.size()));
    z.next_in = raw.data();
    z.avail_in = static_cast<uInt>(raw.size());
    z.next_out = stream.data();
    z.avail_out = static_cast<uInt>(stream.size());
    EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
    stream.resize(z.total_out);
    deflateEnd(&z);
    ASSERT_EQ(stream[0] >> 4, 1);
    Bytes png(good.begin(), good.begin() + 8 + 25);
    Chunk(&png, "IDAT", stream);
    Chunk(&png, "IEND", {});
    cases.push_back({"a small window", png, false});
    EXPECT_TRUE(DecodeVerifiedPng(png, cv::IMREAD_UNCHANGED).value_or(cv::Mat()).has_value());
  }
  Plan sixteen;
  sixteen.depth = 16;
  cases.push_back({"16 bits", MakePng(rows, 33, sixteen), false});
  Plan interlaced;
  interlaced.interlace = 1;
  cases.push_back({"interlaced", MakePng(rows, 33, interlaced), true});
  Plan palette;
  palette.colour = 3;
  cases.push_back({"palette", MakePng(rows, 33, palette), true});
  for (const Case& c : cases) {
    EXPECT_FALSE(DecodePlainPng(c.png, cv::IMREAD_UNCHANGED)) << c.name;
    if (c.libpng_refuses) {
      const std::optional<Expected<cv::Mat>> verified =
          DecodeVerifiedPng(c.png, cv::IMREAD_UNCHANGED);
      EXPECT_TRUE(!verified || !*verified) << c.name << ": libpng decoded it";
    }
  }
}

}  // namespace
}  // namespace revolve
