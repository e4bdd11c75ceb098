#include <filesystem>
#include <map>
#include <string>
#include <utility>

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

// The shipped example configurations (config/examples/, systemd/revolved.toml) are what users
// copy: each must load as it is, with the backend it says.
TEST(StationConfigTest, EveryExampleConfigLoads) {
  const std::filesystem::path source(REVOLVE_SOURCE_DIR);
  std::map<std::string, std::pair<std::string, std::string>> expected = {
      {"default.toml", {"mock", "synthetic"}},
      {"rig-modbus-rtu-usb-camera.toml", {"modbus", "v4l2"}},
      {"rig-gpio-pi-camera.toml", {"gpio", "libcamera"}},
      {"replay-folder.toml", {"mock", "replay"}}};
  int seen = 0;
  for (const auto& entry : std::filesystem::directory_iterator(source / "config/examples")) {
    const std::string name = entry.path().filename().string();
    SCOPED_TRACE(name);
    auto cfg = LoadStationConfig(entry.path());
    ASSERT_TRUE(cfg.has_value()) << cfg.error().message;
    ASSERT_TRUE(expected.contains(name)) << "a new example: add it to this test";
    EXPECT_EQ(cfg->turntable.backend, expected[name].first);
    EXPECT_EQ(cfg->camera.backend, expected[name].second);
    ++seen;
  }
  EXPECT_EQ(seen, static_cast<int>(expected.size()));
  auto daemon = LoadStationConfig(source / "systemd/revolved.toml");
  EXPECT_TRUE(daemon.has_value()) << daemon.error().message;
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

constexpr char kRecipes[] = R"([station]
recipe = "quick"

[recipes.quick]
stops = 12
step_deg = 30.0
resolution = 64
segment = "fixed"
threshold = 90

[recipes.fine]
stops = 72
step_deg = 5.0

[scan]
stops = 36
step_deg = 10.0
)";

TEST(StationConfigTest, RecipesOverlayTheBaseAndReproduceTheScan) {
  auto base = ParseText(kRecipes);
  ASSERT_TRUE(base.has_value()) << base.error().message;
  EXPECT_EQ(RecipeNames(*base), (std::vector<std::string>{"default", "fine", "quick"}));
  EXPECT_EQ(base->scan.stops, 36);

  auto quick = ApplyRecipe(*base, "");  // [station] recipe
  ASSERT_TRUE(quick.has_value()) << quick.error().message;
  EXPECT_EQ(quick->recipe, "quick");
  EXPECT_EQ(quick->scan.stops, 12);
  EXPECT_DOUBLE_EQ(quick->scan.step_deg, 30.0);
  EXPECT_EQ(quick->reconstruct.resolution, 64);
  EXPECT_EQ(quick->segment.method, "fixed");
  EXPECT_EQ(quick->segment.threshold, 90);

  // The effective text (scan.toml) is a valid config that gives the same scan.
  auto again = ParseText(quick->text);
  ASSERT_TRUE(again.has_value()) << again.error().message << "\n" << quick->text;
  EXPECT_EQ(again->scan.stops, 12);
  EXPECT_EQ(again->reconstruct.resolution, 64);
  EXPECT_TRUE(again->recipes.empty());

  // "default" is the base itself.
  auto def = ApplyRecipe(*base, "default");
  ASSERT_TRUE(def.has_value());
  EXPECT_EQ(def->scan.stops, 36);
  EXPECT_EQ(def->recipe, "default");
}

TEST(StationConfigTest, UnknownRecipeNamesTheKnownOnes) {
  auto base = ParseText(kRecipes);
  ASSERT_TRUE(base.has_value());
  auto none = ApplyRecipe(*base, "turbo");
  ASSERT_FALSE(none.has_value());
  EXPECT_EQ(none.error().code, ErrorCode::kNotFound);
  EXPECT_NE(none.error().message.find("quick"), std::string::npos) << none.error().message;
}

