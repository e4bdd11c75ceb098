#include "base/png_decode.h"

#include <libdeflate.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <memory>
#include <string_view>
#include <vector>

#include <opencv2/imgcodecs.hpp>  // the IMREAD_ flags only
#include <opencv2/imgproc.hpp>

namespace revolve {
namespace {

constexpr std::array<std::uint8_t, 8> kSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
// libpng's default limits: a side at most this (png_set_user_limits), a chunk other than IDAT at
// most this long (png_set_chunk_malloc_max).
constexpr std::uint32_t kMaxSide = 1000000;
constexpr std::uint32_t kMaxChunk = 8000000;
// A chunk's length is at most 2^31 - 1 (the PNG specification).
constexpr std::uint32_t kMaxLength = 0x7fffffff;
// Larger images (their rows inflated at once here) are left to libpng, row by row.
constexpr std::size_t kMaxRawBytes = std::size_t{1} << 30;
// Ancillary chunks libpng skips unread in the verified decode (image_verify.cc, kPngSkipped):
// no pixel depends on them. eXIf is not here (OpenCV may turn the picture).
constexpr std::array<std::string_view, 17> kSkipped = {
    "bKGD", "cHRM", "gAMA", "hIST", "iCCP", "iTXt", "oFFs", "pCAL", "pHYs",
    "sBIT", "sCAL", "sPLT", "sRGB", "sTER", "tEXt", "tIME", "zTXt"};

std::uint32_t BigEndian32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         p[3];
}

struct DecompressorDeleter {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

// The PNG predictor of a, b, c.
[[gnu::always_inline]] inline std::uint8_t Paeth(int a, int b, int c) {
  const int p = a + b - c;
  const int pa = std::abs(p - a);
  const int pb = std::abs(p - b);
  const int pc = std::abs(p - c);
  if (pa <= pb && pa <= pc) return static_cast<std::uint8_t>(a);
  return static_cast<std::uint8_t>(pb <= pc ? b : c);
}

// One row of `Bpp` bytes a pixel unfiltered from `in` into `out`, `prior` the row above (zeros
// for the first). The left neighbours are carried in registers, not read back from `out` (a
// load waiting on the store before it: libpng's loop for one byte a pixel).
template <int Bpp>
bool Unfilter(int filter, const std::uint8_t* in, const std::uint8_t* prior, std::uint8_t* out,
              std::size_t bytes) {
  std::array<std::uint8_t, Bpp> a{};  // left
  std::array<std::uint8_t, Bpp> c{};  // above left
  switch (filter) {
    case 0:
      std::memcpy(out, in, bytes);
      return true;
    case 1:
      for (std::size_t i = 0; i < bytes; i += Bpp) {
        for (int k = 0; k < Bpp; ++k)
          out[i + k] = a[k] = static_cast<std::uint8_t>(in[i + k] + a[k]);
      }
      return true;
    case 2:
      for (std::size_t i = 0; i < bytes; ++i) out[i] = static_cast<std::uint8_t>(in[i] + prior[i]);
      return true;
    case 3:
      for (std::size_t i = 0; i < bytes; i += Bpp) {
        for (int k = 0; k < Bpp; ++k) {
          out[i + k] = a[k] = static_cast<std::uint8_t>(in[i + k] + ((a[k] + prior[i + k]) >> 1));
        }
      }
      return true;
    case 4:
      for (std::size_t i = 0; i < bytes; i += Bpp) {
        for (int k = 0; k < Bpp; ++k) {
          const std::uint8_t b = prior[i + k];
          out[i + k] = a[k] = static_cast<std::uint8_t>(in[i + k] + Paeth(a[k], b, c[k]));
          c[k] = b;
        }
      }
      return true;
    default:
      return false;
  }
}

struct Header {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  int channels = 0;
};

// IHDR's 13 bytes, when they describe a plain image.
std::optional<Header> PlainHeader(const std::uint8_t* d) {
  Header h;
  h.width = BigEndian32(d);
  h.height = BigEndian32(d + 4);
  const std::uint8_t depth = d[8];
  const std::uint8_t colour = d[9];
  if (h.width == 0 || h.height == 0 || h.width > kMaxSide || h.height > kMaxSide || depth != 8 ||
      (colour != 0 && colour != 2) || d[10] != 0 || d[11] != 0 || d[12] != 0) {
    return std::nullopt;
  }
  h.channels = colour == 0 ? 1 : 3;
  return h;
}

}  // namespace

std::optional<cv::Mat> DecodePlainPng(std::span<const std::uint8_t> bytes, int imread_flags) {
  if (imread_flags != cv::IMREAD_UNCHANGED && imread_flags != cv::IMREAD_COLOR &&
      imread_flags != cv::IMREAD_GRAYSCALE) {
    return std::nullopt;
  }
  if (bytes.size() < kSignature.size() ||
      !std::equal(kSignature.begin(), kSignature.end(), bytes.begin())) {
    return std::nullopt;
  }
  std::optional<Header> header;
  std::vector<std::span<const std::uint8_t>> idat;
  bool idat_ended = false;
  bool ended = false;
  std::size_t raw_size = 0;
  std::size_t idat_limit = 0;
  for (std::size_t at = kSignature.size(); !ended;) {
    if (bytes.size() - at < 12) return std::nullopt;
    const std::uint32_t length = BigEndian32(&bytes[at]);
    if (length > kMaxLength || length > bytes.size() - at - 12) return std::nullopt;
    const std::string_view type(reinterpret_cast<const char*>(&bytes[at + 4]), 4);
    const std::uint8_t* data = &bytes[at + 8];
    if (libdeflate_crc32(0, &bytes[at + 4], length + 4) != BigEndian32(data + length)) {
      return std::nullopt;
    }
    if (!header) {
      if (type != "IHDR" || length != 13) return std::nullopt;
      header = PlainHeader(data);
      if (!header) return std::nullopt;
      const std::size_t row_factor =
          std::size_t{header->width} * static_cast<std::size_t>(header->channels) + 1;
      raw_size = row_factor * header->height;
      if (raw_size > kMaxRawBytes) return std::nullopt;
      // libpng's bound on an IDAT chunk (png_check_chunk_length): the rows stored, with the
      // overhead of the smallest deflate blocks.
      idat_limit = std::min<std::size_t>(
          kMaxLength, raw_size + 6 + 5 * (raw_size / std::min<std::size_t>(row_factor, 32566) + 1));
    } else if (type == "IDAT") {
      if (idat_ended || length > idat_limit) return std::nullopt;
      idat.emplace_back(data, length);
    } else if (type == "IEND") {
      if (length != 0 || at + 12 != bytes.size()) return std::nullopt;
      ended = true;
    } else if (std::find(kSkipped.begin(), kSkipped.end(), type) != kSkipped.end() &&
               length <= kMaxChunk) {
      idat_ended = !idat.empty();
    } else {
      return std::nullopt;
    }
    at += 12 + std::size_t{length};
  }
  if (idat.empty()) return std::nullopt;
  // A 32 KB window declared (CINFO 7, what zlib writes for all but tiny data): libpng holds a
  // stream to the window its header declares, libdeflate always allows 32 KB back.
  if (idat.front().empty() || (idat.front()[0] >> 4) != 7) return std::nullopt;
  // RGB read as grey: OpenCV's own conversion.
  if (header->channels == 3 && imread_flags == cv::IMREAD_GRAYSCALE) return std::nullopt;
  // The zlib stream whole (one chunk: in place).
  std::vector<std::uint8_t> joined;
  std::span<const std::uint8_t> stream = idat.front();
  if (idat.size() > 1) {
    for (const std::span<const std::uint8_t> part : idat) {
      joined.insert(joined.end(), part.begin(), part.end());
    }
    stream = joined;
  }
  thread_local const std::unique_ptr<libdeflate_decompressor, DecompressorDeleter> decompressor(
      libdeflate_alloc_decompressor());
  if (!decompressor) return std::nullopt;
  std::vector<std::uint8_t> raw(raw_size);
  std::size_t used = 0;
  // Exactly the rows (no actual_out: a shorter stream fails), and nothing after the stream.
  if (libdeflate_zlib_decompress_ex(decompressor.get(), stream.data(), stream.size(), raw.data(),
                                    raw.size(), &used, nullptr) != LIBDEFLATE_SUCCESS ||
      used != stream.size()) {
    return std::nullopt;
  }
  const int channels = header->channels;
  const auto width = static_cast<int>(header->width);
  const auto height = static_cast<int>(header->height);
  cv::Mat image(height, width, channels == 1 ? CV_8UC1 : CV_8UC3);
  const std::size_t row_bytes = std::size_t{header->width} * static_cast<std::size_t>(channels);
  const std::vector<std::uint8_t> zeros(row_bytes, 0);
  const std::uint8_t* prior = zeros.data();
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* in = raw.data() + static_cast<std::size_t>(y) * (row_bytes + 1);
    std::uint8_t* out = image.ptr<std::uint8_t>(y);
    const bool ok = channels == 1 ? Unfilter<1>(in[0], in + 1, prior, out, row_bytes)
                                  : Unfilter<3>(in[0], in + 1, prior, out, row_bytes);
    if (!ok) return std::nullopt;
    prior = out;
  }
  if (channels == 3) {
    cv::cvtColor(image, image, cv::COLOR_RGB2BGR);
  } else if (imread_flags == cv::IMREAD_COLOR) {
    cv::cvtColor(image, image, cv::COLOR_GRAY2BGR);
  }
  return image;
}

}  // namespace revolve
