#include "base/image_read.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <vector>

#include <fmt/format.h>
#include "base/image_codecs.h"
#include "base/image_verify.h"

namespace revolve {
namespace {

namespace fs = std::filesystem;

std::unexpected<Error> Named(const fs::path& path, ErrorCode code, std::string_view what) {
  return MakeError(code, fmt::format("{}: {}", path.string(), what));
}

// The file's bytes, after checking it is a readable regular file no larger than an image of
// `max_pixels` could reasonably be.
Expected<std::vector<std::uint8_t>> ReadBytes(const fs::path& path, std::int64_t max_pixels) {
  std::error_code ec;
  const fs::file_status link = fs::symlink_status(path, ec);
  if (ec || !fs::exists(link)) return Named(path, ErrorCode::kNotFound, "no such file");
  const fs::file_status target = fs::status(path, ec);
  if (fs::is_symlink(link) && !fs::exists(target)) {
    const fs::path to = fs::read_symlink(path, ec);
    return Named(
        path, ErrorCode::kNotFound,
        fmt::format("a dangling symbolic link (its target {} does not exist)", to.string()));
  }
  if (!fs::is_regular_file(target)) return Named(path, ErrorCode::kBadInput, "not a regular file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) return Named(path, ErrorCode::kIo, fmt::format("cannot read: {}", ec.message()));
  // Uncompressed 16-bit RGBA plus headers: no image within the limit is larger.
  const std::uintmax_t max_bytes = static_cast<std::uintmax_t>(max_pixels) * 8 + (1u << 20);
  if (size > max_bytes) {
    return Named(path, ErrorCode::kBadInput,
                 fmt::format("{} MB is too large for an image of at most {:.0f} megapixels",
                             size >> 20, static_cast<double>(max_pixels) / 1e6));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return Named(path, ErrorCode::kIo, fmt::format("cannot open: {}", std::strerror(errno)));
  }
  std::vector<std::uint8_t> bytes(size);
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) {
    return Named(path, ErrorCode::kIo, "cannot read the whole file");
  }
  return bytes;
}

Expected<ImageHeader> CheckedHeader(const fs::path& path, std::span<const std::uint8_t> bytes,
                                    std::int64_t max_pixels) {
  Expected<ImageHeader> header = CheckImageBytes(bytes);
  if (!header) {
    return Named(
        path, ErrorCode::kBadInput,
        fmt::format("{} (an unreadable image: replace or remove it)", header.error().message));
  }
  if (header->pixels() > max_pixels) {
    return Named(path, ErrorCode::kBadInput,
                 fmt::format("{} x {} pixels ({:.1f} megapixels) is over the limit of {:.0f} "
                             "megapixels (--max-image-mp raises it)",
                             header->width_px, header->height_px,
                             static_cast<double>(header->pixels()) / 1e6,
                             static_cast<double>(max_pixels) / 1e6));
  }
  return header;
}

}  // namespace

Expected<ImageHeader> ReadImageHeader(const fs::path& path, std::int64_t max_pixels) {
  auto bytes = ReadBytes(path, max_pixels);
  if (!bytes) return std::unexpected(bytes.error());
  return CheckedHeader(path, *bytes, max_pixels);
}

Expected<cv::Mat> ReadImageFile(const fs::path& path, const ImageReadOptions& options) {
  auto bytes = ReadBytes(path, options.max_pixels);
  if (!bytes) return std::unexpected(bytes.error());
  auto header = CheckedHeader(path, *bytes, options.max_pixels);
  if (!header) return std::unexpected(header.error());
  const cv::Size size = DecodedSize(*header, options);
  if (options.expected_size && size != *options.expected_size) {
    return Named(path, ErrorCode::kBadInput,
                 fmt::format("is {} x {} pixels{}, but the other images are {} x {}", size.width,
                             size.height, header->quarter_turned() ? " (turned by its EXIF)" : "",
                             options.expected_size->width, options.expected_size->height));
  }
  cv::Mat image;
  // The common PNGs and JPEGs (masks, frames, photos) are decoded once, strictly.
  std::optional<Expected<cv::Mat>> decoded;
  if (header->format == ImageFormat::kPng)
    decoded = DecodeVerifiedPng(*bytes, options.imread_flags);
  if (header->format == ImageFormat::kJpeg) {
    decoded = DecodeVerifiedJpeg(*bytes, options.imread_flags);
  }
  if (decoded) {
    if (!*decoded) return Named(path, decoded->error().code, decoded->error().message);
    image = std::move(**decoded);
  }
  if (image.empty()) {
    // Decoded once with every warning of the format's library fatal: OpenCV prints them and
    // goes on; then by OpenCV.
    if (auto verified = VerifyImageData(header->format, *bytes); !verified) {
      return Named(path, verified.error().code, verified.error().message);
    }
    Expected<cv::Mat> opencv = DecodeImage(*bytes, options.imread_flags);
    if (!opencv && opencv.error().code != ErrorCode::kBadInput) {
      return Named(path, opencv.error().code, opencv.error().message);
    }
    if (opencv) image = std::move(*opencv);
  }
  if (image.empty()) {
    return Named(path, ErrorCode::kBadInput,
                 fmt::format("cannot decode the {} data (damaged?)", ToString(header->format)));
  }
  // EXIF orientation may turn a JPEG by a quarter.
  const bool same = image.cols == header->width_px && image.rows == header->height_px;
  const bool turned = image.cols == header->height_px && image.rows == header->width_px;
  if (!same && !turned) {
    return Named(path, ErrorCode::kBadInput,
                 fmt::format("decoded as {} x {} although its header says {} x {} (damaged?)",
                             image.cols, image.rows, header->width_px, header->height_px));
  }
  if (options.upright && options.imread_flags == cv::IMREAD_UNCHANGED && same) {
    TurnUpright(header->orientation, &image);
  }
  return image;
}

cv::Size DecodedSize(const ImageHeader& header, const ImageReadOptions& options) {
  const bool turns = options.imread_flags != cv::IMREAD_UNCHANGED || options.upright;
  const auto width = static_cast<int>(header.width_px);
  const auto height = static_cast<int>(header.height_px);
  return turns && header.quarter_turned() ? cv::Size(height, width) : cv::Size(width, height);
}

void TurnUpright(int orientation, cv::Mat* image) {
  // OpenCV's order (ApplyExifOrientation): a transpose for 5..8, then a flip.
  if (orientation < 2 || orientation > 8) return;
  if (orientation >= 5) cv::transpose(*image, *image);
  switch (orientation) {
    case 2:  // mirrored left-right
    case 6:  // a quarter clockwise
      cv::flip(*image, *image, 1);
      break;
    case 3:  // a half turn
    case 7:
      cv::flip(*image, *image, -1);
      break;
    case 4:  // mirrored top-bottom
    case 8:  // a quarter anticlockwise
      cv::flip(*image, *image, 0);
      break;
    default:  // 5: the transpose alone
      break;
  }
}

}  // namespace revolve