TEST(StationConfigTest, RecipeErrorsNameTheFileLineAndKey) {
  auto typo = ParseText("[recipes.quick]\nstops = 12\nstepdeg = 30\n");
  ASSERT_FALSE(typo.has_value());
  EXPECT_NE(typo.error().message.find("rig.toml:3"), std::string::npos) << typo.error().message;
  EXPECT_NE(typo.error().message.find("recipes.quick.stepdeg"), std::string::npos)
      << typo.error().message;

  auto range = ParseText("[recipes.quick]\nresolution = 5\n");
  ASSERT_FALSE(range.has_value());
  EXPECT_NE(range.error().message.find("rig.toml:2"), std::string::npos) << range.error().message;

  // Valid alone, but more than a revolution over the base: found when the recipe is applied,
  // at the recipe's line.
  auto base = ParseText("[scan]\nstops = 36\nstep_deg = 10.0\n[recipes.wide]\nstep_deg = 20.0\n");
  ASSERT_TRUE(base.has_value()) << base.error().message;
  auto wide = ApplyRecipe(*base, "wide");
  ASSERT_FALSE(wide.has_value());
  EXPECT_NE(wide.error().message.find("rig.toml:"), std::string::npos) << wide.error().message;
  EXPECT_NE(wide.error().message.find("wide"), std::string::npos) << wide.error().message;

  auto station = ParseText("[station]\nrecipe = \"nope\"\n");
  ASSERT_FALSE(station.has_value());
  EXPECT_NE(station.error().message.find("station.recipe"), std::string::npos);
}

TEST(StationConfigTest, DaemonOperatorAndStationKeys) {
  auto cfg = ParseText(R"([daemon]
socket = "/tmp/x.sock"
socket_mode = "0640"
socket_group = "video"
max_clients = 4
[station]
scans_dir = "/srv/scans"
camera_retries = 5
min_free_mb = 100
[operator]
chip = "pinctrl-bcm2711"
start_button = 17
abort_button = "GPIO27"
led = 22
led_active_low = true
debounce_ms = 20
)");
  ASSERT_TRUE(cfg.has_value()) << cfg.error().message;
  EXPECT_EQ(cfg->daemon.socket, "/tmp/x.sock");
  EXPECT_EQ(cfg->daemon.socket_mode, 0640);
  EXPECT_EQ(cfg->daemon.socket_group, "video");
  EXPECT_EQ(cfg->daemon.max_clients, 4);
  EXPECT_EQ(cfg->station.scans_dir, "/srv/scans");
  EXPECT_EQ(cfg->station.camera_retries, 5);
  EXPECT_EQ(cfg->panel.start_button.offset, 17);
  EXPECT_TRUE(cfg->panel.start_button.active_low);  // buttons default to active low
  EXPECT_EQ(cfg->panel.abort_button.name, "GPIO27");
  EXPECT_TRUE(cfg->panel.led.active_low);
  EXPECT_FALSE(cfg->panel.lamp.present());
  EXPECT_TRUE(cfg->panel.Any());

  auto octal = ParseText("[daemon]\nsocket_mode = 0o600\n");
  ASSERT_TRUE(octal.has_value()) << octal.error().message;
  EXPECT_EQ(octal->daemon.socket_mode, 0600);

  for (const char* bad : {"[daemon]\nsocket_mode = \"rw-\"\n", "[daemon]\nmax_clients = 0\n",
                          "[daemon]\nsockett = \"/x\"\n", "[operator]\nled = -3\n",
                          "[station]\ncamera_retries = 99\n", "[operator]\nbias = \"up\"\n"}) {
    auto r = ParseText(bad);
    ASSERT_FALSE(r.has_value()) << bad;
    EXPECT_NE(r.error().message.find("rig.toml:2"), std::string::npos) << r.error().message;
  }
  auto defaults = ParseText("");
  ASSERT_TRUE(defaults.has_value());
  EXPECT_EQ(defaults->daemon.socket, "/run/revolve/control.sock");
  EXPECT_EQ(defaults->daemon.socket_mode, 0660);
  EXPECT_FALSE(defaults->panel.Any());
}

TEST(StationConfigTest, SimulatedFaultsNeedTheSimulatedRig) {
  auto ok = ParseText("[station.simulate]\ndrive_fault = \"alarm\"\ndrive_fault_move = 3\n");
  ASSERT_TRUE(ok.has_value()) << ok.error().message;
  EXPECT_EQ(ok->station.simulate.drive_fault, "alarm");
  EXPECT_TRUE(ok->station.simulate.Any());

  auto real = ParseText(
      "[turntable]\nbackend = \"gpio\"\n[turntable.gpio]\nstep = 1\ndir = 2\n"
      "[station.simulate]\ndrive_fault = \"stall\"\n");
  ASSERT_FALSE(real.has_value());
  EXPECT_NE(real.error().message.find("station.simulate.drive_fault"), std::string::npos)
      << real.error().message;
}

}  // namespace
}  // namespace revolve::station
