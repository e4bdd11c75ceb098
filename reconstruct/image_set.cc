#include "reconstruct/image_set.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/image_files.h"
#include "base/image_read.h"
#include "base/mask_rect.h"
#include "reconstruct/parallel.h"

namespace revolve::reconstruct {
namespace {

cv::Mat Disc(int radius_px) {
  return cv::getStructuringElement(cv::MORPH_ELLIPSE,
                                   cv::Size(2 * radius_px + 1, 2 * radius_px + 1));
}

// Background not 4-connected to the border becomes object, when its region has at most
// `max_area_px` pixels (0: any size).
cv::Mat FillHoles(const cv::Mat& mask, int max_area_px) {
  cv::Mat padded;
  cv::copyMakeBorder(mask, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::Mat flood = padded.clone();
  cv::floodFill(flood, cv::Point(0, 0), cv::Scalar(255), nullptr, cv::Scalar(), cv::Scalar(), 4);
  cv::Mat holes;
  cv::bitwise_not(flood, holes);
  if (max_area_px > 0) {
    cv::Mat labels;
    cv::Mat stats;
    cv::Mat centroids;
    const int count = cv::connectedComponentsWithStats(holes, labels, stats, centroids, 4, CV_32S);
    for (int v = 0; v < holes.rows; ++v) {
      const int* l = labels.ptr<int>(v);
      auto* h = holes.ptr<std::uint8_t>(v);
      for (int u = 0; u < holes.cols; ++u) {
        if (l[u] > 0 && l[u] < count && stats.at<int>(l[u], cv::CC_STAT_AREA) > max_area_px) {
          h[u] = 0;
        }
      }
    }
  }
  cv::Mat filled;
  cv::bitwise_or(padded, holes, filled);
  return filled(cv::Rect(1, 1, mask.cols, mask.rows)).clone();
}

cv::Mat DropSmallComponents(const cv::Mat& mask, double min_fraction) {
  cv::Mat labels;
  cv::Mat stats;
  cv::Mat centroids;
  const int count = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  if (count <= 2) return mask;
  int largest = 0;
  for (int i = 1; i < count; ++i) largest = std::max(largest, stats.at<int>(i, cv::CC_STAT_AREA));
  const double min_area = min_fraction * largest;
  std::vector<std::uint8_t> keep(static_cast<std::size_t>(count), 0);
  for (int i = 1; i < count; ++i) keep[i] = stats.at<int>(i, cv::CC_STAT_AREA) >= min_area;
  cv::Mat out(mask.size(), CV_8UC1, cv::Scalar(0));
  for (int v = 0; v < mask.rows; ++v) {
    const int* l = labels.ptr<int>(v);
    auto* o = out.ptr<std::uint8_t>(v);
    for (int u = 0; u < mask.cols; ++u) o[u] = keep[l[u]] ? 255 : 0;
  }
  return out;
}

// The number at the start of `text`: its value and its digit count.
std::optional<std::pair<long, int>> LeadingNumber(std::string_view text) {
  std::size_t n = 0;
  while (n < text.size() && std::isdigit(static_cast<unsigned char>(text[n]))) ++n;
  if (n == 0 || n > 9) return std::nullopt;
  long value = 0;
  std::from_chars(text.data(), text.data() + n, value);
  return std::make_pair(value, static_cast<int>(n));
}

}  // namespace

Expected<NamePattern> NamePattern::Parse(std::string_view pattern) {
  const auto bad = [&](const std::string& what) {
    return MakeError(ErrorCode::kBadInput, fmt::format("pattern \"{}\": {}", pattern, what));
  };
  if (pattern.empty()) return bad("empty");
  if (pattern.find('/') != std::string_view::npos) {
    return bad("a file name pattern cannot hold '/' (give the folder with --images)");
  }
  NamePattern result;
  int placeholders = 0;
  std::size_t pos = 0;
  std::string* part = &result.prefix_;
  while (pos < pattern.size()) {
    if (pattern[pos] == '{') {
      const std::size_t close = pattern.find('}', pos);
      if (close == std::string_view::npos) return bad("'{' without '}'");
      std::string_view name = pattern.substr(pos + 1, close - pos - 1);
      // A format spec, as in Python and fmt: {index:03} zero-pads to 3 digits.
      if (const std::size_t colon = name.find(':'); colon != std::string_view::npos) {
        const std::string_view spec = name.substr(colon + 1);
        const auto width = LeadingNumber(spec);
        if (!width || width->second != static_cast<int>(spec.size()) || width->first < 1 ||
            width->first > 9) {
          return bad(fmt::format("{{{}}}: expected a zero-padded width like {{{}:03}}", name,
                                 name.substr(0, colon)));
        }
        result.width_ = static_cast<int>(width->first);
        name = name.substr(0, colon);
      }
      if (name != "angle" && name != "index") {
        return bad(
            fmt::format("unknown placeholder {{{}}} (expected {{angle}} or {{index}})", name));
      }
      if (++placeholders > 1) return bad("use exactly one of {angle} and {index}, once");
      result.is_angle_ = name == "angle";
      part = &result.suffix_;
      pos = close + 1;
      continue;
    }
    part->push_back(pattern[pos++]);
  }
  if (placeholders == 0) return bad("holds neither {angle} nor {index}");
  return result;
}

std::optional<NamePattern::Number> NamePattern::Match(std::string_view file_name) const {
  if (file_name.size() <= prefix_.size() + suffix_.size()) return std::nullopt;
  if (file_name.substr(0, prefix_.size()) != prefix_) return std::nullopt;
  if (file_name.substr(file_name.size() - suffix_.size()) != suffix_) return std::nullopt;
  const std::string_view middle =
      file_name.substr(prefix_.size(), file_name.size() - prefix_.size() - suffix_.size());
  const auto number = LeadingNumber(middle);
  if (!number || number->second != static_cast<int>(middle.size())) return std::nullopt;
  // With a width, the number is written with exactly that many digits (or more, unpadded).
  if (width_ > 0 && number->second != width_ &&
      (number->second < width_ || middle.front() == '0')) {
    return std::nullopt;
  }
  return Number{number->first, number->second};
}

std::string NamePattern::Format(long number, int digits) const {
  return prefix_ + fmt::format("{:0{}d}", number, std::max({digits, width_, 1})) + suffix_;
}

std::optional<cv::Mat> BinarySilhouette(const cv::Mat& image) {
  cv::Mat grey;
  if (image.channels() == 1) {
    grey = image;
  } else {
    // A photo's first coloured pixel ends the scan.
    const int channels = image.channels();
    const int compared = std::min(3, channels);
    for (int v = 0; v < image.rows; ++v) {
      const auto* row = image.ptr<std::uint8_t>(v);
      for (int u = 0; u < image.cols; ++u) {
        const std::uint8_t* pixel = row + static_cast<std::ptrdiff_t>(u) * channels;
        for (int c = 1; c < compared; ++c) {
          if (pixel[c] != pixel[0]) return std::nullopt;
        }
      }
    }
    cv::extractChannel(image, grey, 0);
  }
  // At most two grey levels, 0 and 1 or 255, or one level of any value: the levels from the
  // extremes, then the image compared with its mask (no histogram: counting long runs of one
  // value in memory waits on each count's store).
  double low = 0.0;
  double high = 0.0;
  if (!grey.empty()) cv::minMaxIdx(grey, &low, &high);
  cv::Mat mask = grey != 0;
  if (low != high) {
    if (low != 0.0 || (high != 1.0 && high != 255.0)) return std::nullopt;
    const cv::Mat levels = high == 255.0 ? mask : cv::Mat(mask & 1);  // what 0/high pixels are
    for (int v = 0; v < grey.rows; ++v) {
      if (std::memcmp(grey.ptr(v), levels.ptr(v), static_cast<std::size_t>(grey.cols)) != 0) {
        return std::nullopt;
      }
    }
  }
  // Polarity from the border: mostly object there means the object is black on white.
  std::int64_t border = 0;
  std::int64_t border_set = 0;
  for (int u = 0; u < mask.cols; ++u) {
    border_set +=
        (mask.at<std::uint8_t>(0, u) != 0) + (mask.at<std::uint8_t>(mask.rows - 1, u) != 0);
    border += 2;
  }
  for (int v = 0; v < mask.rows; ++v) {
    border_set +=
        (mask.at<std::uint8_t>(v, 0) != 0) + (mask.at<std::uint8_t>(v, mask.cols - 1) != 0);
    border += 2;
  }
  if (2 * border_set > border) cv::bitwise_not(mask, mask);
  return mask;
}

cv::Mat SegmentPhoto(const cv::Mat& image, const PhotoSegmentation& options) {
  cv::Mat mask(image.size(), CV_8UC1, cv::Scalar(0));
  const int channels = image.channels();
  if (channels == 1 || channels == 3) {
    // Background where every channel is at most the threshold (OpenCV's vector loops).
    cv::inRange(image, cv::Scalar::all(0), cv::Scalar::all(options.threshold), mask);
    cv::bitwise_not(mask, mask);
  } else {
    for (int v = 0; v < image.rows; ++v) {
      const auto* in = image.ptr<std::uint8_t>(v);
      auto* out = mask.ptr<std::uint8_t>(v);
      for (int u = 0; u < image.cols; ++u) {
        bool object = false;
        for (int c = 0; c < std::min(channels, 3); ++c)
          object |= in[u * channels + c] > options.threshold;
        out[u] = object ? 255 : 0;
      }
    }
  }
  // The rest on the object's rectangle with a margin of background: the same result as on the
  // whole image (the closing reaches close_px beyond the object and its erosion close_px
  // further; the opening stays within; the margin's background joins the holes that reach the
  // image border to the crop's border, and no component lies outside), on a fraction of it.
  const int margin = 2 * std::max(options.close_px, 0) + 2 * std::max(options.open_px, 0) + 2;
  cv::Rect roi = MaskRect(mask);
  if (roi.empty()) return mask;
  roi = cv::Rect(roi.x - margin, roi.y - margin, roi.width + 2 * margin, roi.height + 2 * margin) &
        cv::Rect(0, 0, mask.cols, mask.rows);
  cv::Mat crop = mask(roi).clone();
  if (options.close_px > 0) cv::morphologyEx(crop, crop, cv::MORPH_CLOSE, Disc(options.close_px));
  if (options.open_px > 0) cv::morphologyEx(crop, crop, cv::MORPH_OPEN, Disc(options.open_px));
  if (options.min_component_fraction > 0.0) {
    crop = DropSmallComponents(crop, options.min_component_fraction);
  }
  if (options.fill_holes) crop = FillHoles(crop, options.max_hole_area_px);
  mask.setTo(0);
  crop.copyTo(mask(roi));
  return mask;
}

cv::Rect FrameWindow(const cv::Mat& mask, int margin_px) {
  const cv::Rect whole(0, 0, mask.cols, mask.rows);
  const cv::Rect roi = MaskRect(mask);
  if (roi.empty()) return whole;
  return cv::Rect(roi.x - margin_px, roi.y - margin_px, roi.width + 2 * margin_px,
                  roi.height + 2 * margin_px) &
         whole;
}

cv::Mat WholeFromWindow(const cv::Mat& window, cv::Point origin, cv::Size size) {
  if (origin == cv::Point() && window.size() == size) return window;
  cv::Mat whole(size, window.type(), cv::Scalar::all(0));
  window.copyTo(whole(cv::Rect(origin, window.size())));
  return whole;
}

std::string KindName(ImageKind kind, bool plural) {
  const char* name = kind == ImageKind::kSilhouette ? "binary silhouette"
                     : kind == ImageKind::kCutOut   ? "cut-out photo"
                                                    : "photo";
  return plural ? std::string(name) + "s" : std::string(name);
}

Expected<cv::Mat> ReadImage8(const std::filesystem::path& path, std::int64_t max_pixels,
                             std::optional<cv::Size> expected_size, cv::Mat* alpha) {
  ImageReadOptions read;
  read.imread_flags = cv::IMREAD_UNCHANGED;
  read.max_pixels = max_pixels;
  read.expected_size = expected_size;
  read.upright = true;
  Expected<cv::Mat> decoded = ReadImageFile(path, read);
  if (!decoded) return std::unexpected(decoded.error());
  cv::Mat image = std::move(*decoded);
  // 16-bit samples (a raw converter's TIFF, a 16-bit PNG) scaled to 8 bits: 65535 is 255.
  if (image.depth() == CV_16U) image.convertTo(image, CV_8U, 1.0 / 257.0);
  if (image.depth() != CV_8U) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{}: {} samples; 8-bit or 16-bit images expected (save the "
                                 "images as 8-bit or 16-bit PNG, TIFF or JPEG)",
                                 path.string(),
                                 image.depth() == CV_32F   ? "32-bit floating-point"
                                 : image.depth() == CV_64F ? "64-bit floating-point"
                                                           : "signed or 32-bit integer"));
  }
  if (alpha != nullptr) alpha->release();
  if (image.channels() == 4) {
    if (alpha != nullptr) cv::extractChannel(image, *alpha, 3);
    cv::cvtColor(image, image, cv::COLOR_BGRA2BGR);
  } else if (image.channels() != 1 && image.channels() != 3) {
    return MakeError(ErrorCode::kBadInput, fmt::format("{}: {} channels; grey or colour expected",
                                                       path.string(), image.channels()));
  }
  return image;
}

