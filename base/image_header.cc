#include "base/image_header.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace revolve {
namespace {

using Bytes = std::span<const std::uint8_t>;

std::unexpected<Error> Bad(ImageFormat format, std::string_view what) {
  return MakeError(ErrorCode::kBadInput, fmt::format("{}: {}", ToString(format), what));
}

std::uint32_t Be32(Bytes b, std::size_t at) {
  return (std::uint32_t{b[at]} << 24) | (std::uint32_t{b[at + 1]} << 16) |
         (std::uint32_t{b[at + 2]} << 8) | std::uint32_t{b[at + 3]};
}
std::uint16_t Be16(Bytes b, std::size_t at) {
  return static_cast<std::uint16_t>((b[at] << 8) | b[at + 1]);
}
std::uint32_t Le32(Bytes b, std::size_t at) {
  return std::uint32_t{b[at]} | (std::uint32_t{b[at + 1]} << 8) | (std::uint32_t{b[at + 2]} << 16) |
         (std::uint32_t{b[at + 3]} << 24);
}
std::uint16_t Le16(Bytes b, std::size_t at) {
  return static_cast<std::uint16_t>(b[at] | (b[at + 1] << 8));
}

Expected<ImageHeader> CheckSize(ImageHeader header) {
  if (header.width_px < 1 || header.height_px < 1) {
    return Bad(header.format, fmt::format("the header gives a size of {} x {}", header.width_px,
                                          header.height_px));
  }
  return header;
}

// ---- PNG --------------------------------------------------------------------------------------

constexpr std::array<std::uint8_t, 8> kPngSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};

Expected<ImageHeader> CheckPng(Bytes b) {
  constexpr ImageFormat f = ImageFormat::kPng;
  ImageHeader header{f, 0, 0, 0};
  std::uint64_t idat_bytes = 0;
  int bit_depth = 0;
  std::size_t at = kPngSignature.size();
  bool first = true;
  while (true) {
    if (at + 12 > b.size()) return Bad(f, "the file is cut short (no IEND chunk)");
    const std::uint32_t length = Be32(b, at);
    if (length > 0x7FFFFFFFu || length > b.size() - at - 12) {
      return Bad(f,
                 fmt::format("the file is cut short (a chunk at byte {} runs past its end)", at));
    }
    const std::string type(reinterpret_cast<const char*>(&b[at + 4]), 4);
    const std::uint32_t stored_crc = Be32(b, at + 8 + length);
    const auto crc = static_cast<std::uint32_t>(
        crc32(0L, reinterpret_cast<const Bytef*>(&b[at + 4]), static_cast<uInt>(length + 4)));
    if (crc != stored_crc) {
      return Bad(f, fmt::format("the {} chunk at byte {} is damaged (CRC mismatch)",
                                std::all_of(type.begin(), type.end(),
                                            [](char c) {
                                              return std::isalpha(static_cast<unsigned char>(c));
                                            })
                                    ? type
                                    : std::string("?"),
                                at));
    }
    const std::size_t data = at + 8;
    if (first) {
      if (type != "IHDR" || length != 13) return Bad(f, "the first chunk is not a valid IHDR");
      header.width_px = Be32(b, data);
      header.height_px = Be32(b, data + 4);
      bit_depth = b[data + 8];
      const int colour = b[data + 9];
      switch (colour) {
        case 0:
          header.channels = 1;
          break;
        case 2:
          header.channels = 3;
          break;
        case 3:
          header.channels = 1;
          break;
        case 4:
          header.channels = 2;
          break;
        case 6:
          header.channels = 4;
          break;
        default:
          return Bad(f, fmt::format("unknown colour type {}", colour));
      }
      if (bit_depth != 1 && bit_depth != 2 && bit_depth != 4 && bit_depth != 8 && bit_depth != 16) {
        return Bad(f, fmt::format("unknown bit depth {}", bit_depth));
      }
      if (header.width_px > 0x7FFFFFFF || header.height_px > 0x7FFFFFFF) {
        return Bad(f, "the header gives a size over 2^31");
      }
      first = false;
    } else if (type == "IDAT") {
      idat_bytes += length;
    } else if (type == "IEND") {
      break;
    }
    at = data + length + 4;
  }
  if (auto sized = CheckSize(header); !sized) return sized;
  // Deflate cannot shrink data by more than about 1032:1.
  const std::uint64_t row_bytes =
      (static_cast<std::uint64_t>(header.width_px) * header.channels * bit_depth + 7) / 8 + 1;
  const std::uint64_t raw_bytes = row_bytes * static_cast<std::uint64_t>(header.height_px);
  // (Interlaced data holds a few more filter bytes than this: the bound holds for it too.)
  if (idat_bytes * 1100 + 4096 < raw_bytes) {
    return Bad(f, fmt::format("{} bytes of image data cannot hold the {} x {} pixels the header "
                              "claims (a damaged or crafted file)",
                              idat_bytes, header.width_px, header.height_px));
  }
  return header;
}

