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
  const std::string message = ErrorOf(ParseCamera("[camera]\nbackend = \"v4l2\"\n"));
  EXPECT_NE(message.find("test.toml:2:"), std::string::npos) << message;
  EXPECT_NE(message.find("camera.backend"), std::string::npos) << message;
  EXPECT_NE(message.find("synthetic"), std::string::npos) << message;
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