namespace {

// What decoding one image of a set found (DecodeSetImage).
struct DecodedImage {
  std::optional<Error> error;  // unreadable, or not of the expected size
  cv::Size size;
  ImageKind kind = ImageKind::kPhoto;
  bool empty_mask = false;  // a mask was made and it is empty
};

// Reads `image`'s file into image->image (photos, BGR) and image->mask (silhouettes, and photos
// when options.segment_photos), refusing another size than `expected_size` (the set's, described
// by `size_source` for the message) from the header.
DecodedImage DecodeSetImage(std::size_t index, SetImage* image, const ImageSetOptions& options,
                            std::optional<cv::Size> expected_size, const std::string& size_source) {
  DecodedImage result;
  cv::Mat alpha;
  Expected<cv::Mat> pixels =
      ReadImage8(image->path, options.max_image_pixels, expected_size, &alpha);
  if (!pixels) {
    result.error = pixels.error();
    return result;
  }
  result.size = pixels->size();
  if (expected_size && result.size != *expected_size) {
    result.error = MakeError(ErrorCode::kBadInput,
                             fmt::format("{}: {}x{} pixels, but {} {}x{} (all images of a set "
                                         "must have one size)",
                                         image->path.string(), pixels->cols, pixels->rows,
                                         size_source, expected_size->width, expected_size->height))
                       .error();
    return result;
  }
  // Some transparent pixel: cut out (whatever its colours are); else a binary image: a
  // silhouette; else a photo.
  double least_alpha = 255.0;
  if (!alpha.empty()) cv::minMaxLoc(alpha, &least_alpha);
  const bool cut_out = least_alpha < 255.0;
  std::optional<cv::Mat> silhouette = cut_out ? std::nullopt : BinarySilhouette(*pixels);
  result.kind = cut_out      ? ImageKind::kCutOut
                : silhouette ? ImageKind::kSilhouette
                             : ImageKind::kPhoto;
  bool segmented_by_caller = false;
  if (silhouette) {
    image->mask = std::move(*silhouette);
  } else {
    if (pixels->channels() == 1) {
      cv::cvtColor(*pixels, image->image, cv::COLOR_GRAY2BGR);
    } else {
      image->image = std::move(*pixels);
    }
    if (options.on_photo) options.on_photo(index, image->image);
    if (cut_out) {
      image->mask = alpha >= kCutOutMinAlpha;
    } else if (!options.segment_photos) {
      if (options.segment_photo) image->mask = options.segment_photo(index, image->image);
      if (image->mask.empty()) return result;
      segmented_by_caller = true;
    } else {
      image->mask = SegmentPhoto(image->image, options.segmentation);
    }
    if (options.frame_margin_px >= 0) {
      const cv::Rect window = FrameWindow(image->mask, options.frame_margin_px);
      image->image = image->image(window).clone();
      image->image_origin = window.tl();
    }
  }
  // A mask made by segment_photo may be empty: the caller judges it.
  result.empty_mask = !segmented_by_caller && cv::countNonZero(image->mask) == 0;
  return result;
}

// The size most of the set's headers give (checked, not decoded), and how to name it in a
// message: one odd image is then reported as the odd one, wherever it stands in the set. Empty
// when no header can be read (the decoder then reports the first file's error).
struct SetSize {
  cv::Size size;       // as decoded (ReadImage8: upright)
  std::string source;  // "the other 35 images are", "view_000.png is"
  int turned = 0;      // images whose EXIF orientation turns or mirrors them
};
std::optional<SetSize> MajoritySize(const std::vector<SetImage>& images, std::int64_t max_pixels) {
  std::vector<std::optional<cv::Size>> sizes(images.size());
  std::vector<char> turned(images.size(), 0);
  ImageReadOptions read;
  read.upright = true;
  ParallelFor(0, images.size(), [&](std::size_t i) {
    Expected<ImageHeader> header = ReadImageHeader(images[i].path, max_pixels);
    if (header) {
      sizes[i] = DecodedSize(*header, read);
      turned[i] = header->orientation != 1 ? 1 : 0;
    }
  });
  const auto turned_count = static_cast<int>(std::count(turned.begin(), turned.end(), 1));
  std::optional<cv::Size> best;
  std::size_t best_count = 0;
  std::size_t best_first = 0;
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    if (!sizes[i]) continue;
    const auto count = static_cast<std::size_t>(std::count(sizes.begin(), sizes.end(), sizes[i]));
    if (count > best_count) {
      best = sizes[i];
      best_count = count;
      best_first = i;
    }
  }
  if (!best) return std::nullopt;
  if (best_count == 1) return SetSize{*best, images[best_first].file_name + " is", turned_count};
  return SetSize{*best,
                 fmt::format("{} of the {} images ({} first) are", best_count, images.size(),
                             images[best_first].file_name),
                 turned_count};
}