// ---- JPEG -------------------------------------------------------------------------------------

bool IsSof(std::uint8_t m) { return m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC; }
bool IsArithmetic(std::uint8_t m) { return m >= 0xC9; }

Expected<ImageHeader> CheckJpeg(Bytes b) {
  constexpr ImageFormat f = ImageFormat::kJpeg;
  ImageHeader header{f, 0, 0, 0};
  std::optional<std::uint8_t> sof;
  bool exif_seen = false;
  std::uint64_t entropy_bytes = 0;
  std::size_t at = 2;
  while (true) {
    if (at >= b.size()) return Bad(f, "the file is cut short (no end-of-image marker)");
    if (b[at] != 0xFF) {
      return Bad(f, fmt::format("damaged: a marker was expected at byte {}", at));
    }
    while (at < b.size() && b[at] == 0xFF) ++at;  // fill bytes
    if (at >= b.size()) return Bad(f, "the file is cut short (no end-of-image marker)");
    const std::uint8_t marker = b[at++];
    if (marker == 0xD9) break;  // EOI
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) continue;
    if (marker == 0xD8 || marker == 0x00) {
      return Bad(f, fmt::format("damaged: unexpected marker 0x{:02X} at byte {}", marker, at - 1));
    }
    if (at + 2 > b.size()) return Bad(f, "the file is cut short (no end-of-image marker)");
    const std::size_t length = Be16(b, at);
    if (length < 2 || at + length > b.size()) {
      return Bad(
          f, fmt::format("the file is cut short (a segment at byte {} runs past its end)", at - 2));
    }
    // APP1: the first EXIF block gives the orientation (an XMP block has none).
    const Bytes payload = b.subspan(at + 2, length - 2);
    if (marker == 0xE1 && !exif_seen && payload.size() >= 6 &&
        std::memcmp(payload.data(), "Exif\0\0", 6) == 0) {
      exif_seen = true;
      const std::optional<int> orientation = ExifOrientation(payload);
      if (orientation && *orientation >= 1 && *orientation <= 8) header.orientation = *orientation;
    }
    if (IsSof(marker)) {
      if (sof) return Bad(f, "damaged: two frame headers");
      if (length < 8) return Bad(f, "damaged: a frame header is too short");
      sof = marker;
      header.height_px = Be16(b, at + 3);
      header.width_px = Be16(b, at + 5);
      header.channels = b[at + 7];
      if (header.height_px == 0) {
        return Bad(f, "the frame header gives no height (DNL marker): not supported");
      }
      if (header.channels < 1 || header.channels > 4) {
        return Bad(f, fmt::format("{} colour components: not supported", header.channels));
      }
    }
    at += length;
    if (marker == 0xDA) {  // SOS: entropy-coded data up to the next marker
      if (!sof) return Bad(f, "damaged: image data before the frame header");
      const std::size_t start = at;
      while (true) {
        const auto ff = std::find(b.begin() + static_cast<std::ptrdiff_t>(at), b.end(), 0xFF);
        at = static_cast<std::size_t>(ff - b.begin());
        if (at + 1 >= b.size()) {
          return Bad(f,
                     "the file is cut short (no end-of-image marker; a decoder would fill "
                     "the rest grey)");
        }
        const std::uint8_t next = b[at + 1];
        if (next == 0x00 || (next >= 0xD0 && next <= 0xD7)) {
          at += 2;
          continue;
        }
        if (next == 0xFF) {
          ++at;
          continue;
        }
        break;  // a marker: back to the segment loop
      }
      entropy_bytes += at - start;
    }
  }
  if (!sof) return Bad(f, "no frame header (SOFn): not an image");
  if (auto sized = CheckSize(header); !sized) return sized;
  // Huffman coding spends at least one bit on each 8 x 8 block of the first component.
  const std::uint64_t blocks = static_cast<std::uint64_t>((header.width_px + 7) / 8) *
                               static_cast<std::uint64_t>((header.height_px + 7) / 8);
  // Arithmetic coding adapts to long runs of empty blocks, but nothing real spends less than a
  // bit on 32 of them.
  if (IsArithmetic(*sof) ? entropy_bytes * 8 * 32 < blocks : entropy_bytes * 8 < blocks) {
    return Bad(f, fmt::format("{} bytes of image data cannot hold the {} x {} pixels the header "
                              "claims (a damaged or crafted file)",
                              entropy_bytes, header.width_px, header.height_px));
  }
  return header;
}

