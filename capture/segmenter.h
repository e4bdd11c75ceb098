// Silhouette segmentation: a frame in, a binary mask out.
//
// Every method ends with the same clean-up: the pixels outside the region of interest are
// cleared, then an opening (removes specks), a closing (fills cracks), the largest 8-connected
// component and hole filling.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "base/error.h"
#include "config/config.h"

namespace revolve::capture {

// [segment]
struct SegmentOptions {
  // otsu | fixed: grey-level threshold against a dark or light backdrop (`backdrop`).
  // background: colour distance to a frame of the empty scene (any backdrop; the plate and the
  //             fixtures are in the background frame, so they never count).
  // chroma:     distance from the backdrop's chroma (a green or blue screen).
  // graphcut:   any plain backdrop (dark, light, uneven, with a stand or shadows): the colour
  //             distance to the backdrop (the frame outline's median colour) seeds a trimap, and
  //             a graph cut (colour histograms of object and backdrop, capture/segment/colour_cut)
  //             decides the rest at reduced size, the edge placed again at full size
  //             (capture/segment/graph_cut.h). Slower (~31 ms a 1280x960 frame, one core).
  // Frames of 1280 px or more on their longer side are decided at a reduced size (mask_ops.h
  // WorkFactor) and their edge placed again at full size.
  // auto:       picks one of the above per frame (Segment) or per set (SegmentImageSet, which
  //             also learns the backdrop from the sequence): a background frame given: background
  //             refined; else a coloured backdrop: chroma; else graphcut.
  std::string method = "otsu";
  // otsu, fixed, graphcut: dark (object brighter) | light (object darker). graphcut and auto
  // measure the backdrop's colour themselves and use this only for otsu and fixed.
  std::string backdrop = "dark";
  int threshold = 128;  // fixed: grey level separating object and backdrop
  // otsu: when the two classes' mean grey levels differ by less than this, the frame holds no
  // object (an empty scene) and the mask is empty. background: the least automatic threshold.
  double min_contrast = 16.0;
  // background: colour distance (Euclidean, 8-bit BGR) above which a pixel is object; 0 picks it
  // per frame by Otsu's method on the distance image (never below min_contrast).
  double difference_threshold = 0.0;
  // background: an image of the empty scene (plate, fixtures, backdrop; same size and camera
  // settings as the scan) used instead of a frame the camera captures at the start. Take it with
  // `revolve camera snapshot FILE` before putting the object on the plate. Empty: none; a scan
  // whose camera cannot capture the empty scene (a real one) then learns the backdrop from its
  // first stops (capture/segment/set_segmentation.h, StopBackdropLearner). auto: with it, the
  // difference to it is refined.
  std::filesystem::path background_file;
  // chroma: the backdrop's colour, B G R 0..255; empty estimates it per frame as the median of
  // the region of interest's outline (which must show backdrop).
  std::vector<double> chroma_key_bgr;
  // graphcut: the backdrop's colour, B G R 0..255; empty estimates it per frame as the median of
  // the region of interest's outline. Either way, a backdrop whose outline shows it lit unevenly
  // is cut against the smooth surface fitted to the outline (capture/segment/backdrop_surface.h).
  std::vector<double> backdrop_bgr;
  // chroma: a pixel is backdrop when its chroma, projected on the key's, reaches this fraction
  // of the key's chroma (0.5 cuts anti-aliased edges at half coverage for neutral objects).
  double chroma_fraction = 0.5;
  // Region of interest [left, top, right, bottom) in pixels, clipped to the image; empty: the
  // whole image. Exclude the plate's rim, the table under it and anything fixed beside it.
  std::vector<int> roi_px;
  // A polygon further limiting the region of interest: x y pairs in pixels (at least three
  // points); empty: no polygon. Trace it just above the plate's near rim so the rim and the
  // table below it are excluded while the plate's top stays in.
  std::vector<int> roi_polygon_px;
  // Rectangles excluded from the region of interest, in groups of four [left, top, right,
  // bottom) (fixtures, clamps, a lamp stand).
  std::vector<int> exclude_px;
  int open_px = 1;           // opening radius; 0 disables
  int close_px = 1;          // closing radius; 0 disables
  bool keep_largest = true;  // keep only the largest 8-connected component
  bool fill_holes = true;    // fill holes in the silhouette
  int max_hole_area_px = 0;  // holes larger than this stay open (a mug's handle); 0: no limit
  // background: refine the difference mask with the graph cut (as graphcut does).
  bool refine = false;
  // graphcut, refine: the graph cut's image is reduced to at most this many pixels on its longer
  // side (0: full size); the edge is placed at full size either way.
  int refine_max_side_px = 320;
};

// Parses [segment] (the keys above, with their ranges); unknown keys are errors naming
// file:line:column and the key.
Expected<SegmentOptions> ParseSegmentOptions(const config::Section& section);

// What a caller found of an image before segmenting it (capture/segment/backdrop_surface.h).
struct FrameFacts;

class Segmenter {
 public:
  virtual ~Segmenter() = default;

  // Returns a CV_8UC1 mask of the image's size: 255 on the object, 0 elsewhere.
  // `background` (may be empty) is a frame of the empty scene for methods that use one.
  // Errors: bad_input for an empty or unsupported image, or (method = background) a missing
  // background frame or one of another size.
  virtual Expected<cv::Mat> Segment(const cv::Mat& image, const cv::Mat& background) const = 0;

  // Segment, given what the caller found of `image` already (the set's survey), which is then
  // not found again: the same mask and errors as Segment(image, background).
  virtual Expected<cv::Mat> SegmentWithFacts(const cv::Mat& image, const cv::Mat& background,
                                             const FrameFacts& facts) const;

  // True when Segment needs a background frame (method = background).
  virtual bool NeedsBackground() const { return false; }
};

// The configured segmenter. Thresholds: grey > threshold (dark backdrop) or grey < threshold
// (light backdrop), the threshold being Otsu's or the fixed one; Otsu on an image whose two
// classes differ by less than min_contrast grey levels (an empty scene) gives an all-zero mask.
// Errors: bad_input for an unknown method or an out-of-range value.
Expected<std::unique_ptr<Segmenter>> CreateSegmenter(const SegmentOptions& options);

// The region of interest as a CV_8UC1 mask of `size` (255 inside): roi_px and roi_polygon_px
// minus exclude_px.
cv::Mat RegionOfInterestMask(const SegmentOptions& options, cv::Size size);

// The objectness score of a frame against a backdrop colour (CV_8UC1): the Euclidean BGR
// distance, saturated at 255. With `shadows`, a pixel whose colour is the backdrop's scaled by
// 0.35..1.1 (a shadow or a brighter fold of the same cloth) scores only its chroma distortion,
// twice |c - a b| for the best scale a: a soft shadow on a light or coloured backdrop is not
// object. Contract: `bgr` CV_8UC3; `backdrop_bgr` a scalar (per frame) or a CV_8UC3 frame of the
// same size (per pixel).
cv::Mat BackdropDistance(const cv::Mat& bgr, const cv::Mat& backdrop_bgr, bool shadows);

// The backdrop colour (B, G, R) a chroma segmenter estimates: the per-channel median of the
// pixels on the outline of the region of interest's bounding rectangle. Contract: CV_8UC3.
cv::Scalar EstimateBackdropColour(const cv::Mat& image, const cv::Mat& roi);

}  // namespace revolve::capture
