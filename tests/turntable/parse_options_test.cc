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

TEST(TurntableParseOptions, ModbusKeys) {
  Expected<TurntableOptions> options = ParseText(
      "[turntable]\nbackend = \"modbus\"\ndisable_at_end = false\n[turntable.modbus]\n"
      "transport = \"rtu\"\nport = \"/dev/serial/by-id/usb-x\"\nbaud = 38400\n"
      "parity = \"even\"\nstop_bits = 2\nslave_id = 7\nrs485 = true\n"
      "profile = \"mks_servo42d\"\nsteps_per_rev = 6400\ngear_ratio = 4.5\n"
      "direction = \"reverse\"\nspeed_deg_per_s = 45\ntolerance_deg = 0.1\nretries = 4\n"
      "idle_disable_s = 60\n[turntable.modbus.params]\nacc = 100\n");
  ASSERT_TRUE(options) << options.error().ToString();
  EXPECT_EQ(options->backend, "modbus");
  EXPECT_FALSE(options->disable_at_end);
  const ModbusOptions& m = options->modbus;
  EXPECT_EQ(m.transport, ModbusOptions::Transport::kRtu);
  EXPECT_EQ(m.serial_port, "/dev/serial/by-id/usb-x");
  EXPECT_EQ(m.baud, 38400);
  EXPECT_EQ(m.parity, 'E');
  EXPECT_EQ(m.stop_bits, 2);
  EXPECT_EQ(m.slave_id, 7);
  EXPECT_TRUE(m.rs485);
  EXPECT_EQ(m.profile_path.filename(), "mks_servo42d.toml");
  EXPECT_EQ(m.steps_per_rev, 6400);
  EXPECT_DOUBLE_EQ(m.gear_ratio, 4.5);
  EXPECT_TRUE(m.reverse);
  EXPECT_EQ(m.retries, 4);
  EXPECT_DOUBLE_EQ(m.params.at("acc"), 100.0);
  EXPECT_EQ(DescribeLink(m), "rtu /dev/serial/by-id/usb-x 38400 8E2 slave 7 rs485");

  Expected<TurntableOptions> tcp = ParseText(
      "[turntable]\nbackend = \"modbus\"\n[turntable.modbus]\ntransport = \"tcp\"\n"
      "host = \"10.0.0.5\"\nport = 1502\nunit_id = 3\n");
  ASSERT_TRUE(tcp) << tcp.error().ToString();
  EXPECT_EQ(DescribeLink(tcp->modbus), "tcp 10.0.0.5:1502 unit 3");
  EXPECT_EQ(tcp->modbus.profile_path.filename(), "generic.toml");
}

TEST(TurntableParseOptions, ModbusErrorsNameFileLineAndKey) {
  const std::string head = "[turntable]\nbackend = \"modbus\"\n[turntable.modbus]\n";
  struct Case {
    std::string body;
    std::string expect;
  };
  for (const Case& c :
       {Case{"baud = 25000\n", "test.toml:4:8: turntable.modbus.baud: 25000 is not a standard"},
        Case{"transport = \"tcp\"\n", "turntable.modbus.host: is required"},
        Case{"transport = \"tcp\"\nhost = \"h\"\nport = \"/dev/x\"\n",
             "turntable.modbus.port: expected an integer"},
        Case{"slave_id = 0\n", "turntable.modbus.slave_id"},
        Case{"parity = \"mark\"\n", "\"mark\" is not one of"},
        Case{"profile = \"no_such_drive\"\n",
             "test.toml:4:11: turntable.modbus.profile: no drive "
             "profile \"no_such_drive\""},
        Case{"profile = \"generic\"\n[turntable.modbus.params]\nacc = 1\n",
             "unknown key \"turntable.modbus.params.acc\" (check the spelling; "
             "docs/configuration.md lists every "
             "key) (profile generic has params: none)"},
        Case{"unit = 1\n", "test.toml:4:1: unknown key \"turntable.modbus.unit\""},
        Case{"gear_ratio = 0\n", "turntable.modbus.gear_ratio: must be greater than 0"}}) {
    Expected<TurntableOptions> options = ParseText(head + c.body);
    ASSERT_FALSE(options) << c.body;
    EXPECT_EQ(options.error().code, ErrorCode::kBadInput) << c.body;
    EXPECT_THAT(options.error().message, HasSubstr(c.expect)) << c.body;
  }
}

TEST(TurntableParseOptions, GpioTableIsParsed) {
  Expected<TurntableOptions> options =
      ParseText("[turntable]\nbackend = \"gpio\"\n[turntable.gpio]\nstep = 17\ndir = 27\n");
  ASSERT_TRUE(options) << options.error().ToString();
  EXPECT_EQ(options->gpio.step.offset, 17);
  Expected<TurntableOptions> missing = ParseText("[turntable]\nbackend = \"gpio\"\n");
  ASSERT_FALSE(missing);
  EXPECT_THAT(missing.error().message, HasSubstr("turntable.gpio.step: is required"));
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

  // A real backend opens its device in Create(): a missing serial port is not_found, a missing
  // GPIO chip not_found/no_device (or unsupported in a build without the library).
  options.backend = "modbus";
  options.modbus.serial_port = "/nonexistent/ttyUSB9";
  options.modbus.profile_path =
      std::string(REVOLVE_SOURCE_DIR) + "/turntable/modbus/profiles/generic.toml";
  Expected<std::unique_ptr<Turntable>> modbus = Create(options, nullptr);
  ASSERT_FALSE(modbus);
#ifdef REVOLVE_HAVE_MODBUS
  EXPECT_EQ(modbus.error().code, ErrorCode::kNotFound) << modbus.error().ToString();
#else
  EXPECT_EQ(modbus.error().code, ErrorCode::kUnsupported);
  EXPECT_THAT(modbus.error().message, HasSubstr("REVOLVE_WITH_MODBUS"));
#endif
  options.backend = "gpio";
  options.gpio.chip = "revolve-no-such-chip";
  options.gpio.step.offset = 1;
  options.gpio.dir.offset = 2;
  Expected<std::unique_ptr<Turntable>> gpio = Create(options, nullptr);
  ASSERT_FALSE(gpio);
#ifndef REVOLVE_HAVE_GPIO
  EXPECT_THAT(gpio.error().message, HasSubstr("REVOLVE_WITH_GPIO"));
#endif

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