// The kind most images are; a tie goes to the first image's.
ImageKind MajorityKind(const std::vector<DecodedImage>& decoded) {
  const auto count = [&](ImageKind kind) {
    return std::count_if(decoded.begin(), decoded.end(),
                         [&](const DecodedImage& d) { return d.kind == kind; });
  };
  ImageKind best = decoded[0].kind;
  for (const ImageKind kind : {ImageKind::kSilhouette, ImageKind::kPhoto, ImageKind::kCutOut}) {
    if (count(kind) > count(best)) best = kind;
  }
  return best;
}

}  // namespace

Expected<ImageSet> LoadImageSet(const std::filesystem::path& dir, const ImageSetOptions& options) {
  if (!(options.step_deg > 0.0) || !std::isfinite(options.step_deg)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("step {} deg: expected a positive angle", options.step_deg));
  }
  Expected<std::vector<std::filesystem::path>> listed = ListImageFiles(dir);
  if (!listed) return std::unexpected(listed.error());
  const std::vector<std::filesystem::path>& files = *listed;

  ImageSet set;
  if (options.pattern.empty()) {
    if (files.empty()) {
      const std::string instead = WhatAFolderHoldsInstead(dir);
      return MakeError(
          ErrorCode::kNotFound,
          fmt::format("{}: no image file (.png .tif .tiff .jpg .jpeg .bmp .pgm .ppm){}",
                      dir.string(), instead.empty() ? "" : ": " + instead));
    }
    for (std::size_t i = 0; i < files.size(); ++i) {
      SetImage image;
      image.path = files[i];
      image.file_name = files[i].filename().string();
      image.index = static_cast<int>(i);
      image.angle_deg = static_cast<double>(i) * options.step_deg;
      set.images.push_back(std::move(image));
    }
  } else {
    Expected<NamePattern> pattern = NamePattern::Parse(options.pattern);
    if (!pattern) return std::unexpected(pattern.error());
    std::map<long, std::filesystem::path> by_stop;
    int digits = 0;
    for (const std::filesystem::path& file : files) {
      const std::string name = file.filename().string();
      const std::optional<NamePattern::Number> number = pattern->Match(name);
      if (!number) continue;
      long stop = number->value;
      if (pattern->is_angle()) {
        stop = std::lround(static_cast<double>(number->value) / options.step_deg);
        // {angle} is in whole degrees: allow the rounding of a fractional stop angle.
        if (std::abs(static_cast<double>(stop) * options.step_deg -
                     static_cast<double>(number->value)) > 0.5 + 1e-9) {
          return MakeError(ErrorCode::kBadInput,
                           fmt::format("{}: angle {} deg is not a multiple of the {} deg step",
                                       file.string(), number->value, options.step_deg));
        }
      } else if (number->digits > static_cast<int>(fmt::format("{}", number->value).size())) {
        digits = number->digits;  // zero-padded names: name a missing one the same way
      }
      if (auto [it, inserted] = by_stop.emplace(stop, file); !inserted) {
        return MakeError(
            ErrorCode::kBadInput,
            fmt::format("{} and {} are the same stop ({})", it->second.string(), file.string(),
                        pattern->is_angle()
                            ? fmt::format("{} deg", static_cast<double>(stop) * options.step_deg)
                            : fmt::format("index {}", stop)));
      }
    }
    if (by_stop.empty()) {
      return MakeError(ErrorCode::kNotFound, fmt::format("{}: no image file matches \"{}\"",
                                                         dir.string(), options.pattern));
    }
    const long first = by_stop.begin()->first;
    const long last = by_stop.rbegin()->first;
    for (long stop = first; stop <= last; ++stop) {
      if (by_stop.count(stop) == 0) {
        const std::string missing =
            pattern->is_angle()
                ? pattern->Format(std::lround(static_cast<double>(stop) * options.step_deg))
                : pattern->Format(stop, digits);
        return MakeError(
            ErrorCode::kNotFound,
            fmt::format("{}: missing (the set runs from {} to {})", (dir / missing).string(),
                        by_stop.begin()->second.filename().string(),
                        by_stop.rbegin()->second.filename().string()));
      }
    }
    for (const auto& [stop, file] : by_stop) {
      SetImage image;
      image.path = file;
      image.file_name = file.filename().string();
      image.index = static_cast<int>(pattern->is_angle() ? stop : stop - first);
      image.angle_deg = static_cast<double>(image.index) * options.step_deg;
      set.images.push_back(std::move(image));
    }
  }

  // Most headers give the size and most images the kind, so that an odd image is named as such
  // wherever it stands. The images are decoded on all cores, each into its own slot, and checked
  // in order afterwards, so the error reported is that of the first bad file.
  const std::optional<SetSize> size = MajoritySize(set.images, options.max_image_pixels);
  std::vector<DecodedImage> decoded(set.images.size());
  ParallelFor(0, set.images.size(), [&](std::size_t i) {
    decoded[i] =
        DecodeSetImage(i, &set.images[i], options, size ? std::optional(size->size) : std::nullopt,
                       size ? size->source : std::string());
  });
  for (const DecodedImage& d : decoded) {
    if (d.error) return std::unexpected(*d.error);
  }
  set.width_px = decoded[0].size.width;
  set.height_px = decoded[0].size.height;
  set.exif_turned = size ? size->turned : 0;
  set.kind = MajorityKind(decoded);
  for (std::size_t i = 0; i < set.images.size(); ++i) {
    const SetImage& image = set.images[i];
    if (decoded[i].kind != set.kind) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("{}: a {} among {} (all images of a set must be binary silhouettes, all "
                      "photos, or all cut-out photos: with transparent pixels around the object)",
                      image.path.string(), KindName(decoded[i].kind), KindName(set.kind, true)));
    }
    if (decoded[i].empty_mask) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("{}: the silhouette is empty ({})", image.path.string(),
                      set.kind == ImageKind::kSilhouette ? std::string("no object pixel")
                      : set.kind == ImageKind::kCutOut
                          ? fmt::format("no pixel's alpha reaches {}: transparent everywhere",
                                        kCutOutMinAlpha)
                          : fmt::format("no pixel brighter than {} on the black background",
                                        options.segmentation.threshold)));
    }
  }
  return set;
}

}  // namespace revolve::reconstruct
