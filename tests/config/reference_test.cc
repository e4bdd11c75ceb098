#include "config/reference.h"

#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/config.h"
#include "config/reader.h"

namespace revolve::config {
namespace {

using testing::ElementsAre;
using testing::HasSubstr;

struct Options {
  double speed_deg_per_s = 30.0;
  int stops = 36;
  bool enabled = true;
  std::string method = "otsu";
  std::vector<double> key_bgr;
  std::optional<int> threshold;
};

// A parser as the modules write them.
Expected<Options> ParseTest(const Section& section) {
  Options o;
  Reader r(section);
  r.NumberAbove("speed_deg_per_s", o.speed_deg_per_s, 0.0, 3600.0);
  r.Integer("stops", o.stops, 1, 3600);
  r.Boolean("enabled", o.enabled);
  r.String("method", o.method, {"otsu", "fixed"});
  r.Numbers("key_bgr", o.key_bgr, 0.0, 255.0, 0, 3);
  r.Optional("threshold", o.threshold,
             [&](std::string_view k, int& v) { r.Integer(k, v, 0, 255); });
  if (auto done = r.Finish(); !done) return std::unexpected(done.error());
  return o;
}

Reference Record(std::string text) {
  Reference reference;
  Expected<Document> document = Parse(std::move(text), "test.toml");
  EXPECT_TRUE(document);
  document->reference = &reference;
  Expected<Section> table = Section::Root(*document).Child("scan");
  EXPECT_TRUE(table);
  EXPECT_TRUE(ParseTest(*table));
  return reference;
}

TEST(Reference, RecordsEveryGetterWithItsDefaultAndRange) {
  // The values in the file do not show: the default is what the option held before.
  const Reference reference = Record("[scan]\nstops = 12\nthreshold = 40\n");
  std::vector<std::string> rows;
  for (const KeyRecord& r : reference.keys())
    rows.push_back(r.table + "." + r.key + " " + r.type + " " + r.fallback);
  EXPECT_THAT(rows, ElementsAre("scan.speed_deg_per_s number 30", "scan.stops integer 36",
                                "scan.enabled boolean true", "scan.method string \"otsu\"",
                                "scan.key_bgr numbers []", "scan.threshold integer 0"));
  EXPECT_TRUE(reference.keys()[0].above_min);
  EXPECT_EQ(reference.keys()[4].count, "3 or none");
  EXPECT_TRUE(reference.keys()[5].optional);
}

TEST(Reference, AnOptionalKeyAbsentFromTheFileIsNotRecorded) {
  const Reference reference = Record("");
  EXPECT_EQ(reference.keys().size(), 5u);
}

TEST(Reference, NothingIsRecordedWithoutAReference) {
  Expected<Document> document = Parse("[scan]\nstops = 12\n", "test.toml");
  ASSERT_TRUE(document);
  EXPECT_TRUE(ParseTest(*Section::Root(*document).Child("scan")));
  EXPECT_EQ(Section::Root(*document).Recorded("scan"), nullptr);
}

TEST(Reference, MarkdownHasATablePerSectionWithRangesAndDescriptions) {
  const Reference reference = Record("[scan]\nthreshold = 1\n");
  const TableDoc tables[] = {{"scan", "One scan."}};
  const KeyDoc keys[] = {{"scan", "speed_deg_per_s", "deg/s", "plate speed"},
                         {"scan", "stops", "count", "stops | in one scan"},
                         {"scan", "enabled", "", "on"},
                         {"scan", "method", "", "how"},
                         {"scan", "key_bgr", "B G R", "colour"},
                         {"scan", "threshold", "", "level", "", "", "0 to 255"}};
  const std::string md = MarkdownReference(reference, "# Title\n", tables, keys);
  EXPECT_THAT(md, HasSubstr("Tables: [`[scan]`](#scan)\n\n## `[scan]`\n\nOne scan.\n\n| key |"));
  EXPECT_THAT(md,
              HasSubstr("| `speed_deg_per_s` | number (deg/s) | `30` | (0, 3600] | plate speed |"));
  EXPECT_THAT(
      md, HasSubstr("| `stops` | integer (count) | `36` | [1, 3600] | stops \\| in one scan |"));
  EXPECT_THAT(md, HasSubstr("| `method` | string | `\"otsu\"` | `otsu`, `fixed` | how |"));
  EXPECT_THAT(
      md,
      HasSubstr("| `key_bgr` | numbers (B G R) | `[]` | each in [0, 255]; 3 or none | colour |"));
  EXPECT_THAT(md, HasSubstr("| `threshold` | integer | unset | 0 to 255 | level |"));
  EXPECT_TRUE(ReferenceGaps(reference, tables, keys).empty());
}

TEST(Reference, GapsNameUndescribedKeysAndStaleDescriptions) {
  const Reference reference = Record("");
  const TableDoc tables[] = {{"scan", ""}};
  const KeyDoc keys[] = {{"scan", "speed_deg_per_s", "", "speed"},
                         {"scan", "stops", "", "stops"},
                         {"scan", "enabled", "", ""},
                         {"scan", "method", "", "how"},
                         {"scan", "old_key", "", "gone"}};
  EXPECT_THAT(ReferenceGaps(reference, tables, keys),
              ElementsAre("[scan] key_bgr: no description", "[scan] enabled: empty description",
                          "[scan] old_key: described, but no parser reads it"));
}

TEST(Reference, NumbersAreWrittenWithoutNeedlessFractions) {
  EXPECT_EQ(FormatReferenceNumber(100000000.0), "100000000");
  EXPECT_EQ(FormatReferenceNumber(0.01), "0.01");
  EXPECT_EQ(FormatReferenceNumber(-1.0), "-1");
  EXPECT_EQ(FormatReferenceNumber(1.5), "1.5");
}

}  // namespace
}  // namespace revolve::config
