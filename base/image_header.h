// What an image file's bytes say before any pixel is decoded: its format and size, and whether
// the file is whole. Pure (no files, no decoder), so that a reader can refuse a file that would
// need too much memory, or that is cut short or damaged, before a decoder allocates for it or
// fills the missing part with grey.
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

#include "base/error.h"

namespace revolve {

enum class ImageFormat { kPng, kJpeg, kTiff, kBmp, kPnm };

// "PNG", "JPEG", "TIFF", "BMP", "PNM"
std::string_view ToString(ImageFormat format);

struct ImageHeader {
  ImageFormat format = ImageFormat::kPng;
  std::int64_t width_px = 0;
  std::int64_t height_px = 0;
  int channels = 0;

  std::int64_t pixels() const { return width_px * height_px; }
};

// The header of a whole image file held in `bytes`, after these checks of its structure:
// - PNG: signature, IHDR first, every chunk complete with a correct CRC, an IEND chunk;
// - JPEG: SOI, every marker segment complete, a frame header (SOFn) before the first scan, the
//   entropy-coded data of every scan ended by a marker, an EOI marker (a file cut short has
//   none: libjpeg would only warn "Premature end of JPEG file" and decode grey);
// - TIFF (classic): the first IFD inside the file with ImageWidth and ImageLength, and every
//   strip or tile (offset + byte count) inside the file;
// - BMP: the headers, and the pixel rows of an uncompressed bitmap inside the file;
// - PNM (P1..P6): the header, and the samples of a binary one inside the file;
// and, for PNG and Huffman-coded JPEG, compressed data large enough for the size the header
// claims (a 2 kB file cannot hold 20000 x 20000 pixels: it is damaged or crafted).
// Width and height are at least 1. Errors: bad_input, the message naming the format and what is
// wrong but not the file (the caller knows its name); unsupported for another format.
Expected<ImageHeader> CheckImageBytes(std::span<const std::uint8_t> bytes);

}  // namespace revolve
