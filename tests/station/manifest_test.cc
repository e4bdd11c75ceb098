// Issue 21, causes 2 and 6: a manifest.json read back with a field of the wrong type, out of
// range, or contradicting another is an error naming the file and the field, never an escaped
// exception.
#include "station/manifest.h"

#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace revolve::station {
namespace {

using nlohmann::json;
using testing::HasSubstr;

json ValidManifest() {
  json m = {{"version", 1},
            {"scan_id", "20261126-101010"},
            {"recipe", "default"},
            {"state", "complete"},
            {"started", "2026-11-26T10:10:10.000Z"},
            {"finished", "2026-11-26T10:11:10.000Z"},
            {"config", "<embedded default config>"},
            {"stops_planned", 3},
            {"step_deg", 10.0},
            {"stops_done", 3},
            {"turntable", "mock"},
            {"camera", "synthetic"},
            {"stops", json::array()}};
  for (int i = 0; i < 3; ++i) {
    m["stops"].push_back({{"index", i},
                          {"commanded_deg", 10.0 * i},
                          {"readback_deg", 10.0 * i + 0.01},
                          {"frame", "frames/stop_00" + std::to_string(i) + ".png"},
                          {"mask", "masks/stop_00" + std::to_string(i) + ".png"},
                          {"quality", json::array({{{"code", "blurred"}, {"message", "m"}}})}});
  }
  return m;
}

// Every JSON type, and numbers that are out of any range.
std::vector<json> EveryType() {
  return {json(nullptr),
          json(true),
          json(42),
          json(-1),
          json(1e300),
          json(0.5),
          json("NaN"),
          json(""),
          json::array(),
          json::array({1, 2}),
          json::object(),
          json::object({{"a", 1}}),
          json(std::uint64_t{18446744073709551615ull})};
}

TEST(Manifest, AValidManifestPasses) {
  EXPECT_TRUE(CheckManifest(ValidManifest(), "scan/manifest.json"));
}

// Every field revolve reads, set to every JSON type: either still valid or an error naming the
// file and the field; never an exception.
TEST(Manifest, EveryFieldOfEveryTypeIsAnErrorNamingFileAndFieldOrValid) {
  const json valid = ValidManifest();
  std::vector<std::pair<std::string, json::json_pointer>> fields;
  for (const auto& [key, value] : valid.items()) {
    if (key != "stops") fields.emplace_back(key, json::json_pointer("/" + key));
  }
  for (const auto& [key, value] : valid["stops"][1].items()) {
    fields.emplace_back("stops[1]." + key, json::json_pointer("/stops/1/" + key));
  }
  fields.emplace_back("stops[1].quality[0].code", json::json_pointer("/stops/1/quality/0/code"));
  fields.emplace_back("stops", json::json_pointer("/stops"));
  fields.emplace_back("stops[1]", json::json_pointer("/stops/1"));
  int rejected = 0;
  for (const auto& [name, pointer] : fields) {
    for (const json& value : EveryType()) {
      json m = valid;
      m[pointer] = value;
      Expected<void> checked;
      ASSERT_NO_THROW(checked = CheckManifest(m, "scan/manifest.json")) << name << " = " << value;
      if (checked) continue;
      ++rejected;
      EXPECT_EQ(checked.error().code, ErrorCode::kBadInput);
      EXPECT_THAT(checked.error().message, HasSubstr("scan/manifest.json: "));
      // The field is named (a whole stop or stops array: its path).
      EXPECT_THAT(checked.error().message, HasSubstr(name.substr(0, name.find('.'))))
          << name << " = " << value << ": " << checked.error().message;
    }
  }
  EXPECT_GT(rejected, 100);
}

TEST(Manifest, TheIssuesExamplesAreNamed) {
  const std::vector<std::pair<std::string, json>> cases = {
      {"/stops/1/readback_deg", json(nullptr)},
      {"/stops/1/readback_deg", json("NaN")},
      {"/stops/1/mask", json(42)},
      {"/state", json(5)},
  };
  for (const auto& [pointer, value] : cases) {
    json m = ValidManifest();
    m[json::json_pointer(pointer)] = value;
    const Expected<void> checked = CheckManifest(m, "s/manifest.json");
    ASSERT_FALSE(checked) << pointer;
    EXPECT_THAT(checked.error().message, HasSubstr("s/manifest.json: "));
  }
  json m = ValidManifest();
  m["stops"][1]["readback_deg"] = nullptr;
  EXPECT_THAT(CheckManifest(m, "s/manifest.json").error().message,
              HasSubstr("stops[1].readback_deg: expected a finite number, got null"));
  m = ValidManifest();
  m["state"] = 5;
  EXPECT_THAT(CheckManifest(m, "s/manifest.json").error().message,
              HasSubstr("state: expected a string, got an integer"));
}

TEST(Manifest, AStopListedTwiceIsAContradiction) {
  json m = ValidManifest();
  m["stops"][2]["index"] = 0;
  const Expected<void> checked = CheckManifest(m, "s/manifest.json");
  ASSERT_FALSE(checked);
  EXPECT_THAT(checked.error().message,
              HasSubstr("stops[2].index: stop 0 is listed twice (also stops[0])"));
}

TEST(Manifest, HundredThousandCopiesOfOneStopAreRefusedQuickly) {
  json m = ValidManifest();
  m.erase("stops_planned");
  const json stop = m["stops"][0];
  m["stops"] = json::array();
  for (int i = 0; i < 100000; ++i) m["stops"].push_back(stop);
  const Expected<void> checked = CheckManifest(m, "s/manifest.json");
  ASSERT_FALSE(checked);
  EXPECT_THAT(checked.error().message, HasSubstr("stops: lists 100000 stops"));
}

TEST(Manifest, AStopOutsideThePlannedOnesIsRefused) {
  json m = ValidManifest();
  m["stops"][2]["index"] = 3;
  EXPECT_THAT(CheckManifest(m, "s/manifest.json").error().message,
              HasSubstr("stops[2].index: 3 is out of range [0, 2]"));
}

TEST(Manifest, FilesOutsideTheScanFolderAreRefused) {
  for (const char* path : {"/etc/passwd", "../other/masks/stop_000.png", "masks/../../x.png"}) {
    json m = ValidManifest();
    m["stops"][0]["mask"] = path;
    const Expected<void> checked = CheckManifest(m, "s/manifest.json");
    ASSERT_FALSE(checked) << path;
    EXPECT_THAT(checked.error().message, HasSubstr("stops[0].mask"));
  }
}

TEST(Manifest, AnUnknownStateIsRefused) {
  json m = ValidManifest();
  m["state"] = "finished";
  EXPECT_THAT(CheckManifest(m, "s/manifest.json").error().message,
              HasSubstr("state: \"finished\" is not one of"));
}

}  // namespace
}  // namespace revolve::station