// ---- TIFF -------------------------------------------------------------------------------------

class TiffReader {
 public:
  TiffReader(Bytes b, bool little) : b_(b), little_(little) {}
  std::uint16_t U16(std::size_t at) const { return little_ ? Le16(b_, at) : Be16(b_, at); }
  std::uint32_t U32(std::size_t at) const { return little_ ? Le32(b_, at) : Be32(b_, at); }

  // The values of an IFD entry of type SHORT or LONG; nullopt when they lie outside the file.
  std::optional<std::vector<std::uint64_t>> Values(std::size_t entry) const {
    const std::uint16_t type = U16(entry + 2);
    const std::uint32_t count = U32(entry + 4);
    const std::size_t size = type == 3 ? 2 : type == 4 ? 4 : 0;
    if (size == 0 || count == 0 || count > b_.size()) return std::nullopt;
    std::size_t at = entry + 8;
    if (count * size > 4) {
      at = U32(entry + 8);
      if (at > b_.size() || count * size > b_.size() - at) return std::nullopt;
    }
    std::vector<std::uint64_t> values(count);
    for (std::size_t i = 0; i < count; ++i) {
      values[i] = size == 2 ? U16(at + 2 * i) : U32(at + 4 * i);
    }
    return values;
  }

 private:
  Bytes b_;
  bool little_;
};

// The strips (or tiles) must hold the pixels the header claims: all of them when uncompressed,
// and no more than each compression can pack into a byte (deflate about 1032:1, LZW with 12-bit
// codes about 1365:1, PackBits 64:1, JPEG at least one bit per 8 x 8 block).
Expected<void> CheckTiffDataSize(const ImageHeader& header, std::uint64_t bits,
                                 std::uint64_t compression,
                                 const std::vector<std::uint64_t>& byte_counts) {
  constexpr ImageFormat f = ImageFormat::kTiff;
  std::uint64_t stored = 0;
  for (const std::uint64_t n : byte_counts) stored += n;
  const auto width = static_cast<std::uint64_t>(header.width_px);
  const auto height = static_cast<std::uint64_t>(header.height_px);
  const std::uint64_t raw =
      (width * static_cast<std::uint64_t>(header.channels) * bits + 7) / 8 * height;
  std::uint64_t ratio = 0;  // the most pixel bytes one stored byte can give; 0: no bound known
  switch (compression) {
    case 1:
      ratio = 1;
      break;
    case 5:
      ratio = 1400;
      break;
    case 8:
    case 32946:
      ratio = 1100;
      break;
    case 32773:
      ratio = 64;
      break;
    case 7:  // one bit a block is 512 pixels a byte, so 512 samples of at most 8 bits
      ratio = 512 * static_cast<std::uint64_t>(header.channels);
      break;
    default:  // CCITT fax and the rest: nothing real packs a thousand pixel bytes into one
      ratio = 1000;
      break;
  }
  if (compression == 1 && stored < raw) {
    return Bad(f, fmt::format("the strips hold {} bytes, but {} x {} uncompressed pixels of {} "
                              "bits need {} (cut short or damaged)",
                              stored, width, height, bits * header.channels, raw));
  }
  if (ratio != 0 && stored * ratio + 4096 < raw) {
    return Bad(f, fmt::format("{} bytes of image data cannot hold the {} x {} pixels the header "
                              "claims (a damaged or crafted file)",
                              stored, width, height));
  }
  return {};
}

