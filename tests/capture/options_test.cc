// [camera], [camera.synthetic] and [segment] parsing.
#include <gtest/gtest.h>

#include "capture/camera.h"
#include "capture/segmenter.h"
#include "config/config.h"

namespace revolve::capture {
namespace {

constexpr char kOrigin[] = "test.toml";

// Parse `text` and hand its [camera] / [segment] table to the parsers. The document must
// outlive the Section, so each helper keeps the last one.
Expected<CameraOptions> ParseCamera(const std::string& text) {
  static config::Document document;
  auto parsed = config::Parse(text, kOrigin);
  if (!parsed) return std::unexpected(parsed.error());
  document = std::move(*parsed);
  auto section = config::Section::Root(document).Child("camera");
  if (!section) return std::unexpected(section.error());
  return ParseOptions(*section);
}

Expected<SegmentOptions> ParseSegment(const std::string& text) {
  static config::Document document;
  auto parsed = config::Parse(text, kOrigin);
  if (!parsed) return std::unexpected(parsed.error());
  document = std::move(*parsed);
  auto section = config::Section::Root(document).Child("segment");
  if (!section) return std::unexpected(section.error());
  return ParseSegmentOptions(*section);
}

// The error message, or "" when parsing succeeded.
template <class T>
std::string ErrorOf(const Expected<T>& result) {
  return result ? std::string() : result.error().message;
}

TEST(CameraOptions, EmbeddedDefaultParses) {
  auto options = ParseCamera(std::string(config::EmbeddedDefault()));
  ASSERT_TRUE(options.has_value()) << options.error().ToString();
  const SyntheticOptions& s = options->synthetic;
  EXPECT_EQ(options->backend, "synthetic");
  EXPECT_EQ(s.width_px, 768);
  EXPECT_EQ(s.height_px, 576);
  EXPECT_EQ(s.hfov_deg, 30.0);
  EXPECT_EQ(s.distance_mm, 450.0);
  EXPECT_EQ(s.object, "vase");
  EXPECT_EQ(s.seed, 1u);
  auto segment = ParseSegment(std::string(config::EmbeddedDefault()));
  ASSERT_TRUE(segment.has_value()) << segment.error().ToString();
  EXPECT_EQ(segment->method, "otsu");
  EXPECT_TRUE(segment->keep_largest);
}

TEST(CameraOptions, ReadsEveryKey) {
  auto options = ParseCamera(R"(
[camera]
backend = "synthetic"
[camera.synthetic]
width_px = 640
height_px = 480
hfov_deg = 40.5
distance_mm = 600
elevation_deg = -10.0
target_height_mm = 35.0
object = "cylinder"
radius_mm = 25.0
height_mm = 70.0
backdrop_grey = 5
noise_sigma = 0.0
seed = 99
)");
  ASSERT_TRUE(options.has_value()) << options.error().ToString();
  const SyntheticOptions& s = options->synthetic;
  EXPECT_EQ(s.width_px, 640);
  EXPECT_EQ(s.height_px, 480);
  EXPECT_EQ(s.hfov_deg, 40.5);
  EXPECT_EQ(s.distance_mm, 600.0);  // an integer is a number too
  EXPECT_EQ(s.elevation_deg, -10.0);
  EXPECT_EQ(s.target_height_mm, 35.0);
  EXPECT_EQ(s.object, "cylinder");
  EXPECT_EQ(s.radius_mm, 25.0);
  EXPECT_EQ(s.height_mm, 70.0);
  EXPECT_EQ(s.backdrop_grey, 5);
  EXPECT_EQ(s.noise_sigma, 0.0);
  EXPECT_EQ(s.seed, 99u);
}

TEST(CameraOptions, MissingTablesGiveDefaults) {
  auto options = ParseCamera("");
  ASSERT_TRUE(options.has_value());
  EXPECT_EQ(options->synthetic.width_px, SyntheticOptions{}.width_px);
  EXPECT_EQ(options->synthetic.object, SyntheticOptions{}.object);
}

TEST(CameraOptions, UnknownKeysAreErrorsWithFileAndLine) {
  std::string message =
      ErrorOf(ParseCamera("[camera]\nbackend = \"synthetic\"\n\n"
                          "[camera.synthetic]\nwidth_px = 640\nfocal_px = 900\n"));
  EXPECT_NE(message.find("test.toml:6:"), std::string::npos) << message;
  EXPECT_NE(message.find("camera.synthetic.focal_px"), std::string::npos) << message;
  EXPECT_NE(message.find("unknown key"), std::string::npos) << message;

  message = ErrorOf(ParseCamera("[camera]\nbakend = \"synthetic\"\n"));
  EXPECT_NE(message.find("test.toml:2:"), std::string::npos) << message;
  EXPECT_NE(message.find("camera.bakend"), std::string::npos) << message;

  message = ErrorOf(ParseSegment("[segment]\nmethod = \"otsu\"\nopen_radius = 2\n"));
  EXPECT_NE(message.find("test.toml:3:"), std::string::npos) << message;
  EXPECT_NE(message.find("segment.open_radius"), std::string::npos) << message;
}

TEST(CameraOptions, OutOfRangeAndMistypedValuesAreErrors) {
  const std::pair<std::string, std::string> cases[] = {
      {"width_px = 4", "width_px"},          {"height_px = 100000", "height_px"},
      {"hfov_deg = 0.0", "hfov_deg"},        {"hfov_deg = 180.0", "hfov_deg"},
      {"distance_mm = -5.0", "distance_mm"}, {"elevation_deg = 95.0", "elevation_deg"},
      {"object = \"cube\"", "object"},       {"radius_mm = 0.0", "radius_mm"},
      {"height_mm = -1.0", "height_mm"},     {"backdrop_grey = 300", "backdrop_grey"},
      {"noise_sigma = -1.0", "noise_sigma"}, {"seed = -1", "seed"},
      {"width_px = 640.5", "width_px"},      {"width_px = \"wide\"", "width_px"},
      {"distance_mm = 30.0", "distance_mm"},  // the camera would stand inside the vase
  };
  for (const auto& [line, key] : cases) {
    auto result = ParseCamera("[camera.synthetic]\n" + line + "\n");
    ASSERT_FALSE(result.has_value()) << line;
    EXPECT_EQ(result.error().code, ErrorCode::kBadInput);
    EXPECT_NE(result.error().message.find("test.toml:2:"), std::string::npos)
        << result.error().message;
    EXPECT_NE(result.error().message.find("camera.synthetic." + key), std::string::npos)
        << result.error().message;
  }
}

TEST(CameraOptions, BackendsThisBuildLacksAreErrors) {
  const std::string message = ErrorOf(ParseCamera("[camera]\nbackend = \"kinect\"\n"));
  EXPECT_NE(message.find("test.toml:2:"), std::string::npos) << message;
  EXPECT_NE(message.find("camera.backend"), std::string::npos) << message;
  EXPECT_NE(message.find("synthetic"), std::string::npos) << message;
}

TEST(CameraOptions, ReadsTheOtherBackendsTables) {
  auto options = ParseCamera(R"(
[camera]
backend = "replay"
[camera.replay]
dir = "frames"
pattern = "bw_shoe{angle}.tif"
step_deg = 10.0
order = "sequence"
[camera.v4l2]
device = "/dev/v4l/by-id/usb-Logitech_C920-video-index0"
width_px = 1920
height_px = 1080
pixel_formats = ["MJPG", "YUYV"]
exposure_us = 20000
white_balance_k = 4500
focus = 0
power_line_hz = 50
[camera.libcamera]
width_px = 2028
height_px = 1520
colour_gains = [1.8, 1.5]
[camera.synthetic]
projection = "orthographic"
axis_offset_px = 12.5
object = "torus"
radius_mm = 40
height_mm = 20
backdrop_bgr = [40, 170, 40]
plate_radius_mm = 60
fixture_mm = [80, -5, 0, 90, 5, 60]
blur_sigma_px = 1.5
)");
  ASSERT_TRUE(options.has_value()) << options.error().ToString();
  EXPECT_EQ(options->backend, "replay");
  // A relative dir is taken from the config file's folder ("test.toml" has none).
  EXPECT_EQ(options->replay.dir, "frames");
  EXPECT_EQ(options->replay.pattern, "bw_shoe{angle}.tif");
  EXPECT_EQ(options->replay.order, "sequence");
  EXPECT_EQ(options->v4l2.pixel_formats, (std::vector<std::string>{"MJPG", "YUYV"}));
  EXPECT_EQ(options->v4l2.exposure_us, 20000.0);
  EXPECT_EQ(options->v4l2.power_line_hz, 50);
  EXPECT_EQ(options->libcamera.colour_gains.size(), 2u);
  EXPECT_EQ(options->synthetic.projection, "orthographic");
  EXPECT_EQ(options->synthetic.object, "torus");
  EXPECT_EQ(options->synthetic.fixture_mm.size(), 6u);

  const std::pair<std::string, std::string> cases[] = {
      {"[camera.replay]\npattern = \"shoe.tif\"", "camera.replay.pattern"},
      {"[camera.replay]\norder = \"random\"", "camera.replay.order"},
      {"[camera.v4l2]\npixel_formats = [\"YUV\"]", "camera.v4l2.pixel_formats"},
      {"[camera.v4l2]\npower_line_hz = 55", "camera.v4l2.power_line_hz"},
      {"[camera.v4l2]\nexpose_us = 5", "camera.v4l2.expose_us"},
      {"[camera.synthetic]\nprojection = \"fisheye\"", "camera.synthetic.projection"},
      {"[camera.synthetic]\nbackdrop_bgr = [1, 2]", "camera.synthetic.backdrop_bgr"},
      {"[camera.synthetic]\nfixture_mm = [1, 2, 3]", "camera.synthetic.fixture_mm"},
      {"[camera.synthetic]\nobject = \"mesh\"", "camera.synthetic.mesh_path"},
      {"[camera.synthetic]\nobject = \"torus\"\nradius_mm = 10\nheight_mm = 30",
       "camera.synthetic.object"},
  };
  for (const auto& [text, key] : cases) {
    const std::string message = ErrorOf(ParseCamera(text + "\n"));
    EXPECT_NE(message.find(key), std::string::npos) << text << " -> " << message;
    EXPECT_NE(message.find("test.toml:"), std::string::npos) << message;
  }
}

TEST(SegmentOptions, ReadsTheNewKeys) {
  auto options = ParseSegment(R"(
[segment]
method = "chroma"
chroma_key_bgr = [40, 170, 40]
chroma_fraction = 0.4
roi_px = [0, 0, 768, 500]
roi_polygon_px = [0, 0, 768, 0, 768, 480, 0, 480]
exclude_px = [700, 100, 760, 400, 10, 10, 20, 20]
fill_holes = false
max_hole_area_px = 500
)");
  ASSERT_TRUE(options.has_value()) << options.error().ToString();
  EXPECT_EQ(options->method, "chroma");
  EXPECT_EQ(options->roi_px, (std::vector<int>{0, 0, 768, 500}));
  EXPECT_EQ(options->exclude_px.size(), 8u);
  EXPECT_FALSE(options->fill_holes);
  const std::pair<std::string, std::string> cases[] = {
      {"roi_px = [0, 0, 10]", "segment.roi_px"},
      {"roi_px = [10, 0, 5, 5]", "segment.roi_px"},
      {"exclude_px = [1, 2, 3, 4, 5]", "segment.exclude_px"},
      {"roi_polygon_px = [1, 2, 3, 4]", "segment.roi_polygon_px"},
      {"chroma_key_bgr = [1, 2]", "segment.chroma_key_bgr"},
      {"backdrop = \"grey\"", "segment.backdrop"},
      {"roi_px = [0.5, 0, 10, 10]", "segment.roi_px"},
  };
  for (const auto& [line, key] : cases) {
    const std::string message = ErrorOf(ParseSegment("[segment]\n" + line + "\n"));
    EXPECT_NE(message.find(key), std::string::npos) << line << " -> " << message;
    EXPECT_NE(message.find("test.toml:2:"), std::string::npos) << message;
  }
}

TEST(SegmentOptions, ReadsEveryKeyAndChecksRanges) {
  auto options = ParseSegment(
      "[segment]\nmethod = \"fixed\"\nthreshold = 70\nopen_px = 0\nclose_px = 3\n"
      "keep_largest = false\n");
  ASSERT_TRUE(options.has_value()) << options.error().ToString();
  EXPECT_EQ(options->method, "fixed");
  EXPECT_EQ(options->threshold, 70);
  EXPECT_EQ(options->open_px, 0);
  EXPECT_EQ(options->close_px, 3);
  EXPECT_FALSE(options->keep_largest);

  const std::pair<std::string, std::string> cases[] = {
      {"method = \"kmeans\"", "segment.method"}, {"threshold = 256", "segment.threshold"},
      {"threshold = -1", "segment.threshold"},   {"open_px = -1", "segment.open_px"},
      {"close_px = 99", "segment.close_px"},     {"keep_largest = 1", "segment.keep_largest"},
  };
  for (const auto& [line, key] : cases) {
    const std::string message = ErrorOf(ParseSegment("[segment]\n" + line + "\n"));
    EXPECT_NE(message.find("test.toml:2:"), std::string::npos) << line << ": " << message;
    EXPECT_NE(message.find(key), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace revolve::capture
