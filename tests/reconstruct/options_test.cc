// [reconstruct] parsing and the factory.
#include <gtest/gtest.h>

#include "config/config.h"
#include "reconstruct/reconstructor.h"

namespace revolve::reconstruct {
namespace {

Expected<ReconstructOptions> ParseText(const std::string& text) {
  static std::vector<std::unique_ptr<config::Document>> documents;  // outlive the Section
  Expected<config::Document> document = config::Parse(text, "test.toml");
  EXPECT_TRUE(document.has_value());
  documents.push_back(std::make_unique<config::Document>(std::move(*document)));
  Expected<config::Section> section = config::Section::Root(*documents.back()).Child("reconstruct");
  EXPECT_TRUE(section.has_value());
  return ParseOptions(*section);
}

TEST(ReconstructOptions, ParsesAGoodSection) {
  const Expected<ReconstructOptions> options = ParseText(
      "[reconstruct]\nmethod = \"hull\"\nresolution = 257\nvolume_radius_mm = 45.5\n"
      "volume_height_mm = 80\nformats = [\"wrl\", \"ply\", \"wrl\"]\n");
  ASSERT_TRUE(options.has_value()) << options.error().ToString();
  EXPECT_EQ(options->method, "hull");
  EXPECT_EQ(options->resolution, 257);
  EXPECT_EQ(options->bbox_min_mm, Eigen::Vector3d(-45.5, -45.5, 0.0));
  EXPECT_EQ(options->bbox_max_mm, Eigen::Vector3d(45.5, 45.5, 80.0));
  EXPECT_EQ(options->formats, (std::vector<std::string>{"wrl", "ply"}));
}

TEST(ReconstructOptions, ParsesFormatsTextureAndBottom) {
  const Expected<ReconstructOptions> options = ParseText(
      "[reconstruct]\nformats = [\"glb\", \"obj\", \"stl\", \"ply\", \"wrl\", \"obj\"]\n"
      "texture = false\ntexture_size_px = 1024\nflat_bottom = false\n");
  ASSERT_TRUE(options.has_value()) << options.error().ToString();
  EXPECT_EQ(options->formats, (std::vector<std::string>{"glb", "obj", "stl", "ply", "wrl"}));
  EXPECT_FALSE(options->texture);
  EXPECT_EQ(options->texture_size_px, 1024);
  EXPECT_FALSE(options->flat_bottom);
  const Expected<ReconstructOptions> defaults = ParseText("[reconstruct]\n");
  ASSERT_TRUE(defaults.has_value());
  EXPECT_TRUE(defaults->texture);
  EXPECT_EQ(defaults->texture_size_px, 4096);
  EXPECT_TRUE(defaults->flat_bottom);
}

TEST(ReconstructOptions, DefaultsMatchTheEmbeddedConfig) {
  const Expected<ReconstructOptions> absent = ParseText("[scan]\nstops = 36\n");
  ASSERT_TRUE(absent.has_value());
  const ReconstructOptions defaults;
  EXPECT_EQ(absent->resolution, defaults.resolution);
  EXPECT_EQ(absent->bbox_min_mm, defaults.bbox_min_mm);
  EXPECT_EQ(absent->bbox_max_mm, defaults.bbox_max_mm);
  EXPECT_EQ(absent->formats, defaults.formats);

  Expected<config::Document> document =
      config::Parse(std::string(config::EmbeddedDefault()), std::string(config::kEmbeddedOrigin));
  ASSERT_TRUE(document.has_value());
  Expected<config::Section> section = config::Section::Root(*document).Child("reconstruct");
  ASSERT_TRUE(section.has_value());
  const Expected<ReconstructOptions> embedded = ParseOptions(*section);
  ASSERT_TRUE(embedded.has_value()) << embedded.error().ToString();
  EXPECT_EQ(embedded->method, "hull");
  EXPECT_EQ(embedded->formats, defaults.formats);
  EXPECT_EQ(embedded->texture, defaults.texture);
  EXPECT_EQ(embedded->flat_bottom, defaults.flat_bottom);
}

TEST(ReconstructOptions, RejectsAnUnknownKey) {
  const Expected<ReconstructOptions> options =
      ParseText("[reconstruct]\nresolution = 64\nresolutoin = 65\n");
  ASSERT_FALSE(options.has_value());
  EXPECT_EQ(options.error().code, ErrorCode::kBadInput);
  EXPECT_NE(options.error().message.find("test.toml:3:"), std::string::npos)
      << options.error().message;
  EXPECT_NE(options.error().message.find("reconstruct.resolutoin"), std::string::npos);
}

TEST(ReconstructOptions, RejectsBadValues) {
  struct Case {
    const char* text;
    const char* key;
  };
  for (const Case& c : {Case{"resolution = 8", "reconstruct.resolution"},
                        Case{"resolution = 1025", "reconstruct.resolution"},
                        Case{"resolution = 64.5", "reconstruct.resolution"},
                        Case{"volume_radius_mm = 0", "reconstruct.volume_radius_mm"},
                        Case{"volume_height_mm = -5", "reconstruct.volume_height_mm"},
                        Case{"method = \"voxels\"", "reconstruct.method"},
                        Case{"meridian_row_step_px = 0", "reconstruct.meridian_row_step_px"},
                        Case{"formats = [\"ply\", \"fbx\"]", "reconstruct.formats"},
                        Case{"texture = 1", "reconstruct.texture"},
                        Case{"texture_size_px = 32", "reconstruct.texture_size_px"},
                        Case{"texture_size_px = 20000", "reconstruct.texture_size_px"},
                        Case{"flat_bottom = \"yes\"", "reconstruct.flat_bottom"},
                        Case{"formats = []", "reconstruct.formats"},
                        Case{"formats = \"ply\"", "reconstruct.formats"}}) {
    const Expected<ReconstructOptions> options =
        ParseText(std::string("[reconstruct]\n") + c.text + "\n");
    ASSERT_FALSE(options.has_value()) << c.text;
    EXPECT_EQ(options.error().code, ErrorCode::kBadInput);
    EXPECT_NE(options.error().message.find(c.key), std::string::npos) << options.error().message;
    EXPECT_NE(options.error().message.find("test.toml:2:"), std::string::npos)
        << options.error().message;
  }
}

TEST(ReconstructOptions, CreateValidates) {
  ReconstructOptions options;
  EXPECT_TRUE(Create(options).has_value());
  options.method = "meridian";
  EXPECT_TRUE(Create(options).has_value());
  options.method = "voxels";
  EXPECT_EQ(Create(options).error().code, ErrorCode::kBadInput);
  options = ReconstructOptions{};
  options.resolution = 4;
  EXPECT_EQ(Create(options).error().code, ErrorCode::kBadInput);
  options = ReconstructOptions{};
  options.bbox_max_mm.z() = options.bbox_min_mm.z();
  EXPECT_EQ(Create(options).error().code, ErrorCode::kBadInput);
}

}  // namespace
}  // namespace revolve::reconstruct
