// What an image file's bytes say before any pixel is decoded: its format and size, and whether
// the file is whole. Pure (no files, no decoder), so that a reader can refuse a file that would
// need too much memory, or that is cut short or damaged, before a decoder allocates for it or
// fills the missing part with grey.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "base/error.h"

namespace revolve {

enum class ImageFormat { kPng, kJpeg, kTiff, kBmp, kPnm };

// "PNG", "JPEG", "TIFF", "BMP", "PNM"
std::string_view ToString(ImageFormat format);

struct ImageHeader {
  ImageFormat format = ImageFormat::kPng;
  std::int64_t width_px = 0;  // as stored
  std::int64_t height_px = 0;
  int channels = 0;
  // A JPEG's EXIF orientation (tag 0x0112 of the first EXIF block): how a viewer turns the stored
  // pixels to show them. 1 as stored; 3 a half turn; 6 a quarter clockwise, 8 anticlockwise; 2
  // and 4 mirrored left-right and top-bottom; 5 and 7 mirrored across a diagonal. 1 for the other
  // formats, and for a value that is missing, unreadable or not 1..8 (OpenCV ignores those too).
  int orientation = 1;

  std::int64_t pixels() const { return width_px * height_px; }
  // Whether the orientation swaps width and height (5..8).
  bool quarter_turned() const { return orientation >= 5; }
};

// The orientation in the payload of a JPEG APP1 marker segment (after its length): 1 when it is
// not an EXIF block or has no orientation tag, nullopt when the block cannot be read.
std::optional<int> ExifOrientation(std::span<const std::uint8_t> app1);

// The header of a whole image file held in `bytes`, after these checks of its structure:
// - PNG: signature, IHDR first, every chunk complete with a correct CRC, an IEND chunk;
// - JPEG: SOI, every marker segment complete, a frame header (SOFn) before the first scan, the
//   entropy-coded data of every scan ended by a marker, an EOI marker (a file cut short has
//   none: libjpeg would only warn "Premature end of JPEG file" and decode grey);
// - TIFF (classic): the first IFD inside the file with ImageWidth and ImageLength, every
//   strip or tile (offset + byte count) inside the file, and strips that hold the pixels:
//   all their bytes when uncompressed, no more than the compression can pack when compressed
//   (LZW 1400:1, deflate 1100:1, PackBits 64:1, JPEG, any other 1000:1);
// - BMP: the headers, the pixel rows of an uncompressed bitmap inside the file, and the
//   run-length data of an RLE4/RLE8 one coding every pixel and ending with its end-of-bitmap
//   mark;
// - PNM (P1..P6): the header, and the samples of a binary one inside the file;
// and, for PNG and JPEG, compressed data large enough for the size the header claims (a 2 kB
// file cannot hold 20000 x 20000 pixels: it is damaged or crafted): deflate packs at most about
// 1032 bytes into one, Huffman coding spends at least a bit on each 8 x 8 block, arithmetic
// coding a bit on 32 blocks.
// Width and height are at least 1. Errors: bad_input, the message naming the format and what is
// wrong but not the file (the caller knows its name); unsupported for another format.
Expected<ImageHeader> CheckImageBytes(std::span<const std::uint8_t> bytes);

}  // namespace revolve
