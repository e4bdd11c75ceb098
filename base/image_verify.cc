#include "base/image_verify.h"
#include "base/png_decode.h"

// libjpeg and libpng report errors by longjmp: every function below that calls setjmp holds
// only trivially destructible locals, and what outlives the jump lives in a context object owned
// by its caller.
#include <algorithm>
#include <array>
#include <csetjmp>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

// clang-format off
#include <jpeglib.h>
#include <png.h>
#include <tiffio.h>
// clang-format on

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

namespace revolve {
namespace {

using Bytes = std::span<const std::uint8_t>;

std::unexpected<Error> Bad(ImageFormat format, std::string_view what) {
  return MakeError(
      ErrorCode::kBadInput,
      fmt::format("{}: {} (a damaged image: replace or remove it)", ToString(format), what));
}

// ---- JPEG -------------------------------------------------------------------------------------

struct JpegContext {
  jpeg_error_mgr manager{};  // first: libjpeg hands back a pointer to it
  std::jmp_buf jump{};
  char message[JMSG_LENGTH_MAX] = {};
  bool warning = false;
};

[[noreturn]] void JpegErrorExit(j_common_ptr cinfo) {
  auto* context = reinterpret_cast<JpegContext*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, context->message);
  std::longjmp(context->jump, 1);
}

// Level -1 is a warning (corrupt data the library would paper over): fatal here. Levels 0 and
// up are traces: ignored.
void JpegEmitMessage(j_common_ptr cinfo, int level) {
  if (level >= 0) return;
  auto* context = reinterpret_cast<JpegContext*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, context->message);
  context->warning = true;
  std::longjmp(context->jump, 1);
}

void JpegOutputMessage(j_common_ptr /*cinfo*/) {}

// Returns false with context.message set when libjpeg complained.
bool DecodeJpeg(Bytes b, jpeg_decompress_struct& cinfo, JpegContext& context) {
  if (setjmp(context.jump) != 0) return false;
  jpeg_mem_src(&cinfo, b.data(), static_cast<unsigned long>(b.size()));
  jpeg_read_header(&cinfo, TRUE);
  // The entropy decoder, where damage shows, runs for every component whatever the output; the
  // cheapest output is enough.
  if (cinfo.jpeg_color_space == JCS_YCbCr || cinfo.jpeg_color_space == JCS_GRAYSCALE) {
    cinfo.out_color_space = JCS_GRAYSCALE;
  }
  cinfo.dct_method = JDCT_IFAST;
  cinfo.do_fancy_upsampling = FALSE;
  jpeg_start_decompress(&cinfo);
  JSAMPARRAY row = (*cinfo.mem->alloc_sarray)(reinterpret_cast<j_common_ptr>(&cinfo), JPOOL_IMAGE,
                                              cinfo.output_width * cinfo.output_components, 1);
  while (cinfo.output_scanline < cinfo.output_height) jpeg_read_scanlines(&cinfo, row, 1);
  jpeg_finish_decompress(&cinfo);  // reads on to the end-of-image marker
  return true;
}

// A libjpeg decompressor whose every complaint, warnings included, jumps back with its words
// in `context`.
struct JpegDecompressor {
  JpegContext context;
  jpeg_decompress_struct cinfo{};

  JpegDecompressor() {
    cinfo.err = jpeg_std_error(&context.manager);
    context.manager.error_exit = JpegErrorExit;
    context.manager.emit_message = JpegEmitMessage;
    context.manager.output_message = JpegOutputMessage;
    jpeg_create_decompress(&cinfo);
  }
  ~JpegDecompressor() { jpeg_destroy_decompress(&cinfo); }
  JpegDecompressor(const JpegDecompressor&) = delete;
  JpegDecompressor& operator=(const JpegDecompressor&) = delete;

  std::unexpected<Error> Complaint() const {
    return Bad(
        ImageFormat::kJpeg,
        fmt::format("libjpeg {}: \"{}\"", context.warning ? "warns" : "fails", context.message));
  }
};

