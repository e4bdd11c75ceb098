// A folder of images as reconstruction input (`revolve reconstruct --images DIR`): which files,
// in which order, at which angle, and the silhouette of each.
//
// Naming (`pattern`): `{angle}` stands for the stop's angle in whole degrees and `{index}` for its
// number (digits, zero-padding allowed; `{index:03}` asks for exactly 3 digits, zero-padded);
// every other character is literal. `bw_shoe{angle}.tif`
// matches the thesis's bw_shoe0.tif ... bw_shoe350.tif, `dinoSR{index}.png` the Middlebury
// files. Without a pattern every image file of the folder (.png .tif .tiff .jpg .jpeg .bmp .pgm
// .ppm, any case) is taken, in file-name order, stop k at k * step_deg.
//
// Three kinds of image, told apart per file and required to agree across the set:
//  - binary silhouettes (the thesis's input): one grey channel (or three equal ones) holding only
//    two levels (0 and 255, or 0 and 1). Object white on black, or inverted: the polarity is
//    taken from the image border, which must be mostly background. The mask is the image; there
//    is no colour for texture.
//  - cut-out photos: an alpha channel (PNG, TIFF) with transparent pixels, as background
//    removal tools and phones' "lift the subject" export them. The mask is where alpha reaches
//    kCutOutMinAlpha (35 %: the object's partly covered rim is object, as the segmenter places
//    its edges), whatever colour the transparent pixels hold; the colours are kept for texture.
//  - photos on a black background: the mask is the pixels where any channel exceeds
//    `threshold`, then a closing (`close_px`), an opening (`open_px`), components smaller than
//    `min_component_fraction` of the largest dropped, and holes up to `max_hole_area_px` filled.
//    The photo is kept (BGR) for texture.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "base/image_read.h"

namespace revolve::reconstruct {

struct PhotoSegmentation {
  int threshold = 20;  // 0..254: object where any channel > threshold (8-bit)
  int close_px = 3;    // closing radius (elliptical kernel 2r+1); 0 disables
  int open_px = 1;     // opening radius; 0 disables
  // Connected components (8-connected) smaller than this fraction of the largest are dropped
  // (specks of noise on the backdrop); 0 keeps all, 1 keeps only the largest.
  double min_component_fraction = 0.05;
  bool fill_holes = true;
  // Holes (background regions not reaching the border) larger than this stay open: the gaps
  // between a temple's columns. 0 fills every hole.
  int max_hole_area_px = 0;
};

struct ImageSetOptions {
  std::string pattern;     // empty: every image file of the folder, in name order
  double step_deg = 10.0;  // angle between consecutive stops (> 0)
  PhotoSegmentation segmentation;
  // false: photos are loaded with an empty mask, for the caller to segment
  // (capture::SegmentImageSet); silhouettes and cut-out photos keep theirs.
  bool segment_photos = true;
  // Larger images are refused from their headers, before decoding (base/image_read.h).
  std::int64_t max_image_pixels = kDefaultMaxImagePixels;
  // >= 0, with segment_photos: each photo keeps only its pixels within FrameWindow(mask,
  // frame_margin_px) (SetImage::image_origin says where they are); -1 keeps whole photos.
  int frame_margin_px = -1;
  // Called with each photo as decoded (BGR, whole), on the thread that decoded it, before it is
  // cut to its window; `index` is its place in ImageSet::images. May be empty.
  std::function<void(std::size_t index, const cv::Mat& photo)> on_photo;
  // Without segment_photos: called after on_photo with each photo that is not cut out, to
  // segment it where it was decoded. It returns the photo's mask (CV_8UC1 0/255 of its size; an
  // empty mask is not an error here), which the photo then keeps and is cut to the window of as
  // frame_margin_px says; or an empty Mat: the photo stays whole, without a mask. May be empty.
  std::function<cv::Mat(std::size_t index, const cv::Mat& photo)> segment_photo;
};

enum class ImageKind { kSilhouette, kPhoto, kCutOut };

// A cut-out photo's alpha from which a pixel is object (see the file comment).
inline constexpr int kCutOutMinAlpha = 90;

// What an image of `kind` is called in messages: "binary silhouette", "photo", "cut-out photo";
// `plural` adds the s.
std::string KindName(ImageKind kind, bool plural = false);

struct SetImage {
  std::filesystem::path path;
  std::string file_name;
  // Stop number: round({angle} / step), {index} minus the lowest found, or the position in name
  // order.
  int index = 0;
  double angle_deg = 0.0;  // index * step_deg
  cv::Mat image;           // CV_8UC3 BGR for (cut-out) photos (or a window); empty for silhouettes
  cv::Point image_origin;  // the photo's pixel that is image's (0, 0)
  cv::Mat mask;            // CV_8UC1, 255 = object (empty: a photo not segmented here)
};

struct ImageSet {
  ImageKind kind = ImageKind::kPhoto;
  int width_px = 0;  // as decoded: upright (ReadImage8)
  int height_px = 0;
  // Images whose JPEG EXIF orientation turned or mirrored them upright (ReadImage8).
  int exif_turned = 0;
  std::vector<SetImage> images;  // by index (pattern) or by file name
};

// A file-name pattern with {angle} / {index} (see the file comment).
class NamePattern {
 public:
  // Errors: bad_input for an empty pattern, one with both or neither of {angle} and {index}, a
  // placeholder given twice, a '/' or an unknown {placeholder}.
  static Expected<NamePattern> Parse(std::string_view pattern);

