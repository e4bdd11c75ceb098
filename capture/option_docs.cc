// The descriptions of [camera], its backends' tables, [segment] and [quality] for the configuration
// reference (docs/configuration.md, made by `revolve check-config --reference`). The types,
// defaults and ranges come from the parser itself; a key it reads with no description here fails
// the test config_reference.
#include "capture/camera.h"

namespace revolve::capture {
namespace {

constexpr config::TableDoc kTables[] = {
    {"camera", ""},
    {"camera.synthetic",
     "A pinhole (or orthographic) camera aimed at the rotation axis, rendering a known object "
     "standing on the plate (bottom at the plate, axis through its middle), shaded (Lambert and "
     "ambient light), with a procedural texture that turns with the object, on a backdrop, with "
     "Gaussian sensor noise. The silhouette edge is anti-aliased. The camera must be outside the "
     "object's enclosing cylinder.\n\nThe vase's radius at height z (0 ≤ z ≤ h) is `r(z) = R · "
     "(0.66 + 0.34 · cos(2π (z/h − 0.35)))`: a foot of 0.46 R, a belly of R at 0.35 h, a neck of "
     "0.32 R at 0.85 h and a lip flaring back to 0.46 R; its volume is 0.4934 π R² h. The cone has "
     "its base on the plate and its apex on the axis; the box is square (|x|, |y| ≤ r) and its "
     "corners turn with the plate; the torus lies flat."},
    {"camera.v4l2", ""},
    {"camera.libcamera", ""},
    {"camera.replay", ""},
    {"segment", ""},
    {"quality", "The gates of [Quality warnings](operator-guide.md#quality-warnings)."},
};

constexpr config::KeyDoc kKeys[] = {
    {"camera", "backend", "", "where frames come from", "", "",
     "`synthetic`, `replay`, `v4l2`, `libcamera` (those this build has)"},
    {"camera.synthetic", "width_px", "px", "image size"},
    {"camera.synthetic", "height_px", "px", "image size"},
    {"camera.synthetic", "hfov_deg", "degrees", "horizontal field of view"},
    {"camera.synthetic", "distance_mm", "mm", "from the lens to the rotation axis"},
    {"camera.synthetic", "elevation_deg", "degrees", "camera height angle above the aim point"},
    {"camera.synthetic", "target_height_mm", "mm", "where on the axis the camera aims"},
    {"camera.synthetic", "projection", "",
     "orthographic: the thesis's parallel projection (magnification fx / distance)"},
    {"camera.synthetic", "axis_offset_px", "px",
     "the axis appears this many pixels right of the middle column"},
    {"camera.synthetic", "roll_deg", "degrees",
     "camera rolled about its optical axis: the picture turns clockwise"},
    {"camera.synthetic", "known_geometry", "",
     "false hides the camera's geometry, like a real camera (calibration or thesis mode needed); "
     "the truth stays for accuracy"},
    {"camera.synthetic", "object", "", "the object"},
    {"camera.synthetic", "radius_mm", "mm",
     "sphere, cylinder and cone radius; the vase's largest radius; the box's half side; the "
     "torus's outer radius (> `height_mm` / 2)"},
    {"camera.synthetic", "height_mm", "mm",
     "height of every object but the sphere (`2 × radius_mm` tall); the torus's tube is this "
     "thick; a mesh is scaled to it"},
    {"camera.synthetic", "mesh_path", "", "`object = \"mesh\"`: the mesh file"},
    {"camera.synthetic", "mesh_up", "", "the mesh file's up axis"},
    {"camera.synthetic", "backdrop_grey", "grey level", "backdrop brightness"},
    {"camera.synthetic", "backdrop_bgr", "B G R",
     "backdrop colour (e.g. `[40, 170, 40]` green); empty: `backdrop_grey`"},
    {"camera.synthetic", "object_albedo", "", "texture brightness (0.45 suits a light backdrop)"},
    {"camera.synthetic", "plate_radius_mm", "mm",
     "the turntable's plate under the object; 0: none"},
    {"camera.synthetic", "plate_thickness_mm", "mm", "thickness of the plate"},
    {"camera.synthetic", "plate_top_bgr", "B G R", "the plate's top; empty: the backdrop's colour"},
    {"camera.synthetic", "plate_rim_bgr", "B G R", "the plate's rim"},
    {"camera.synthetic", "fixture_mm", "mm",
     "boxes fixed to the table: x0 y0 z0 x1 y1 z1 (table frame), repeated"},
    {"camera.synthetic", "fixture_bgr", "B G R", "fixture colour"},
    {"camera.synthetic", "texture", "",
     "the object's surface: a checker, or speckle that feature matchers (COLMAP) can match"},
    {"camera.synthetic", "blur_sigma_px", "px", "optical blur (Gaussian σ)"},
    {"camera.synthetic", "noise_sigma", "grey levels", "standard deviation of the sensor noise"},
    {"camera.synthetic", "seed", "",
     "noise seed (with the frame number), so a scan is reproducible"},
    {"camera.v4l2", "device", "",
     "the capture node; prefer `/dev/v4l/by-id/...` or a udev symlink"},
    {"camera.v4l2", "width_px", "px", "wanted size (0: the driver's current size)"},
    {"camera.v4l2", "height_px", "px", "wanted size (0: the driver's current size)"},
    {"camera.v4l2", "pixel_formats", "fourcc list", "preference order, at least one", "", "",
     "at least one four-character code; revolve converts YUYV, UYVY, MJPG, JPEG, GREY, RGB3, BGR3"},
    {"camera.v4l2", "exact_size", "", "a size the driver changes is an error"},
    {"camera.v4l2", "fps", "1/s", "frame rate (0: the driver's)"},
    {"camera.v4l2", "buffers", "count", "mmap buffers"},
    {"camera.v4l2", "use_libv4l2", "",
     "go through libv4l2 (format emulation for odd cameras) when built with it"},
    {"camera.v4l2", "exposure_us", "µs", "manual exposure (V4L2 units are 100 µs); -1: unset"},
    {"camera.v4l2", "gain", "device units", "manual gain; -1: unset"},
    {"camera.v4l2", "white_balance_k", "K", "manual white balance temperature; -1: unset"},
    {"camera.v4l2", "focus", "device units", "manual focus (autofocus off); -1: unset"},
    {"camera.v4l2", "power_line_hz", "Hz", "anti-flicker", "", "", "-1 (unset), 0 (off), 50, 60"},
    {"camera.v4l2", "lock_after_s", "s",
     "run auto exposure / gain / white balance this long after starting, then lock the controls "
     "not set above (0: never)"},
    {"camera.v4l2", "settle_margin_ms", "ms",
     "extra wait after the table settled before an exposure may start"},
    {"camera.v4l2", "timeouts_before_reopen", "count",
     "consecutive capture timeouts before the device is reopened"},
    {"camera.libcamera", "camera", "", "libcamera camera id; `\"\"` = the first"},
    {"camera.libcamera", "width_px", "px", "image size"},
    {"camera.libcamera", "height_px", "px", "image size"},
    {"camera.libcamera", "exposure_us", "µs", "manual exposure; -1: automatic"},
    {"camera.libcamera", "analogue_gain", "", "manual analogue gain; -1: automatic"},
    {"camera.libcamera", "colour_gains", "",
     "manual white balance `[red, blue]`; empty: automatic white balance"},
    {"camera.replay", "dir", "", "the folder of images"},
    {"camera.replay", "pattern", "", "`\"\"` = every image in natural order; else the file names",
     "", "", "`{angle}` or `{index}`, optionally `{angle:03}`"},
    {"camera.replay", "step_deg", "degrees", "angle between images"},
    {"camera.replay", "order", "", "the image for the plate's angle, or one after the other"},
    {"camera.replay", "background", "",
     "an image of the empty scene, for `[segment] method = \"background\"`"},
    {"camera.replay", "hfov_deg", "degrees",
     "> 0: the camera reports this geometry (with the three keys below, as "
     "`[camera.synthetic]`'s); 0: none, a calibration must give it"},
    {"camera.replay", "distance_mm", "mm",
     "with `hfov_deg` > 0: from the lens to the rotation axis"},
    {"camera.replay", "elevation_deg", "degrees",
     "with `hfov_deg` > 0: camera height angle above the aim point"},
    {"camera.replay", "target_height_mm", "mm",
     "with `hfov_deg` > 0: where on the axis the camera aims"},
    {"segment", "method", "",
     "how pixels are classified "
     "([choosing](operator-guide.md#choosing-a-backdrop-and-a-segmentation-method))"},
    {"segment", "backdrop", "",
     "otsu, fixed: the object is brighter (dark backdrop) or darker (light) than the backdrop"},
    {"segment", "threshold", "grey level", "fixed: the level between backdrop and object"},
    {"segment", "min_contrast", "grey levels",
     "otsu: two classes closer than this mean no object (empty mask); background: the least "
     "automatic threshold"},
    {"segment", "difference_threshold", "colour distance",
     "background: Euclidean 8-bit BGR distance from the empty scene above which a pixel is object; "
     "0 = chosen per frame (Otsu on the distance image)"},
    {"segment", "background_file", "",
     "background, auto: an image of the empty scene (same size and camera settings as the "
     "scan); without it a real camera's scan learns the backdrop from its first stops; "
     "relative to the config file"},
    {"segment", "chroma_key_bgr", "B G R",
     "chroma: the backdrop colour; empty = estimated per frame from the region of interest's "
     "outline (which must show backdrop)",
     "", "", "3 numbers in [0, 255], or none"},
    {"segment", "backdrop_bgr", "B G R",
     "graphcut: the backdrop's colour; empty: estimated per frame from the outline of the "
     "region of interest. A backdrop lit unevenly (from one side, vignetted) is cut against a "
     "smooth surface fitted to the outline either way"},
    {"segment", "refine", "",
     "background: refine the difference mask's edge with the graph cut, as graphcut does"},
    {"segment", "refine_max_side_px", "px",
     "graphcut and refine: the cut runs on the image reduced to at most this side"},
    {"segment", "chroma_fraction", "",
     "chroma: a pixel whose chroma carries at least this share of the key's is backdrop"},
    {"segment", "roi_px", "px",
     "region of interest [left, top, right, bottom); empty = whole image", "", "",
     "4 integers (left, top, right, bottom), or none"},
    {"segment", "roi_polygon_px", "px", "polygon limiting the region further", "", "",
     "x y pairs (integers), at least 3"},
    {"segment", "exclude_px", "px",
     "rectangles [left, top, right, bottom) left out (fixtures, clamps, stands)", "", "",
     "groups of 4 integers"},
    {"segment", "open_px", "px", "morphological opening radius (removes specks); 0 = off"},
    {"segment", "close_px", "px", "morphological closing radius (fills cracks); 0 = off"},
    {"segment", "keep_largest", "", "keep only the largest 8-connected component"},
    {"segment", "fill_holes", "", "fill holes in the silhouette"},
    {"segment", "max_hole_area_px", "px",
     "holes larger than this stay open (a handle, a torus); 0 = fill every hole"},
    {"quality", "enabled", "", "false: measure, never warn or recapture"},
    {"quality", "recaptures", "count",
     "captures of a failing stop again before it is kept with a warning"},
    {"quality", "min_area_fraction", "share of the image", "`empty_mask` below this"},
    {"quality", "border_margin_px", "px", "`touches_border` within this distance of the edge"},
    {"quality", "max_clipped_fraction", "share of the silhouette",
     "`overexposed` / `underexposed` above this"},
    {"quality", "max_edge_width_px", "px", "`blurred` above this"},
    {"quality", "max_area_change", "share of the larger area", "`area_jump` above this"},
    {"quality", "max_centroid_shift", "share of the bounding-box diagonal",
     "`centroid_jump` above this"},
};

}  // namespace

config::OptionDocs ReferenceDocs() { return {kTables, kKeys}; }

}  // namespace revolve::capture