Expected<void> VerifyJpeg(Bytes b) {
  JpegDecompressor jpeg;
  if (DecodeJpeg(b, jpeg.cinfo, jpeg.context)) return {};
  return jpeg.Complaint();
}

struct JpegPixels {
  int imread_flags = cv::IMREAD_UNCHANGED;
  cv::Mat image;
  bool other_kind = false;
};

// Decodes to pixels as OpenCV's JPEG decoder does (the same libjpeg settings: BGR or grey out,
// the accurate DCT, fancy upsampling), every warning fatal. Returns false with context.message
// set when libjpeg complained, or with pixels.other_kind set when OpenCV would do more (CMYK,
// an EXIF turn).
bool DecodeJpegPixels(Bytes b, jpeg_decompress_struct& cinfo, JpegContext& context,
                      JpegPixels& pixels) {
  if (setjmp(context.jump) != 0) return false;
  jpeg_mem_src(&cinfo, b.data(), static_cast<unsigned long>(b.size()));
  jpeg_save_markers(&cinfo, JPEG_APP0 + 1, 0xFFFF);
  jpeg_read_header(&cinfo, TRUE);
  const int flags = pixels.imread_flags;
  bool turned = false;
  for (jpeg_saved_marker_ptr m = cinfo.marker_list; m != nullptr; m = m->next) {
    const std::optional<int> orientation =
        ExifOrientation(std::span<const std::uint8_t>(m->data, m->data_length));
    turned = turned || orientation != 1;
  }
  const J_COLOR_SPACE space = cinfo.jpeg_color_space;
  if (space != JCS_YCbCr && space != JCS_GRAYSCALE && space != JCS_RGB) pixels.other_kind = true;
  if (turned && flags != cv::IMREAD_UNCHANGED) pixels.other_kind = true;
  if (pixels.other_kind) return false;
  const bool colour =
      flags == cv::IMREAD_COLOR || (flags == cv::IMREAD_UNCHANGED && cinfo.num_components == 3);
  cinfo.out_color_space = colour ? JCS_EXT_BGR : JCS_GRAYSCALE;
  jpeg_start_decompress(&cinfo);
  pixels.image.create(static_cast<int>(cinfo.output_height), static_cast<int>(cinfo.output_width),
                      colour ? CV_8UC3 : CV_8UC1);
  std::array<JSAMPROW, 16> rows{};
  while (cinfo.output_scanline < cinfo.output_height) {
    const JDIMENSION first = cinfo.output_scanline;
    const JDIMENSION count = std::min<JDIMENSION>(rows.size(), cinfo.output_height - first);
    for (JDIMENSION i = 0; i < count; ++i) rows[i] = pixels.image.ptr(static_cast<int>(first + i));
    jpeg_read_scanlines(&cinfo, rows.data(), count);
  }
  jpeg_finish_decompress(&cinfo);  // reads on to the end-of-image marker
  return true;
}

// ---- PNG --------------------------------------------------------------------------------------

struct PngContext {
  Bytes bytes;
  std::size_t at = 0;
  std::string message;
  std::vector<png_byte> row;
  // DecodeVerifiedPng: the flags asked for, the image made, and whether the file is of a kind
  // it decodes.
  int imread_flags = cv::IMREAD_UNCHANGED;
  cv::Mat image;
  std::vector<png_bytep> rows;
  bool other_kind = false;
};

void PngRead(png_structp png, png_bytep out, png_size_t length) {
  auto* context = static_cast<PngContext*>(png_get_io_ptr(png));
  if (length > context->bytes.size() - context->at) png_error(png, "read past the end of file");
  std::memcpy(out, context->bytes.data() + context->at, length);
  context->at += length;
}

[[noreturn]] void PngError(png_structp png, png_const_charp message) {
  static_cast<PngContext*>(png_get_error_ptr(png))->message = message;
  png_longjmp(png, 1);
}

// A warning is as fatal as an error: libpng would go on with what it could make of the data.
void PngWarning(png_structp png, png_const_charp message) {
  static_cast<PngContext*>(png_get_error_ptr(png))->message = message;
  png_longjmp(png, 1);
}