Expected<ImageHeader> CheckTiff(Bytes b, bool little) {
  constexpr ImageFormat f = ImageFormat::kTiff;
  const TiffReader r(b, little);
  if (r.U16(2) == 43) return Bad(f, "BigTIFF is not supported");
  if (r.U16(2) != 42) return Bad(f, "damaged header");
  const std::size_t ifd = r.U32(4);
  if (ifd < 8 || ifd + 2 > b.size()) return Bad(f, "the file is cut short (no image directory)");
  const std::size_t count = r.U16(ifd);
  if (ifd + 2 + count * 12 + 4 > b.size()) {  // the entries and the next directory's offset
    return Bad(f, "the file is cut short (the image directory runs past its end)");
  }
  ImageHeader header{f, 0, 0, 1};
  std::vector<std::uint64_t> offsets, byte_counts;
  std::uint64_t bits = 1;
  std::uint64_t compression = 1;
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t entry = ifd + 2 + i * 12;
    const std::uint16_t tag = r.U16(entry);
    if (tag != 256 && tag != 257 && tag != 258 && tag != 259 && tag != 277 && tag != 273 &&
        tag != 279 && tag != 324 && tag != 325) {
      continue;
    }
    auto values = r.Values(entry);
    if (!values) return Bad(f, fmt::format("damaged: tag {} lies outside the file", tag));
    if (tag == 256) header.width_px = static_cast<std::int64_t>(values->front());
    if (tag == 257) header.height_px = static_cast<std::int64_t>(values->front());
    if (tag == 258) bits = std::min<std::uint64_t>(values->front(), 64);
    if (tag == 259) compression = values->front();
    if (tag == 277)
      header.channels = static_cast<int>(std::min<std::uint64_t>(values->front(), 64));
    if (tag == 273 || tag == 324) offsets = std::move(*values);
    if (tag == 279 || tag == 325) byte_counts = std::move(*values);
  }
  if (auto sized = CheckSize(header); !sized) return sized;
  if (offsets.empty() || offsets.size() != byte_counts.size()) {
    return Bad(f, "damaged: no strips or tiles, or their offsets and byte counts disagree");
  }
  for (std::size_t i = 0; i < offsets.size(); ++i) {
    if (offsets[i] > b.size() || byte_counts[i] > b.size() - offsets[i]) {
      return Bad(f, fmt::format("the file is cut short (strip or tile {} of {} runs past its end)",
                                i + 1, offsets.size()));
    }
  }
  if (auto enough = CheckTiffDataSize(header, bits, compression, byte_counts); !enough) {
    return std::unexpected(enough.error());
  }
  return header;
}

// ---- BMP --------------------------------------------------------------------------------------

