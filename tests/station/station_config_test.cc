#include <gtest/gtest.h>

#include "station/station_config.h"

namespace revolve::station {
namespace {

Expected<StationConfig> ParseText(const std::string& text) {
  auto document = config::Parse(text, "rig.toml");
  if (!document) return std::unexpected(document.error());
  return ParseStationConfig(*document);
}

TEST(StationConfigTest, EmbeddedDefaultIsTheSimulatedRig) {
  auto cfg = LoadStationConfig(std::nullopt);
  ASSERT_TRUE(cfg.has_value()) << cfg.error().message;
  EXPECT_EQ(cfg->origin, config::kEmbeddedOrigin);
  EXPECT_EQ(cfg->scan.stops, 36);
  EXPECT_DOUBLE_EQ(cfg->scan.step_deg, 10.0);
  EXPECT_EQ(cfg->turntable.backend, "mock");
  EXPECT_EQ(cfg->camera.backend, "synthetic");
  EXPECT_FALSE(cfg->text.empty());
}

TEST(StationConfigTest, EmptyFileTakesDefaults) {
  auto cfg = ParseText("");
  ASSERT_TRUE(cfg.has_value()) << cfg.error().message;
  EXPECT_EQ(cfg->scan.stops, 36);
}

TEST(StationConfigTest, UnknownTableIsNamedWithItsLine) {
  auto cfg = ParseText("[scan]\nstops = 4\n\n[turntabel]\nbackend = \"mock\"\n");
  ASSERT_FALSE(cfg.has_value());
  EXPECT_EQ(cfg.error().code, ErrorCode::kBadInput);
  EXPECT_NE(cfg.error().message.find("rig.toml:4"), std::string::npos) << cfg.error().message;
  EXPECT_NE(cfg.error().message.find("turntabel"), std::string::npos) << cfg.error().message;
}

TEST(StationConfigTest, MoreThanOneRevolutionIsRefused) {
  auto cfg = ParseText("[scan]\nstops = 40\nstep_deg = 10.0\n");
  ASSERT_FALSE(cfg.has_value());
  EXPECT_NE(cfg.error().message.find("scan.stops"), std::string::npos) << cfg.error().message;
}

TEST(StationConfigTest, ScanKeysAreRead) {
  auto cfg = ParseText("[scan]\nstops = 18\nstep_deg = 20\nsettle_ms = 5\n");
  ASSERT_TRUE(cfg.has_value()) << cfg.error().message;
  EXPECT_EQ(cfg->scan.stops, 18);
  EXPECT_DOUBLE_EQ(cfg->scan.step_deg, 20.0);
  EXPECT_DOUBLE_EQ(cfg->scan.settle_ms, 5.0);
}

TEST(StationConfigTest, MissingFileIsNotFound) {
  auto cfg = LoadStationConfig(std::filesystem::path("/nonexistent/rig.toml"));
  ASSERT_FALSE(cfg.has_value());
  EXPECT_EQ(cfg.error().code, ErrorCode::kNotFound);
  EXPECT_NE(cfg.error().message.find("/nonexistent/rig.toml"), std::string::npos);
}

}  // namespace
}  // namespace revolve::station