// Ancillary chunks that change no pixel of the decoded image: skipped unread.
constexpr png_byte kPngSkipped[] =
    "bKGD\0cHRM\0eXIf\0gAMA\0hIST\0iCCP\0iTXt\0oFFs\0pCAL\0pHYs\0sBIT\0sCAL\0sPLT\0sRGB\0sTER\0"
    "tEXt\0tIME\0zTXt";

// Reads up to the image data, every complaint fatal. Called after the caller's setjmp: libpng
// jumps back to it.
void ReadPngInfo(png_structp png, png_infop info, PngContext& context) {
  png_set_read_fn(png, &context, PngRead);
  png_set_keep_unknown_chunks(png, PNG_HANDLE_CHUNK_NEVER, kPngSkipped,
                              static_cast<int>(sizeof(kPngSkipped) / 5));
  png_set_benign_errors(png, 0);
  png_read_info(png, info);
}

bool DecodePng(png_structp png, png_infop info, PngContext& context) {
  if (setjmp(png_jmpbuf(png)) != 0) return false;
  ReadPngInfo(png, info, context);
  const int passes = png_set_interlace_handling(png);
  png_read_update_info(png, info);
  context.row.resize(png_get_rowbytes(png, info));
  const png_uint_32 height = png_get_image_height(png, info);
  for (int pass = 0; pass < passes; ++pass) {
    for (png_uint_32 y = 0; y < height; ++y) png_read_row(png, context.row.data(), nullptr);
  }
  png_read_end(png, nullptr);  // on to IEND: image data left over is a complaint
  return true;
}

// Returns false with context.message set when libpng complained, or with context.other_kind
// set when the file is not one this decodes.
bool DecodePngPixels(png_structp png, png_infop info, PngContext& context) {
  if (setjmp(png_jmpbuf(png)) != 0) return false;
  ReadPngInfo(png, info, context);
  const int colour = png_get_color_type(png, info);
  const int flags = context.imread_flags;
  const int depth = png_get_bit_depth(png, info);
  // 8 bits a channel, or a 1-bit grey mask (base/png_encode.h), expanded to 0 and 255 as
  // OpenCV expands it.
  const bool bits = depth == 1 && colour == PNG_COLOR_TYPE_GRAY;
  if ((depth != 8 && !bits) || png_get_valid(png, info, PNG_INFO_tRNS) != 0 ||
      (colour != PNG_COLOR_TYPE_GRAY && colour != PNG_COLOR_TYPE_RGB &&
       colour != PNG_COLOR_TYPE_RGBA) ||
      (flags == cv::IMREAD_GRAYSCALE && colour != PNG_COLOR_TYPE_GRAY)) {
    context.other_kind = true;
    return false;
  }
  if (bits) png_set_expand_gray_1_2_4_to_8(png);
  int type = CV_8UC1;
  if (colour != PNG_COLOR_TYPE_GRAY) png_set_bgr(png);
  if (flags == cv::IMREAD_COLOR) {
    if (colour == PNG_COLOR_TYPE_GRAY) png_set_gray_to_rgb(png);
    if (colour == PNG_COLOR_TYPE_RGBA) png_set_strip_alpha(png);
    type = CV_8UC3;
  } else if (colour == PNG_COLOR_TYPE_RGB) {
    type = CV_8UC3;
  } else if (colour == PNG_COLOR_TYPE_RGBA) {
    type = CV_8UC4;
  }
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  const auto width = static_cast<int>(png_get_image_width(png, info));
  const auto height = static_cast<int>(png_get_image_height(png, info));
  context.image.create(height, width, type);
  if (png_get_rowbytes(png, info) != context.image.step[0]) {
    context.other_kind = true;  // not what the transforms promise: leave it to OpenCV
    return false;
  }
  context.rows.resize(static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) context.rows[static_cast<std::size_t>(y)] = context.image.ptr(y);
  png_read_image(png, context.rows.data());
  png_read_end(png, nullptr);
  return true;
}