// Walks run-length coded pixels (RLE8, or RLE4 when `four_bit`) from `at` to their
// end-of-bitmap mark, which a whole file has; the runs and literal pixels must code every one of
// `pixels` (skips by delta or an early end leave pixels the decoder makes up, and let a tiny file
// claim any size).
Expected<void> CheckBmpRle(Bytes b, std::size_t at, bool four_bit, std::uint64_t pixels) {
  constexpr ImageFormat f = ImageFormat::kBmp;
  std::uint64_t coded = 0;
  while (at + 2 <= b.size()) {
    const std::uint8_t count = b[at];
    const std::uint8_t value = b[at + 1];
    at += 2;
    if (count != 0) {  // a run
      coded += count;
      continue;
    }
    if (value == 1) {  // end of bitmap
      if (coded < pixels) {
        return Bad(f, fmt::format("damaged: its run-length data codes {} of the {} pixels the "
                                  "header claims",
                                  coded, pixels));
      }
      return {};
    }
    if (value == 0) continue;  // end of line
    if (value == 2) {          // delta
      at += 2;
      continue;
    }
    coded += value;
    const std::size_t literal = four_bit ? (value + 1u) / 2 : value;
    at += (literal + 1) / 2 * 2;  // absolute mode, padded to a word
  }
  return Bad(f, "the file is cut short (its run-length data has no end-of-bitmap mark)");
}

Expected<ImageHeader> CheckBmp(Bytes b) {
  constexpr ImageFormat f = ImageFormat::kBmp;
  if (b.size() < 26) return Bad(f, "the file is cut short (in its header)");
  const std::uint32_t pixels_at = Le32(b, 10);
  const std::uint32_t dib = Le32(b, 14);
  ImageHeader header{f, 0, 0, 0};
  int bits = 0;
  std::uint32_t compression = 0;
  if (dib == 12) {
    header.width_px = Le16(b, 18);
    header.height_px = Le16(b, 20);
    bits = Le16(b, 24);
  } else if (dib >= 40 && b.size() >= 34) {
    header.width_px = static_cast<std::int32_t>(Le32(b, 18));
    const auto height = static_cast<std::int32_t>(Le32(b, 22));
    header.height_px = height < 0 ? -static_cast<std::int64_t>(height) : height;
    bits = Le16(b, 28);
    compression = Le32(b, 30);
  } else {
    return Bad(f, fmt::format("unknown header size {}", dib));
  }
  if (bits != 1 && bits != 4 && bits != 8 && bits != 16 && bits != 24 && bits != 32) {
    return Bad(f, fmt::format("unknown bit count {}", bits));
  }
  header.channels = bits <= 8 ? 1 : bits == 32 ? 4 : 3;
  if (auto sized = CheckSize(header); !sized) return sized;
  if (compression == 1 || compression == 2) {
    if (auto whole = CheckBmpRle(b, pixels_at, compression == 2,
                                 static_cast<std::uint64_t>(header.pixels()));
        !whole) {
      return std::unexpected(whole.error());
    }
  }
  if (compression == 0 || compression == 3) {
    const std::uint64_t row = (static_cast<std::uint64_t>(header.width_px) * bits + 31) / 32 * 4;
    if (pixels_at > b.size() ||
        row * static_cast<std::uint64_t>(header.height_px) > b.size() - pixels_at) {
      return Bad(f, fmt::format("the file is cut short ({} x {} pixels need more bytes than it "
                                "holds)",
                                header.width_px, header.height_px));
    }
  }
  return header;
}

// ---- PNM --------------------------------------------------------------------------------------

