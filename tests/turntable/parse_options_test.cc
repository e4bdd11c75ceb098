#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/config.h"
#include "turntable/turntable.h"

namespace revolve::turntable {
namespace {

using testing::HasSubstr;

// Parses `text` as test.toml and then its [turntable] table.
Expected<TurntableOptions> ParseText(const std::string& text) {
  Expected<config::Document> document = config::Parse(text, "test.toml");
  if (!document) return std::unexpected(document.error());
  Expected<config::Section> section = config::Section::Root(*document).Child("turntable");
  if (!section) return std::unexpected(section.error());
  return ParseOptions(*section);
}

TEST(TurntableParseOptions, EmbeddedDefault) {
  Expected<TurntableOptions> options = ParseText(std::string(config::EmbeddedDefault()));
  ASSERT_TRUE(options) << options.error().ToString();
  EXPECT_EQ(options->backend, "mock");
  EXPECT_DOUBLE_EQ(options->mock.speed_deg_per_s, 120.0);
  EXPECT_DOUBLE_EQ(options->mock.acceleration_deg_per_s2, 720.0);
  EXPECT_DOUBLE_EQ(options->mock.settle_ms, 20.0);
  EXPECT_DOUBLE_EQ(options->mock.time_scale, 0.1);
  EXPECT_DOUBLE_EQ(options->mock.tolerance_deg, MockOptions{}.tolerance_deg);
}

TEST(TurntableParseOptions, MissingTablesGiveDefaults) {
  Expected<TurntableOptions> options = ParseText("[scan]\nstops = 4\n");
  ASSERT_TRUE(options) << options.error().ToString();
  EXPECT_EQ(options->backend, "mock");
  EXPECT_DOUBLE_EQ(options->mock.speed_deg_per_s, MockOptions{}.speed_deg_per_s);
  EXPECT_DOUBLE_EQ(options->mock.time_scale, MockOptions{}.time_scale);
}

TEST(TurntableParseOptions, AllMockKeys) {
  Expected<TurntableOptions> options = ParseText(
      "[turntable]\nbackend = \"mock\"\n[turntable.mock]\nspeed_deg_per_s = 30\n"
      "acceleration_deg_per_s2 = 90.5\nsettle_ms = 0\ntime_scale = 1\ntolerance_deg = 0.5\n");
  ASSERT_TRUE(options) << options.error().ToString();
  EXPECT_DOUBLE_EQ(options->mock.speed_deg_per_s, 30.0);
  EXPECT_DOUBLE_EQ(options->mock.acceleration_deg_per_s2, 90.5);
  EXPECT_DOUBLE_EQ(options->mock.settle_ms, 0.0);
  EXPECT_DOUBLE_EQ(options->mock.time_scale, 1.0);
  EXPECT_DOUBLE_EQ(options->mock.tolerance_deg, 0.5);
  EXPECT_TRUE(options->mock.faults.empty());
}

TEST(TurntableParseOptions, UnknownKeyInTurntableNamesFileLineAndKey) {
  Expected<TurntableOptions> options = ParseText("[turntable]\nbackend = \"mock\"\nsped = 3\n");
  ASSERT_FALSE(options);
  EXPECT_EQ(options.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(options.error().message, HasSubstr("test.toml:3:"));
  EXPECT_THAT(options.error().message, HasSubstr("turntable.sped"));
}

TEST(TurntableParseOptions, UnknownKeyInMockNamesFileLineAndKey) {
  Expected<TurntableOptions> options =
      ParseText("[turntable.mock]\nspeed_deg_per_s = 10\n\nfaults = 1\n");
  ASSERT_FALSE(options);
  EXPECT_EQ(options.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(options.error().message, HasSubstr("test.toml:4:"));
  EXPECT_THAT(options.error().message, HasSubstr("turntable.mock.faults"));
}

TEST(TurntableParseOptions, OutOfRangeValues) {
  struct Case {
    std::string line;
    std::string key;
  };
  for (const Case& c :
       {Case{"time_scale = 0", "time_scale"}, Case{"time_scale = 100.5", "time_scale"},
        Case{"time_scale = -1", "time_scale"}, Case{"speed_deg_per_s = 0", "speed_deg_per_s"},
        Case{"speed_deg_per_s = 1e6", "speed_deg_per_s"},
        Case{"acceleration_deg_per_s2 = -720", "acceleration_deg_per_s2"},
        Case{"settle_ms = -1", "settle_ms"}, Case{"settle_ms = 1e9", "settle_ms"},
        Case{"tolerance_deg = 10", "tolerance_deg"}}) {
    Expected<TurntableOptions> options = ParseText("[turntable.mock]\n" + c.line + "\n");
    ASSERT_FALSE(options) << c.line;
    EXPECT_EQ(options.error().code, ErrorCode::kBadInput) << c.line;
    EXPECT_THAT(options.error().message, HasSubstr("test.toml:2:")) << c.line;
    EXPECT_THAT(options.error().message, HasSubstr("turntable.mock." + c.key)) << c.line;
  }
  // The upper bound of time_scale is inclusive.
  EXPECT_TRUE(ParseText("[turntable.mock]\ntime_scale = 100\n"));
}

TEST(TurntableParseOptions, WrongType) {
  Expected<TurntableOptions> options = ParseText("[turntable.mock]\nspeed_deg_per_s = \"fast\"\n");
  ASSERT_FALSE(options);
  EXPECT_THAT(options.error().message, HasSubstr("expected a number"));
  Expected<TurntableOptions> not_table = ParseText("[turntable]\nmock = 3\n");
  ASSERT_FALSE(not_table);
  EXPECT_THAT(not_table.error().message, HasSubstr("expected a table"));
}

TEST(TurntableParseOptions, BackendsNotBuiltYet) {
  for (const std::string backend : {"modbus", "gpio"}) {
    Expected<TurntableOptions> options = ParseText("[turntable]\nbackend = \"" + backend + "\"\n");
    ASSERT_FALSE(options) << backend;
    EXPECT_EQ(options.error().code, ErrorCode::kUnsupported) << backend;
    EXPECT_THAT(options.error().message, HasSubstr("test.toml:2:"));
    EXPECT_THAT(options.error().message, HasSubstr(backend + " backend is not built yet"));
  }
  Expected<TurntableOptions> table = ParseText("[turntable.modbus]\nunit_id = 1\n");
  ASSERT_FALSE(table);
  EXPECT_EQ(table.error().code, ErrorCode::kUnsupported);
  EXPECT_THAT(table.error().message, HasSubstr("not built yet"));
}

TEST(TurntableParseOptions, UnknownBackend) {
  Expected<TurntableOptions> options = ParseText("[turntable]\nbackend = \"canopen\"\n");
  ASSERT_FALSE(options);
  EXPECT_EQ(options.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(options.error().message, HasSubstr("\"canopen\" is not one of"));
}

TEST(TurntableCreate, MockAndUnsupportedBackends) {
  TurntableOptions options;
  options.mock.time_scale = 0.01;
  Expected<std::unique_ptr<Turntable>> mock = Create(options, nullptr);
  ASSERT_TRUE(mock) << mock.error().ToString();
  EXPECT_THAT((*mock)->Describe(), HasSubstr("mock"));

  options.backend = "modbus";
  Expected<std::unique_ptr<Turntable>> modbus = Create(options, nullptr);
  ASSERT_FALSE(modbus);
  EXPECT_EQ(modbus.error().code, ErrorCode::kUnsupported);

  options.backend = "mock";
  options.mock.speed_deg_per_s = 0.0;
  Expected<std::unique_ptr<Turntable>> bad = Create(options, nullptr);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(bad.error().message, HasSubstr("speed_deg_per_s"));

  options.mock.speed_deg_per_s = 120.0;
  options.mock.faults.push_back(MockFault{.at_fraction = 1.5});
  Expected<std::unique_ptr<Turntable>> bad_fault = Create(options, nullptr);
  ASSERT_FALSE(bad_fault);
  EXPECT_THAT(bad_fault.error().message, HasSubstr("at_fraction"));
}

}  // namespace
}  // namespace revolve::turntable