// Whether a chunk of type `type` is in the PNG `b` (whose structure CheckImageBytes accepted).
bool HasPngChunk(Bytes b, std::string_view type) {
  for (std::size_t at = 8; at + 12 <= b.size();) {
    const std::uint32_t length = (std::uint32_t{b[at]} << 24) | (std::uint32_t{b[at + 1]} << 16) |
                                 (std::uint32_t{b[at + 2]} << 8) | b[at + 3];
    if (std::string_view(reinterpret_cast<const char*>(&b[at + 4]), 4) == type) return true;
    if (length > b.size() - at - 12) return false;
    at += 12 + length;
  }
  return false;
}

Expected<void> VerifyPng(Bytes b) {
  PngContext context;
  context.bytes = b;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &context, PngError, PngWarning);
  if (png == nullptr) return MakeError(ErrorCode::kIo, "PNG: out of memory");
  png_infop info = png_create_info_struct(png);
  const bool ok = info != nullptr && DecodePng(png, info, context);
  png_destroy_read_struct(&png, info != nullptr ? &info : nullptr, nullptr);
  if (ok) return {};
  return Bad(ImageFormat::kPng, fmt::format("libpng fails: \"{}\"", context.message));
}

// ---- TIFF -------------------------------------------------------------------------------------

struct TiffContext {
  Bytes bytes;
  toff_t at = 0;
  std::string message;
};

tmsize_t TiffRead(thandle_t handle, void* out, tmsize_t size) {
  auto* context = static_cast<TiffContext*>(handle);
  if (size < 0 || context->at > context->bytes.size()) return 0;
  const auto n =
      std::min<std::size_t>(static_cast<std::size_t>(size), context->bytes.size() - context->at);
  std::memcpy(out, context->bytes.data() + context->at, n);
  context->at += n;
  return static_cast<tmsize_t>(n);
}
tmsize_t TiffWrite(thandle_t, void*, tmsize_t) { return 0; }
toff_t TiffSeek(thandle_t handle, toff_t offset, int whence) {
  auto* context = static_cast<TiffContext*>(handle);
  toff_t base = 0;
  if (whence == SEEK_CUR) base = context->at;
  if (whence == SEEK_END) base = context->bytes.size();
  context->at = base + offset;
  return context->at;
}
int TiffClose(thandle_t) { return 0; }
toff_t TiffSize(thandle_t handle) { return static_cast<TiffContext*>(handle)->bytes.size(); }
int TiffMap(thandle_t, void**, toff_t*) { return 0; }
void TiffUnmap(thandle_t, void*, toff_t) {}

int TiffComplaint(TIFF*, void* user, const char* module, const char* format, va_list args,
                  bool warning) {
  auto* context = static_cast<TiffContext*>(user);
  char text[512];
  std::vsnprintf(text, sizeof(text), format, args);
  // Private tags of cameras and editors are legitimate.
  if (warning && std::strstr(text, "Unknown field with tag") != nullptr) return 1;
  if (context->message.empty()) {
    context->message = module != nullptr && *module != '\0' ? fmt::format("{}: {}", module, text)
                                                            : std::string(text);
  }
  return 1;  // handled: libtiff's global handler (stderr) stays quiet
}
int TiffError(TIFF* tif, void* user, const char* module, const char* format, va_list args) {
  return TiffComplaint(tif, user, module, format, args, false);
}
int TiffWarning(TIFF* tif, void* user, const char* module, const char* format, va_list args) {
  return TiffComplaint(tif, user, module, format, args, true);
}

void DecodeTiff(TIFF* tif, TiffContext& context) {
  const bool tiled = TIFFIsTiled(tif) != 0;
  const tmsize_t chunk = tiled ? TIFFTileSize(tif) : TIFFStripSize(tif);
  const std::uint32_t count = tiled ? TIFFNumberOfTiles(tif) : TIFFNumberOfStrips(tif);
  if (chunk <= 0 || count == 0) {
    if (context.message.empty()) context.message = "no strips or tiles to decode";
    return;
  }
  std::vector<std::uint8_t> buffer(static_cast<std::size_t>(chunk));
  for (std::uint32_t i = 0; i < count && context.message.empty(); ++i) {
    const tmsize_t got = tiled ? TIFFReadEncodedTile(tif, i, buffer.data(), chunk)
                               : TIFFReadEncodedStrip(tif, i, buffer.data(), chunk);
    if (got < 0 && context.message.empty()) {
      context.message =
          fmt::format("{} {} of {} cannot be decoded", tiled ? "tile" : "strip", i + 1, count);
    }
  }
}