Expected<ImageHeader> CheckPnm(Bytes b) {
  constexpr ImageFormat f = ImageFormat::kPnm;
  const int kind = b[1] - '0';
  std::size_t at = 2;
  // The next decimal number, after whitespace and # comments.
  const auto number = [&]() -> std::optional<std::uint64_t> {
    while (at < b.size()) {
      if (b[at] == '#') {
        while (at < b.size() && b[at] != '\n' && b[at] != '\r') ++at;
      } else if (std::isspace(b[at])) {
        ++at;
      } else {
        break;
      }
    }
    if (at >= b.size() || !std::isdigit(b[at])) return std::nullopt;
    std::uint64_t value = 0;
    while (at < b.size() && std::isdigit(b[at])) {
      value = value * 10 + static_cast<std::uint64_t>(b[at] - '0');
      if (value > 0xFFFFFFFFu) return std::nullopt;
      ++at;
    }
    return value;
  };
  const auto width = number();
  const auto height = number();
  std::optional<std::uint64_t> max_value = 1;
  if (kind != 1 && kind != 4) max_value = number();
  if (!width || !height || !max_value || *max_value < 1 || *max_value > 65535) {
    return Bad(f, "damaged header (width, height, maximum value)");
  }
  ImageHeader header{f, static_cast<std::int64_t>(*width), static_cast<std::int64_t>(*height),
                     kind == 3 || kind == 6 ? 3 : 1};
  if (auto sized = CheckSize(header); !sized) return sized;
  ++at;  // the single whitespace before binary data
  const std::uint64_t samples = static_cast<std::uint64_t>(header.width_px) *
                                static_cast<std::uint64_t>(header.height_px) * header.channels;
  const std::uint64_t left = at <= b.size() ? b.size() - at : 0;
  std::uint64_t needed = 0;
  if (kind == 4) {
    needed = (static_cast<std::uint64_t>(header.width_px) + 7) / 8 *
             static_cast<std::uint64_t>(header.height_px);
  } else if (kind >= 5) {
    needed = samples * (*max_value > 255 ? 2 : 1);
  } else {
    needed = samples;  // text: at least one character a sample
  }
  if (needed > left) {
    return Bad(f, fmt::format("the file is cut short ({} x {} pixels need more bytes than it "
                              "holds)",
                              header.width_px, header.height_px));
  }
  return header;
}

}  // namespace

std::string_view ToString(ImageFormat format) {
  switch (format) {
    case ImageFormat::kPng:
      return "PNG";
    case ImageFormat::kJpeg:
      return "JPEG";
    case ImageFormat::kTiff:
      return "TIFF";
    case ImageFormat::kBmp:
      return "BMP";
    case ImageFormat::kPnm:
      return "PNM";
  }
  return "image";
}

std::optional<int> ExifOrientation(std::span<const std::uint8_t> app1) {
  const Bytes b = app1;
  if (b.size() < 14 || std::memcmp(b.data(), "Exif\0\0", 6) != 0) return 1;
  const Bytes tiff = b.subspan(6);
  const bool little = tiff[0] == 'I' && tiff[1] == 'I';
  if (!little && !(tiff[0] == 'M' && tiff[1] == 'M')) return std::nullopt;
  const auto u16 = [&](std::size_t at) { return little ? Le16(tiff, at) : Be16(tiff, at); };
  const auto u32 = [&](std::size_t at) { return little ? Le32(tiff, at) : Be32(tiff, at); };
  const std::size_t ifd = u32(4);
  if (ifd > tiff.size() || tiff.size() - ifd < 2) return std::nullopt;
  const std::uint32_t entries = u16(ifd);
  for (std::uint32_t e = 0; e < entries; ++e) {
    const std::size_t at = ifd + 2 + 12 * std::size_t{e};
    if (at + 12 > tiff.size()) return std::nullopt;
    if (u16(at) == 0x0112) return static_cast<int>(u16(at + 8));
  }
  return 1;
}

Expected<ImageHeader> CheckImageBytes(std::span<const std::uint8_t> bytes) {
  if (bytes.size() >= 8 && std::equal(kPngSignature.begin(), kPngSignature.end(), bytes.begin())) {
    return CheckPng(bytes);
  }
  if (bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) {
    return CheckJpeg(bytes);
  }
  if (bytes.size() >= 8 && bytes[0] == 'I' && bytes[1] == 'I') return CheckTiff(bytes, true);
  if (bytes.size() >= 8 && bytes[0] == 'M' && bytes[1] == 'M') return CheckTiff(bytes, false);
  if (bytes.size() >= 2 && bytes[0] == 'B' && bytes[1] == 'M') return CheckBmp(bytes);
  if (bytes.size() >= 3 && bytes[0] == 'P' && bytes[1] >= '1' && bytes[1] <= '6' &&
      std::isspace(bytes[2])) {
    return CheckPnm(bytes);
  }
  if (bytes.empty()) return MakeError(ErrorCode::kBadInput, "the file is empty");
  return MakeError(ErrorCode::kUnsupported,
                   "not a PNG, JPEG, TIFF, BMP or PNM image (unknown signature)");
}

}  // namespace revolve
