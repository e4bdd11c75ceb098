// 8-bit images as PNG, on every core (base/png_encode.h).
//
// A PNG's pixels are one zlib stream, which one deflate call makes on one thread. Here the rows
// are cut into bands of a fixed number of rows, as pigz cuts a file: each band is filtered and
// deflated on its own (raw deflate blocks ended by a full flush, so it stops on a byte boundary
// without a final block; the last band finishes the stream), and each becomes one IDAT chunk; the
// zlib header leads the first and the Adler-32 of all the filtered bytes (combined from the
// bands') ends the last. The cut depends on the image only, so the bytes are the same whatever
// the number of threads. Paeth filtering of every row, and ISA-L's igzip at its level 1 (Intel's
// deflate, on vectors where the processor has them): on a textured atlas it is 4x as fast as
// zlib's fastest (level 1 with run-length matching, what this used before) for a file 15 %
// larger (docs/performance.md, the thirteenth pass). ISA-L picks its code by the processor, so the
// bytes may differ between machines; the pixels never do.
#include <isa-l/igzip_lib.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <limits>

#include <fmt/format.h>

#include <tbb/parallel_for.h>

#include "base/atomic_file.h"
#include "base/png_encode.h"

namespace revolve {
namespace {

constexpr int kBandRows = 32;
constexpr int kPaethFilter = 4;

void PutBigEndian32(std::uint32_t value, char* out) {
  out[0] = static_cast<char>(value >> 24);
  out[1] = static_cast<char>(value >> 16);
  out[2] = static_cast<char>(value >> 8);
  out[3] = static_cast<char>(value);
}

// zlib's CRC-32 of `bytes` continued from `crc` (with none, crc itself: zlib would return its
// initial value for a null pointer).
std::uint32_t Crc(std::uint32_t crc, const char* bytes, std::size_t size) {
  if (size == 0) return crc;
  return static_cast<std::uint32_t>(
      crc32_z(crc, reinterpret_cast<const Bytef*>(bytes), static_cast<z_size_t>(size)));
}

// A chunk: length, type, data, CRC of type and data.
void AppendChunk(std::string* png, const char (&type)[5], std::string_view data) {
  char head[8];
  PutBigEndian32(static_cast<std::uint32_t>(data.size()), head);
  std::memcpy(head + 4, type, 4);
  std::uint32_t crc = Crc(crc32_z(0, nullptr, 0), head + 4, 4);
  crc = Crc(crc, data.data(), data.size());
  char tail[4];
  PutBigEndian32(crc, tail);
  png->append(head, 8);
  png->append(data);
  png->append(tail, 4);
}

// How a row of the image becomes a PNG row: BGR as RGB, grey as it is, or a binary grey image
// (only 0 and 255) packed one bit a pixel, the first pixel in the top bit (255: 1).
enum class RowKind { kBgr, kGrey, kBits };

// The PNG row of image row `row` (width pixels) at `raw`: RowBytes(kind, width) bytes.
std::size_t RowBytes(RowKind kind, int width) {
  const auto w = static_cast<std::size_t>(width);
  return kind == RowKind::kBgr ? 3 * w : kind == RowKind::kGrey ? w : (w + 7) / 8;
}

// Eight bytes as a little-endian word (the pixel at `p` in the low byte).
std::uint64_t Word(const std::uint8_t* p) {
  std::uint64_t w = 0;
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(&w, p, sizeof(w));
  } else {
    for (int k = 7; k >= 0; --k) w = (w << 8) | p[k];
  }
  return w;
}

// Eight pixels of a binary row as one byte, the first in the top bit: each byte's top bit
// gathered into the word's top byte by one multiplication (pixel k's to bit 56 + k: the partial
// products fall on distinct bits, so nothing carries), then that byte's bits reversed.
std::uint8_t PackEight(const std::uint8_t* p) {
  static constexpr std::array<std::uint8_t, 256> kReversed = [] {
    std::array<std::uint8_t, 256> table{};
    for (int v = 0; v < 256; ++v) {
      int r = 0;
      for (int bit = 0; bit < 8; ++bit) r |= ((v >> bit) & 1) << (7 - bit);
      table[static_cast<std::size_t>(v)] = static_cast<std::uint8_t>(r);
    }
    return table;
  }();
  const std::uint64_t tops = Word(p) & 0x8080808080808080ULL;
  return kReversed[(tops * 0x0002040810204081ULL) >> 56];
}

void RawRow(RowKind kind, const std::uint8_t* row, int width, std::uint8_t* raw) {
  if (kind == RowKind::kBgr) {
    for (std::ptrdiff_t x = 0; x < width; ++x) {
      raw[3 * x] = row[3 * x + 2];
      raw[3 * x + 1] = row[3 * x + 1];
      raw[3 * x + 2] = row[3 * x];
    }
  } else if (kind == RowKind::kGrey) {
    std::memcpy(raw, row, static_cast<std::size_t>(width));
  } else {
    const int whole = width / 8;
    for (std::ptrdiff_t b = 0; b < whole; ++b) raw[b] = PackEight(row + 8 * b);
    if (whole * 8 < width) {
      std::uint8_t last = 0;
      for (int x = whole * 8; x < width; ++x) {
        last |= static_cast<std::uint8_t>(row[x] & (0x80 >> (x % 8)));
      }
      raw[whole] = last;
    }
  }
}

// One PNG row `raw` (`bytes` bytes, `bpp` bytes a pixel, at least 1) as its filter byte and
// Paeth differences at `out` (1 + bytes); `prior` is the PNG row above (zeros above the first).
// Vectorised; built for AVX2 too where the processor has it (twice as wide, the same bytes).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(REVOLVE_PORTABLE)
[[gnu::target_clones("avx2", "default")]]
#endif
void FilterRow(const std::uint8_t* raw, std::size_t bytes, int bpp, const std::uint8_t* prior,
               std::uint8_t* out) {
  out[0] = kPaethFilter;
  ++out;
  const auto first = std::min(bytes, static_cast<std::size_t>(bpp));
  // The first pixel: no left neighbour (a = c = 0), so Paeth predicts b.
  for (std::size_t i = 0; i < first; ++i) out[i] = static_cast<std::uint8_t>(raw[i] - prior[i]);
  for (std::size_t i = first; i < bytes; ++i) {
    const int a = raw[i - bpp], b = prior[i], c = prior[i - bpp];
    const int pa = std::abs(b - c);          // |p - a| with p = a + b - c
    const int pb = std::abs(a - c);          // |p - b|
    const int pc = std::abs(a + b - c - c);  // |p - c|
    const int predicted = (pa <= pb && pa <= pc) ? a : (pb <= pc ? b : c);
    out[i] = static_cast<std::uint8_t>(raw[i] - predicted);
  }
}

// Whether every pixel of the grey `image` is 0 or 255, eight at a time: a byte is 0 or 255 iff
// it equals its top bit spread over the byte.
bool IsBinary(const cv::Mat& image) {
  for (int y = 0; y < image.rows; ++y) {
    const std::uint8_t* row = image.ptr<std::uint8_t>(y);
    std::uint64_t off = 0;
    int x = 0;
    for (; x + 8 <= image.cols; x += 8) {
      const std::uint64_t w = Word(row + x);
      off |= w ^ (((w >> 7) & 0x0101010101010101ULL) * 0xff);
    }
    for (; x < image.cols; ++x) off |= static_cast<std::uint8_t>(row[x] + 1) > 1 ? 1 : 0;
    if (off != 0) return false;
  }
  return true;
}

// A band's compressed bytes and the Adler-32 of its filtered bytes.
struct Band {
  std::string deflated;
  std::uint32_t adler = 1;
  std::size_t filtered_size = 0;
  bool ok = false;
};

Band EncodeBand(const cv::Mat& image, RowKind kind, int first_row, int rows, bool last) {
  Band band;
  const std::size_t row_bytes = RowBytes(kind, image.cols);
  const int bpp = kind == RowKind::kBgr ? 3 : 1;
  std::vector<std::uint8_t> raw(2 * row_bytes, 0);
  std::uint8_t* prior = raw.data();
  std::uint8_t* current = raw.data() + row_bytes;
  std::vector<std::uint8_t> filtered(static_cast<std::size_t>(rows) * (row_bytes + 1));
  // The row above (Paeth reads it).
  if (first_row > 0) RawRow(kind, image.ptr<std::uint8_t>(first_row - 1), image.cols, prior);
  for (int r = 0; r < rows; ++r) {
    RawRow(kind, image.ptr<std::uint8_t>(first_row + r), image.cols, current);
    FilterRow(current, row_bytes, bpp, prior, filtered.data() + r * (row_bytes + 1));
    std::swap(prior, current);
  }
  band.filtered_size = filtered.size();
  band.adler = isal_adler32(1, filtered.data(), filtered.size());
  // ISA-L's level 1, in one call: the band as deflate blocks ended on a byte boundary (a full
  // flush: an empty stored block, no history carried over) or, for the last band, by the final
  // block. Its level buffer is the thread's, kept from band to band.
  thread_local std::vector<std::uint8_t> level_buffer(ISAL_DEF_LVL1_DEFAULT);
  isal_zstream stream;
  isal_deflate_stateless_init(&stream);
  stream.level = 1;
  stream.level_buf = level_buffer.data();
  stream.level_buf_size = static_cast<std::uint32_t>(level_buffer.size());
  stream.flush = FULL_FLUSH;
  stream.end_of_stream = last ? 1 : 0;
  stream.gzip_flag = IGZIP_DEFLATE;
  // At worst stored blocks: 5 bytes of header per 64 KiB, and the flush's empty block.
  band.deflated.resize(filtered.size() + 5 * (filtered.size() / 65535 + 2) + 64);
  stream.next_in = filtered.data();
  stream.avail_in = static_cast<std::uint32_t>(filtered.size());
  stream.next_out = reinterpret_cast<std::uint8_t*>(band.deflated.data());
  stream.avail_out = static_cast<std::uint32_t>(band.deflated.size());
  band.ok = isal_deflate_stateless(&stream) == COMP_OK && stream.avail_in == 0;
  band.deflated.resize(stream.total_out);
  return band;
}

}  // namespace