Expected<void> VerifyTiff(Bytes b) {
  TiffContext context;
  context.bytes = b;
  TIFFOpenOptions* options = TIFFOpenOptionsAlloc();
  if (options == nullptr) return MakeError(ErrorCode::kIo, "TIFF: out of memory");
  TIFFOpenOptionsSetErrorHandlerExtR(options, TiffError, &context);
  TIFFOpenOptionsSetWarningHandlerExtR(options, TiffWarning, &context);
  TIFF* tif = TIFFClientOpenExt("image", "rm", &context, TiffRead, TiffWrite, TiffSeek, TiffClose,
                                TiffSize, TiffMap, TiffUnmap, options);
  TIFFOpenOptionsFree(options);
  if (tif != nullptr) {
    if (context.message.empty()) DecodeTiff(tif, context);
    TIFFClose(tif);
  } else if (context.message.empty()) {
    context.message = "cannot be opened";
  }
  if (context.message.empty()) return {};
  return Bad(ImageFormat::kTiff, fmt::format("libtiff: \"{}\"", context.message));
}

}  // namespace

std::optional<Expected<cv::Mat>> DecodeVerifiedPng(std::span<const std::uint8_t> bytes,
                                                   int imread_flags) {
  if (imread_flags != cv::IMREAD_UNCHANGED && imread_flags != cv::IMREAD_COLOR &&
      imread_flags != cv::IMREAD_GRAYSCALE) {
    return std::nullopt;
  }
  if (HasPngChunk(bytes, "eXIf")) return std::nullopt;  // OpenCV may turn the picture
  // The common plain files without libpng (faster; the same pixels), the rest with it.
  if (std::optional<cv::Mat> plain = DecodePlainPng(bytes, imread_flags)) return std::move(*plain);
  PngContext context;
  context.bytes = bytes;
  context.imread_flags = imread_flags;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &context, PngError, PngWarning);
  if (png == nullptr) return MakeError(ErrorCode::kIo, "PNG: out of memory");
  png_infop info = png_create_info_struct(png);
  const bool ok = info != nullptr && DecodePngPixels(png, info, context);
  png_destroy_read_struct(&png, info != nullptr ? &info : nullptr, nullptr);
  if (ok) return std::move(context.image);
  if (context.other_kind) return std::nullopt;
  return Bad(ImageFormat::kPng, fmt::format("libpng fails: \"{}\"", context.message));
}

std::optional<Expected<cv::Mat>> DecodeVerifiedJpeg(std::span<const std::uint8_t> bytes,
                                                    int imread_flags) {
  if (imread_flags != cv::IMREAD_UNCHANGED && imread_flags != cv::IMREAD_COLOR &&
      imread_flags != cv::IMREAD_GRAYSCALE) {
    return std::nullopt;
  }
  JpegPixels pixels;
  pixels.imread_flags = imread_flags;
  JpegDecompressor jpeg;
  if (DecodeJpegPixels(bytes, jpeg.cinfo, jpeg.context, pixels)) return std::move(pixels.image);
  if (pixels.other_kind) return std::nullopt;
  return jpeg.Complaint();
}

Expected<void> VerifyImageData(ImageFormat format, std::span<const std::uint8_t> bytes) {
  switch (format) {
    case ImageFormat::kJpeg:
      return VerifyJpeg(bytes);
    case ImageFormat::kPng:
      return VerifyPng(bytes);
    case ImageFormat::kTiff:
      return VerifyTiff(bytes);
    case ImageFormat::kBmp:
    case ImageFormat::kPnm:
      return {};
  }
  return {};
}

}  // namespace revolve
