// The pure core of the Modbus backend: framing, status expressions, profiles (every shipped
// profile is parsed and its commands are compared with golden frames), move variables.
#include <cmath>
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/config.h"
#include "turntable/modbus/expression.h"
#include "turntable/modbus/frame.h"
#include "turntable/modbus/modbus_turntable.h"
#include "turntable/modbus/profile.h"
#include "turntable/modbus/profile_library.h"

namespace revolve::turntable::modbus {
namespace {

using testing::HasSubstr;
namespace fs = std::filesystem;

const fs::path kProfileDir = fs::path(REVOLVE_SOURCE_DIR) / "turntable/modbus/profiles";

DriveProfile Shipped(const std::string& name) {
  Expected<DriveProfile> profile = LoadProfileFile(kProfileDir / (name + ".toml"));
  EXPECT_TRUE(profile) << profile.error().ToString();
  return profile.value_or(DriveProfile{});
}

Expected<DriveProfile> ParseText(const std::string& text) {
  Expected<config::Document> document = config::Parse(text, "test_profile.toml");
  if (!document) return std::unexpected(document.error());
  return ParseProfile(*document, "test_profile");
}

// --- framing ---

TEST(ModbusFrame, CrcMatchesVendorExampleFrames) {
  // Oriental FAQ 0331: write -1000 to 0x1802 (FC16); Leadshine CS2RS manual p.50: PR0 frame and
  // its reply. The last two bytes are the CRC, low byte first.
  for (const char* hex : {"01 10 18 02 00 02 04 FF FF FC 18 99 58",
                          "07 10 62 00 00 08 10 00 01 00 00 27 10 00 00 27 10 27 10 00 00 00 10 "
                          "8D 50",
                          "07 10 62 00 00 08 DE 11"}) {
    const std::vector<std::uint8_t> frame = FromHex(hex);
    const std::uint16_t crc = Crc16(std::span(frame).first(frame.size() - 2));
    EXPECT_EQ(crc & 0xFF, frame[frame.size() - 2]) << hex;
    EXPECT_EQ(crc >> 8, frame[frame.size() - 1]) << hex;
  }
}

TEST(ModbusFrame, EncodesEveryRequestKind) {
  Request read{FunctionCode::kReadInputRegisters, 0x00F1, 1, {}};
  EXPECT_EQ(ToHex(EncodeRtuAdu(1, EncodeRequestPdu(read))), "01 04 00 F1 00 01 60 39");
  Request coil{FunctionCode::kWriteSingleCoil, 0x0010, 0, {1}};
  EXPECT_EQ(ToHex(EncodeRequestPdu(coil)), "05 00 10 FF 00");
  Request single{FunctionCode::kWriteSingleRegister, 0x00F3, 0, {1}};
  EXPECT_EQ(ToHex(EncodeRtuAdu(1, EncodeRequestPdu(single))), "01 06 00 F3 00 01 B8 39");
  Request multi{FunctionCode::kWriteMultipleRegisters, 0x0010, 0, {1, 2}};
  EXPECT_EQ(ToHex(EncodeTcpAdu(0x1234, 7, EncodeRequestPdu(multi))),
            "12 34 00 00 00 0B 07 10 00 10 00 02 04 00 01 00 02");
}

TEST(ModbusFrame, DecodesRequestsAndRejectsBadOnes) {
  for (const Request& r : {Request{FunctionCode::kReadHoldingRegisters, 0x1003, 2, {}},
                           Request{FunctionCode::kWriteSingleCoil, 3, 0, {0}},
                           Request{FunctionCode::kWriteSingleRegister, 0x6002, 0, {0x20}},
                           Request{FunctionCode::kWriteMultipleRegisters, 0x58, 0, {1, 2, 3}}}) {
    auto decoded = DecodeRequestPdu(EncodeRequestPdu(r));
    ASSERT_TRUE(decoded) << Describe(r);
    EXPECT_EQ(*decoded, r);
  }
  EXPECT_EQ(DecodeRequestPdu(FromHex("2B 0E 01 00")).error().exception,
            ExceptionCode::kIllegalFunction);
  EXPECT_EQ(DecodeRequestPdu(FromHex("03 00 00 00 7E")).error().exception,  // 126 registers
            ExceptionCode::kIllegalDataValue);
  EXPECT_EQ(DecodeRequestPdu(FromHex("10 00 00 00 02 02 00 01")).error().exception,
            ExceptionCode::kIllegalDataValue);
  EXPECT_EQ(DecodeRequestPdu(FromHex("05 00 00 12 34")).error().exception,
            ExceptionCode::kIllegalDataValue);
}

TEST(ModbusFrame, ResponsesAndRtuLengths) {
  Request read{FunctionCode::kReadHoldingRegisters, 0, 2, {}};
  const std::uint16_t values[] = {0x1234, 0xABCD};
  EXPECT_EQ(ToHex(EncodeResponsePdu(read, values)), "03 04 12 34 AB CD");
  Request multi{FunctionCode::kWriteMultipleRegisters, 0x6200, 0, std::vector<std::uint16_t>(8)};
  // The Leadshine manual's reply to its PR0 example.
  EXPECT_EQ(ToHex(EncodeRtuAdu(7, EncodeResponsePdu(multi, {}))), "07 10 62 00 00 08 DE 11");
  EXPECT_EQ(ToHex(EncodeExceptionPdu(0x06, ExceptionCode::kIllegalDataAddress)), "86 02");
  EXPECT_EQ(RtuRequestLength(FromHex("01")), std::nullopt);
  EXPECT_EQ(RtuRequestLength(FromHex("01 03")), 8u);
  EXPECT_EQ(RtuRequestLength(FromHex("01 10 00 00 00 02")), std::nullopt);
  EXPECT_EQ(RtuRequestLength(FromHex("01 10 00 00 00 02 04")), 13u);
  EXPECT_EQ(RtuRequestLength(FromHex("01 2B")), 0u);
  EXPECT_EQ(ExceptionName(2), "illegal data address");
}

// --- values ---

TEST(ModbusValues, EncodeDecodeWordOrderAndRange) {
  EXPECT_EQ(*EncodeValue(-1000, ValueType::kI32, WordOrder::kHighFirst),
            (std::vector<std::uint16_t>{0xFFFF, 0xFC18}));
  EXPECT_EQ(*EncodeValue(100000, ValueType::kI32, WordOrder::kLowFirst),
            (std::vector<std::uint16_t>{0x86A0, 0x0001}));
  EXPECT_EQ(*EncodeValue(-2, ValueType::kI16, WordOrder::kHighFirst),
            (std::vector<std::uint16_t>{0xFFFE}));
  EXPECT_FALSE(EncodeValue(-1, ValueType::kU16, WordOrder::kHighFirst));
  EXPECT_FALSE(EncodeValue(70000, ValueType::kU16, WordOrder::kHighFirst));
  EXPECT_FALSE(EncodeValue(1LL << 31, ValueType::kI32, WordOrder::kHighFirst));
  const std::uint16_t high_first[] = {0xFFFF, 0xFC18};
  EXPECT_EQ(DecodeValue(high_first, ValueType::kI32, WordOrder::kHighFirst), -1000);
  EXPECT_EQ(DecodeValue(high_first, ValueType::kU32, WordOrder::kHighFirst), 0xFFFFFC18);
  const std::uint16_t low_first[] = {0x86A0, 0x0001};
  EXPECT_EQ(DecodeValue(low_first, ValueType::kI32, WordOrder::kLowFirst), 100000);
  EXPECT_EQ(DecodeValue(high_first, ValueType::kI16, WordOrder::kHighFirst), -1);
}

// --- expressions ---

TEST(StatusExpression, EvaluatesTheGrammar) {
  struct Case {
    const char* text;
    FieldValues values;
    bool expected;
  };
  const Case cases[] = {
      {"status in [2, 3, 4, 5, 6]", {{"status", 4}}, true},
      {"status in [2, 3, 4, 5, 6]", {{"status", 1}}, false},
      {"st.bit5 && !st.bit2", {{"st", 0x20}}, true},
      {"st.bit5 && !st.bit2", {{"st", 0x24}}, false},
      {"status == 0 || stall == 1", {{"status", 1}, {"stall", 1}}, true},
      {"status == 0 || stall == 1", {{"status", 1}, {"stall", 0}}, false},
      {"!(a == 1 && b != 2)", {{"a", 1}, {"b", 2}}, true},
      {"x >= -5 && x < 0x10", {{"x", -5}}, true},
      {"x > 15", {{"x", 0x10}}, true},
      {"x <= 3", {{"x", 4}}, false},
      {"enabled", {{"enabled", 7}}, true},
      {"missing", {}, false},
      {"true && !false", {}, true},
      {"out.bit31", {{"out", 0x80000000LL}}, true},
  };
  for (const Case& c : cases) {
    Expected<StatusExpression> e = StatusExpression::Parse(c.text);
    ASSERT_TRUE(e) << c.text << ": " << e.error().message;
    EXPECT_EQ(e->Evaluate(c.values), c.expected) << c.text;
  }
  EXPECT_EQ(StatusExpression::Parse("a && st.bit3 || b == 1")->Fields(),
            (std::set<std::string>{"a", "b", "st"}));
}

TEST(StatusExpression, ErrorsNameTheColumn) {
  for (const auto& [text, column] :
       std::vector<std::pair<std::string, std::string>>{{"status ==", "column 10"},
                                                        {"st.bit40", "column"},
                                                        {"a && (b", "column 8"},
                                                        {"a in [1, 2", "column 11"},
                                                        {"a b", "column 3"},
                                                        {"", "column 1"},
                                                        {"3 == a", "column 1"}}) {
    Expected<StatusExpression> e = StatusExpression::Parse(text);
    ASSERT_FALSE(e) << text;
    EXPECT_EQ(e.error().code, ErrorCode::kBadInput);
    EXPECT_THAT(e.error().message, HasSubstr(column)) << text;
  }
}

// --- profiles ---

constexpr char kMinimal[] = R"(
[profile]
steps_per_rev = 200
[fields.position]
address = 0x10
type = "i32"
[fields.st]
table = "input"
address = 0
[commands]
move = ["write_registers 0x10 ${target:i32}"]
stop = ["write_register 0 5"]
[status]
moving = "st.bit1"
)";

TEST(DriveProfileParse, MinimalProfile) {
  Expected<DriveProfile> p = ParseText(kMinimal);
  ASSERT_TRUE(p) << p.error().ToString();
  EXPECT_EQ(p->steps_per_rev, 200);
  EXPECT_EQ(p->position().type, ValueType::kI32);
  EXPECT_EQ(p->fields.at("st").table, RegisterTable::kInput);
  EXPECT_FALSE(p->status.alarm);
  EXPECT_EQ(p->FindCommand("home"), nullptr);
}

TEST(DriveProfileParse, ErrorsNameFileLineAndKey) {
  struct Case {
    std::string replace;  // appended to the minimal profile, or a whole-line replacement
    std::string with;
    std::string expect;
  };
  const Case cases[] = {
      {"moving = \"st.bit1\"", "moving = \"st.bit1\"\nalarm = \"nope == 1\"",
       "test_profile.toml:15:9: status.alarm: \"nope\" is not a field"},
      {"stop = [\"write_register 0 5\"]", "stop = [\"write_reg 0 5\"]",
       "test_profile.toml:12:8: commands.stop: step 1: unknown operation \"write_reg\""},
      {"stop = [\"write_register 0 5\"]", "stop = [\"write_register 0 ${target:i32}\"]",
       "commands.stop: step 1: write_register (FC06) takes exactly one 16-bit value"},
      {"stop = [\"write_register 0 5\"]", "stop = [\"write_register 0 ${speed}\"]",
       "unknown variable ${speed}"},
      {"stop = [\"write_register 0 5\"]", "stop = [\"write_register 0x10000 5\"]",
       "the address must be 0..0xFFFF"},
      {"stop = [\"write_register 0 5\"]", "stop = [\"write_register 0 70000\"]",
       "70000 does not fit u16"},
      {"stop = [\"write_register 0 5\"]", "stop = [\"write_coil 1 2\"]",
       "write_coil takes one value, 0 or 1"},
      {"stop = [\"write_register 0 5\"]", "stop = [\"sleep_ms 20000\"]", "sleep_ms N"},
      {"stop = [\"write_register 0 5\"]", "", "commands.stop: is required"},
      {"stop = [\"write_register 0 5\"]", "stop = [\"write_register 0 5\"]\nfly = [\"sleep_ms 1\"]",
       "test_profile.toml:13:7: commands.fly: unknown command"},
      {"type = \"i32\"", "type = \"i64\"", "test_profile.toml:6:8: fields.position.type"},
      {"address = 0x10", "adress = 0x10", "fields.position.address: is required"},
      {"steps_per_rev = 200", "steps_per_rev = 200\nspeed = 3",
       "test_profile.toml:4:1: unknown key \"profile.speed\""},
      {"moving = \"st.bit1\"", "moving = \"st.bit1 &&\"", "status.moving: column 11"},
  };
  for (const Case& c : cases) {
    std::string text = kMinimal;
    const std::size_t at = text.find(c.replace);
    ASSERT_NE(at, std::string::npos) << c.replace;
    text.replace(at, c.replace.size(), c.with);
    Expected<DriveProfile> p = ParseText(text);
    ASSERT_FALSE(p) << c.with;
    EXPECT_EQ(p.error().code, ErrorCode::kBadInput);
    EXPECT_THAT(p.error().message, HasSubstr(c.expect)) << text;
  }
  Expected<DriveProfile> no_position =
      ParseText("[profile]\nsteps_per_rev = 1\n[commands]\nmove = [\"sleep_ms 1\"]\n");
  ASSERT_FALSE(no_position);
  EXPECT_THAT(no_position.error().message, HasSubstr("fields.position: is required"));
}

TEST(DriveProfileParse, EveryShippedProfileParsesAndIsFound) {
  const std::vector<std::string> names = {"generic", "leadshine_pr", "mks_servo42d", "oriental_az"};
  for (const std::string& name : names) {
    DriveProfile p = Shipped(name);
    EXPECT_EQ(p.name, name);
    for (const char* command : {"enable", "disable", "move", "home", "stop", "reset_alarm"}) {
      EXPECT_NE(p.FindCommand(command), nullptr) << name << " " << command;
    }
    EXPECT_TRUE(p.status.alarm) << name;
    EXPECT_TRUE(p.status.alarm_code_field) << name;
    EXPECT_FALSE(p.alarm_texts.empty()) << name;
    Expected<fs::path> found = FindProfile(name, {});
    ASSERT_TRUE(found) << found.error().message;
    EXPECT_EQ(found->filename(), name + ".toml");
  }
  const std::vector<std::string> listed = ListProfiles();
  for (const std::string& name : names) {
    EXPECT_NE(std::find(listed.begin(), listed.end(), name), listed.end()) << name;
  }
}

TEST(DriveProfileParse, FindProfileByPathAndErrors) {
  Expected<fs::path> relative = FindProfile("generic.toml", kProfileDir);
  ASSERT_TRUE(relative) << relative.error().message;
  Expected<fs::path> missing = FindProfile("no_such_drive", {});
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_THAT(missing.error().message, HasSubstr("generic"));  // lists what exists
  EXPECT_FALSE(FindProfile("./nope.toml", kProfileDir));
}

TEST(DriveProfileParse, FieldReadsMergeOnlyAdjacentFields) {
  DriveProfile generic = Shipped("generic");
  std::vector<FieldRead> reads = PlanFieldReads(generic);
  ASSERT_EQ(reads.size(), 1u);  // status, alarm code, position: input 0..3
  EXPECT_EQ(reads[0].address, 0);
  EXPECT_EQ(reads[0].count, 4);
  DriveProfile mks = Shipped("mks_servo42d");
  reads = PlanFieldReads(mks);
  // 0x33-34 position, 0x3A en, 0x3B goback (merged), 0x3E stall, 0xF1 status.
  ASSERT_EQ(reads.size(), 4u);
  EXPECT_EQ(reads[1].address, 0x3A);
  EXPECT_EQ(reads[1].count, 2);
  FieldValues values;
  const std::uint16_t registers[] = {0xFFFF, 0xFC18};
  DecodeFields(mks, reads[0], registers, values);
  EXPECT_EQ(values.at("position"), -1000);
}

// Renders `command` and returns the RTU frames for slave `slave`.
std::vector<std::string> Frames(const DriveProfile& profile, const std::string& command,
                                const Variables& variables, std::uint8_t slave = 1) {
  Variables all(profile.params.begin(), profile.params.end());
  for (const auto& [k, v] : variables) all[k] = v;
  Expected<std::vector<RenderedStep>> steps =
      RenderCommand(profile, *profile.FindCommand(command), all);
  EXPECT_TRUE(steps) << steps.error().message;
  std::vector<std::string> frames;
  for (const RenderedStep& step : steps.value_or(std::vector<RenderedStep>{})) {
    if (step.request) frames.push_back(ToHex(EncodeRtuAdu(slave, EncodeRequestPdu(*step.request))));
  }
  return frames;
}

using Frames_ = std::vector<std::string>;

// Expected frames from tests/turntable/peers/golden_frames.py (pymodbus's encoder and CRC).
TEST(ProfileGoldenFrames, Generic) {
  const DriveProfile p = Shipped("generic");
  EXPECT_EQ(Frames(p, "enable", {}), Frames_{"01 06 00 00 00 01 48 0A"});
  EXPECT_EQ(Frames(p, "move", {{"target", 12345}, {"speed_hz", 1600}, {"accel_hz_s", 4000}}),
            (Frames_{"01 10 00 10 00 06 0C 00 00 30 39 00 00 06 40 00 00 0F A0 3D 94",
                     "01 06 00 00 00 03 C9 CB"}));
  EXPECT_EQ(Frames(p, "home", {}), Frames_{"01 06 00 00 00 04 88 09"});
  EXPECT_EQ(Frames(p, "stop", {}), Frames_{"01 06 00 00 00 05 49 C9"});
}

TEST(ProfileGoldenFrames, MksServo42d) {
  const DriveProfile p = Shipped("mks_servo42d");
  EXPECT_EQ(Frames(p, "enable", {}), Frames_{"01 06 00 F3 00 01 B8 39"});
  EXPECT_EQ(Frames(p, "move", {{"target", 12345}, {"speed_rpm", 60}}),  // acc: param 240
            Frames_{"01 10 00 FE 00 04 08 00 F0 00 3C 00 00 30 39 68 B4"});
  EXPECT_EQ(Frames(p, "home", {}), Frames_{"01 06 00 91 00 01 19 E7"});
  EXPECT_EQ(Frames(p, "stop", {}), Frames_{"01 06 00 F7 00 01 F9 F8"});
}

TEST(ProfileGoldenFrames, LeadshinePrMatchesTheVendorExample) {
  const DriveProfile p = Shipped("leadshine_pr");
  EXPECT_EQ(Frames(p, "enable", {}), Frames_{"01 06 00 0F 00 01 78 09"});
  EXPECT_EQ(Frames(p, "move", {{"target", 12345}, {"speed_rpm", 60}, {"accel_ms_per_krpm", 1000}}),
            Frames_{"01 10 62 00 00 08 10 00 01 00 00 30 39 00 3C 03 E8 03 E8 00 00 00 10 4B A7"});
  EXPECT_EQ(Frames(p, "home", {}), Frames_{"01 06 60 02 00 20 37 D2"});
  EXPECT_EQ(Frames(p, "stop", {}), Frames_{"01 06 60 02 00 40 37 FA"});
  // CS2RS manual p.50, slave 7: PR0 absolute to 10000 pulses, velocity word 0, acc/dec 10000.
  EXPECT_EQ(
      Frames(p, "move", {{"target", 10000}, {"speed_rpm", 0}, {"accel_ms_per_krpm", 10000}}, 7),
      Frames_{"07 10 62 00 00 08 10 00 01 00 00 27 10 00 00 27 10 27 10 00 00 00 10 8D 50"});
}

TEST(ProfileGoldenFrames, OrientalAzMatchesTheVendorExample) {
  const DriveProfile p = Shipped("oriental_az");
  EXPECT_EQ(Frames(p, "enable", {}), Frames_{"01 10 00 7C 00 02 04 00 00 00 00 F4 DE"});
  EXPECT_EQ(Frames(p, "move", {{"target", 12345}, {"speed_hz", 1000}, {"accel_hz_s", 3000}}),
            Frames_{"01 10 00 58 00 10 20 00 00 00 00 00 00 00 01 00 00 30 39 00 00 03 E8 00 00 "
                    "0B B8 00 00 0B B8 00 00 03 E8 00 00 00 01 57 BE"});
  EXPECT_EQ(Frames(p, "home", {}), Frames_{"01 10 00 78 00 02 04 00 00 00 10 F4 E1"});
  EXPECT_EQ(Frames(p, "stop", {}), Frames_{"01 10 00 78 00 02 04 00 00 00 20 F4 F5"});
  // Oriental FAQ 0331: -1000 written to 0x1802 as a 32-bit pair in the profile's word order.
  Expected<std::vector<std::uint16_t>> value = EncodeValue(-1000, ValueType::kI32, p.word_order);
  ASSERT_TRUE(value);
  Request request{FunctionCode::kWriteMultipleRegisters, 0x1802, 0, *value};
  EXPECT_EQ(ToHex(EncodeRtuAdu(1, EncodeRequestPdu(request))),
            "01 10 18 02 00 02 04 FF FF FC 18 99 58");
}

TEST(ProfileRender, ValueThatDoesNotFitNamesTheCommand) {
  const DriveProfile p = Shipped("mks_servo42d");
  Variables v(p.params.begin(), p.params.end());
  v["target"] = 0;
  v["speed_rpm"] = 70000;
  Expected<std::vector<RenderedStep>> steps = RenderCommand(p, *p.FindCommand("move"), v);
  ASSERT_FALSE(steps);
  EXPECT_THAT(steps.error().message, HasSubstr("mks_servo42d"));
  EXPECT_THAT(steps.error().message, HasSubstr("${speed_rpm} = 70000 does not fit u16"));
  v.erase("speed_rpm");
  steps = RenderCommand(p, *p.FindCommand("move"), v);
  ASSERT_FALSE(steps);
  EXPECT_THAT(steps.error().message, HasSubstr("${speed_rpm} has no value"));
}

TEST(ProfileRender, FactorsSleepsAndCoils) {
  Expected<DriveProfile> p = ParseText(std::string(kMinimal) + R"(
[commands.x]
)");
  ASSERT_FALSE(p);  // [commands.x] is a table, not a list of steps
  std::string text = kMinimal;
  text.replace(text.find("stop = "), 0,
               "home = [\"write_coil 0x20 1\", \"sleep_ms 5\", \"write_coil 0x20 0\"]\n");
  text.replace(text.find("move = [\"write_registers 0x10 ${target:i32}\"]"),
               std::string("move = [\"write_registers 0x10 ${target:i32}\"]").size(),
               "move = [\"write_registers 0x10 ${target:i32} ${speed_rpm*10:u16}\"]");
  p = ParseText(text);
  ASSERT_TRUE(p) << p.error().message;
  Expected<std::vector<RenderedStep>> home = RenderCommand(*p, *p->FindCommand("home"), {});
  ASSERT_TRUE(home);
  ASSERT_EQ(home->size(), 3u);
  EXPECT_EQ((*home)[0].request->function, FunctionCode::kWriteSingleCoil);
  EXPECT_EQ((*home)[1].sleep_ms, 5);
  EXPECT_EQ((*home)[2].request->values, std::vector<std::uint16_t>{0});
  Expected<std::vector<RenderedStep>> move =
      RenderCommand(*p, *p->FindCommand("move"), {{"target", -2}, {"speed_rpm", 12.34}});
  ASSERT_TRUE(move);
  EXPECT_EQ((*move)[0].request->values, (std::vector<std::uint16_t>{0xFFFF, 0xFFFE, 123}));
}

// --- kinematics ---

TEST(ModbusKinematics, MoveVariablesFromPlateUnits) {
  Kinematics k;
  k.steps_per_rev = 3200;
  k.gear_ratio = 5;
  EXPECT_DOUBLE_EQ(k.CountsPerPlateRev(), 16000);
  EXPECT_DOUBLE_EQ(k.CountsFromDeg(10), 16000.0 / 36);
  k.reverse = true;
  EXPECT_DOUBLE_EQ(k.CountsFromDeg(90), -4000);
  EXPECT_DOUBLE_EQ(k.DegFromCounts(-4000), 90);
  k.reverse = false;
  // 36 deg/s plate = 0.1 rev/s = 0.5 motor rev/s = 30 rpm = 1600 Hz.
  const Variables v = MoveVariables(k, 4000, 1000, 36.0, 72.0, {{"acc", 7}});
  EXPECT_DOUBLE_EQ(v.at("target"), 4000);
  EXPECT_DOUBLE_EQ(v.at("delta"), 3000);
  EXPECT_DOUBLE_EQ(v.at("speed_rpm"), 30);
  EXPECT_DOUBLE_EQ(v.at("speed_hz"), 1600);
  EXPECT_DOUBLE_EQ(v.at("accel_rpm_s"), 60);
  EXPECT_DOUBLE_EQ(v.at("accel_hz_s"), 3200);
  EXPECT_DOUBLE_EQ(v.at("accel_ms"), 500);
  EXPECT_NEAR(v.at("accel_ms_per_krpm"), 1000.0 / 60 * 1000, 1e-9);
  EXPECT_DOUBLE_EQ(v.at("acc"), 7);
}

TEST(ModbusKinematics, AlarmTextUsesTheProfileWords) {
  const DriveProfile p = Shipped("leadshine_pr");
  EXPECT_THAT(AlarmText(p, 0xE0), HasSubstr("over-current"));
  EXPECT_THAT(AlarmText(p, 0x77), HasSubstr("alarm 0x77 (see the alarm list"));
  EXPECT_THAT(AlarmText(p, std::nullopt), HasSubstr("home the table"));
}

}  // namespace
}  // namespace revolve::turntable::modbus