  struct Number {
    long value = 0;
    int digits = 0;  // as written, with any leading zeros
  };
  // The number in place of the placeholder, or nullopt when `file_name` does not match.
  std::optional<Number> Match(std::string_view file_name) const;
  // The file name for `number`, zero-padded to `digits` (0: no padding).
  std::string Format(long number, int digits = 0) const;
  bool is_angle() const { return is_angle_; }

 private:
  std::string prefix_;
  std::string suffix_;
  bool is_angle_ = false;
  int width_ = 0;  // {index:03}: 3; 0 without a width
};

// Silhouette of a binary image (see the file comment), or nullopt when the image is not binary.
// `image`: 8-bit, 1, 3 or 4 channels.
std::optional<cv::Mat> BinarySilhouette(const cv::Mat& image);

// The mask of a photo on a black background (see the file comment). `image`: 8-bit BGR or grey.
cv::Mat SegmentPhoto(const cv::Mat& image, const PhotoSegmentation& options);

// The bounding rectangle of `mask`'s non-zero pixels widened by margin_px on every side, within
// the mask; the whole mask when it is empty.
cv::Rect FrameWindow(const cv::Mat& mask, int margin_px);

// The image of `size` holding `window` from `origin` on and zeros elsewhere (the whole of an
// image kept as a window of it). Precondition: the window lies within the image.
cv::Mat WholeFromWindow(const cv::Mat& window, cv::Point origin, cv::Size size);

// Loads the set. Errors name the file: not_found (no folder, no image in it, no file matching
// the pattern, a stop missing between the first and the last: the expected file name), bad_input
// (an unreadable image or one neither 8-bit nor 16-bit, sizes that differ, kinds mixed
// (silhouettes, photos, cut-out photos), an empty silhouette, two files for one stop, an {angle}
// that is not a multiple of step_deg, a bad pattern or step).
Expected<ImageSet> LoadImageSet(const std::filesystem::path& dir, const ImageSetOptions& options);

// Reads one image file as LoadImageSet does: upright (a JPEG turned or mirrored as its EXIF
// orientation says, as viewers show it), 8-bit grey or BGR (16-bit samples scaled to 8 bits;
// BGRA loses its alpha, into
// *alpha when given: CV_8UC1, left empty for an image without one), its header checked first
// (base/image_read.h: over `max_pixels`, of another size than `expected_size`, cut short or
// damaged: refused before decoding). Errors: not_found (also a dangling symbolic link), or
// bad_input naming the file (not an image OpenCV can decode, not 8-bit, the checks above).
Expected<cv::Mat> ReadImage8(const std::filesystem::path& path,
                             std::int64_t max_pixels = kDefaultMaxImagePixels,
                             std::optional<cv::Size> expected_size = std::nullopt,
                             cv::Mat* alpha = nullptr);

}  // namespace revolve::reconstruct