Expected<std::string> EncodePng(const cv::Mat& image) {
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 3 && image.channels() != 1)) {
    return MakeError(ErrorCode::kInternal,
                     "cannot encode the image as PNG: it is not an 8-bit BGR or grey image");
  }
  const RowKind kind = image.channels() == 3 ? RowKind::kBgr
                       : IsBinary(image)     ? RowKind::kBits
                                             : RowKind::kGrey;
  const std::size_t row_bytes = RowBytes(kind, image.cols) + 1;
  if (row_bytes * kBandRows > std::numeric_limits<uInt>::max() / 2) {
    return MakeError(
        ErrorCode::kInternal,
        fmt::format("cannot encode the image as PNG: {}x{} is too large", image.cols, image.rows));
  }
  const int bands = (image.rows + kBandRows - 1) / kBandRows;
  std::vector<Band> encoded(static_cast<std::size_t>(bands));
  tbb::parallel_for(std::size_t{0}, encoded.size(), [&](std::size_t b) {
    const int first = static_cast<int>(b) * kBandRows;
    encoded[b] = EncodeBand(image, kind, first, std::min(kBandRows, image.rows - first),
                            static_cast<int>(b) == bands - 1);
  });
  std::uint32_t adler = static_cast<std::uint32_t>(adler32_z(0, nullptr, 0));
  std::size_t size = 8 + 25 + 12;
  for (const Band& band : encoded) {
    if (!band.ok)
      return MakeError(ErrorCode::kInternal, "cannot encode the image as PNG: deflate failed");
    adler = static_cast<std::uint32_t>(
        adler32_combine(adler, band.adler, static_cast<z_off_t>(band.filtered_size)));
    size += band.deflated.size() + 12;
  }
  std::string png;
  png.reserve(size + 6);
  png.append("\x89PNG\r\n\x1a\n", 8);
  char header[13];
  PutBigEndian32(static_cast<std::uint32_t>(image.cols), header);
  PutBigEndian32(static_cast<std::uint32_t>(image.rows), header + 4);
  header[8] = kind == RowKind::kBits ? 1 : 8;  // bits per channel
  header[9] = image.channels() == 3 ? 2 : 0;   // truecolour or grey
  header[10] = header[11] = header[12] = 0;    // deflate, adaptive filtering, no interlace
  AppendChunk(&png, "IHDR", std::string_view(header, sizeof(header)));
  // zlib's header: deflate with a 32 KiB window, level "fastest" (FCHECK makes it a multiple of
  // 31).
  constexpr std::array<char, 2> kZlibHeader = {0x78, 0x01};
  encoded.front().deflated.insert(0, kZlibHeader.data(), kZlibHeader.size());
  char trailer[4];
  PutBigEndian32(adler, trailer);
  encoded.back().deflated.append(trailer, 4);
  for (const Band& band : encoded) AppendChunk(&png, "IDAT", band.deflated);
  AppendChunk(&png, "IEND", {});
  return png;
}

Expected<void> WritePngFile(const std::filesystem::path& path, const cv::Mat& image) {
  Expected<std::string> png = EncodePng(image);
  if (!png) {
    return MakeError(png.error().code, fmt::format("{}: {}", path.string(), png.error().message));
  }
  return WriteFileAtomically(path, *png);
}

}  // namespace revolve
