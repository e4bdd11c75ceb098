#include "config/config.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace revolve::config {
namespace {

using testing::HasSubstr;
using testing::StartsWith;

Document MustParse(std::string text) {
  Expected<Document> document = Parse(std::move(text), "test.toml");
  EXPECT_TRUE(document) << document.error().ToString();
  return document ? std::move(*document) : Document{};
}

Section MustChild(const Section& section, std::string_view key) {
  Expected<Section> child = section.Child(key);
  EXPECT_TRUE(child) << child.error().ToString();
  return *child;
}

// A private temporary directory, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::string pattern =
        (std::filesystem::temp_directory_path() / "revolve-config-test-XXXXXX").string();
    path_ = mkdtemp(pattern.data());
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

TEST(ConfigParse, SyntaxErrorNamesOriginLineAndColumn) {
  Expected<Document> document = Parse("[scan]\nstops = 36\nstep_deg = = 10\n", "rig.toml");
  ASSERT_FALSE(document);
  EXPECT_EQ(document.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(document.error().message, StartsWith("rig.toml:3:"));
  EXPECT_THAT(document.error().message, testing::MatchesRegex("rig\\.toml:3:[0-9]+: .+"));
}

TEST(ConfigParse, DuplicateKeyIsASyntaxError) {
  Expected<Document> document = Parse("a = 1\nb = 2\na = 3\n", "dup.toml");
  ASSERT_FALSE(document);
  EXPECT_THAT(document.error().message, StartsWith("dup.toml:3:"));
}

TEST(ConfigParse, EmbeddedDefaultParsesAndHasEveryModuleTable) {
  Expected<Document> document = Parse(std::string(EmbeddedDefault()), std::string(kEmbeddedOrigin));
  ASSERT_TRUE(document) << document.error().ToString();
  EXPECT_EQ(document->origin, kEmbeddedOrigin);
  const Section root = Section::Root(*document);
  for (std::string_view table : {"scan", "turntable", "camera", "segment", "reconstruct"}) {
    EXPECT_TRUE(root.Has(table)) << table;
  }
  EXPECT_EQ(MustChild(root, "turntable").String("backend", "").value_or(""), "mock");
  EXPECT_TRUE(MustChild(MustChild(root, "turntable"), "mock").Has("time_scale"));
}

TEST(ConfigLoadFile, MissingFileIsNotFoundAndNamesThePath) {
  TempDir dir;
  const std::filesystem::path path = dir.path() / "nope.toml";
  Expected<Document> document = LoadFile(path);
  ASSERT_FALSE(document);
  EXPECT_EQ(document.error().code, ErrorCode::kNotFound);
  EXPECT_THAT(document.error().message, HasSubstr(path.string()));
}

TEST(ConfigLoadFile, DirectoryIsBadInput) {
  TempDir dir;
  Expected<Document> document = LoadFile(dir.path());
  ASSERT_FALSE(document);
  EXPECT_EQ(document.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(document.error().message, HasSubstr(dir.path().string()));
}

TEST(ConfigLoadFile, ReadsAFileAndItsErrorsNameIt) {
  TempDir dir;
  const std::filesystem::path good = dir.path() / "good.toml";
  std::ofstream(good) << "[scan]\nstops = 12\n";
  Expected<Document> document = LoadFile(good);
  ASSERT_TRUE(document) << document.error().ToString();
  EXPECT_EQ(document->origin, good.string());
  const Section scan = MustChild(Section::Root(*document), "scan");
  EXPECT_EQ(scan.Integer("stops", 36, 1, 3600).value_or(0), 12);
  Expected<std::int64_t> out_of_range = scan.Integer("stops", 36, 24, 3600);
  ASSERT_FALSE(out_of_range);
  EXPECT_THAT(out_of_range.error().message, StartsWith(good.string() + ":2:"));

  const std::filesystem::path bad = dir.path() / "bad.toml";
  std::ofstream(bad) << "[scan\n";
  Expected<Document> broken = LoadFile(bad);
  ASSERT_FALSE(broken);
  EXPECT_EQ(broken.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(broken.error().message, StartsWith(bad.string() + ":1:"));
}

TEST(ConfigSection, Numbers) {
  const Document document = MustParse("[t]\nf = 2.5\ni = 3\ns = \"x\"\nbig = 1e9\n");
  const Section t = MustChild(Section::Root(document), "t");
  EXPECT_EQ(t.Number("f", 0.0, 0.0, 10.0).value_or(-1), 2.5);
  EXPECT_EQ(t.Number("i", 0.0, 0.0, 10.0).value_or(-1), 3.0);  // integers are numbers
  EXPECT_EQ(t.Number("absent", 7.5, 0.0, 10.0).value_or(-1), 7.5);
  EXPECT_EQ(t.Number("f", 0.0, 2.5, 2.5).value_or(-1), 2.5);  // bounds are inclusive

  Expected<double> wrong_type = t.Number("s", 0.0, 0.0, 10.0);
  ASSERT_FALSE(wrong_type);
  EXPECT_EQ(wrong_type.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(wrong_type.error().message, StartsWith("test.toml:4:"));
  EXPECT_THAT(wrong_type.error().message, HasSubstr("t.s: expected a number"));

  Expected<double> out_of_range = t.Number("big", 0.0, 0.0, 10.0);
  ASSERT_FALSE(out_of_range);
  EXPECT_THAT(out_of_range.error().message, StartsWith("test.toml:5:"));
  EXPECT_THAT(out_of_range.error().message, HasSubstr("t.big"));
  EXPECT_THAT(out_of_range.error().message, HasSubstr("out of range"));
}

TEST(ConfigSection, IntegersBooleansAndStrings) {
  const Document document =
      MustParse("[t]\nn = 4\nf = 4.5\nb = true\nmode = \"otsu\"\nother = \"magic\"\n");
  const Section t = MustChild(Section::Root(document), "t");
  EXPECT_EQ(t.Integer("n", 0, 0, 10).value_or(-1), 4);
  EXPECT_EQ(t.Integer("absent", 9, 0, 10).value_or(-1), 9);
  Expected<std::int64_t> not_integer = t.Integer("f", 0, 0, 10);
  ASSERT_FALSE(not_integer);
  EXPECT_THAT(not_integer.error().message, HasSubstr("expected an integer"));
  Expected<std::int64_t> too_small = t.Integer("n", 0, 5, 10);
  ASSERT_FALSE(too_small);
  EXPECT_THAT(too_small.error().message, StartsWith("test.toml:2:"));

  EXPECT_EQ(t.Boolean("b", false).value_or(false), true);
  EXPECT_EQ(t.Boolean("absent", true).value_or(false), true);
  EXPECT_THAT(t.Boolean("n", false).error().message, HasSubstr("expected true or false"));

  EXPECT_EQ(t.String("mode", "", {"otsu", "fixed"}).value_or(""), "otsu");
  EXPECT_EQ(t.String("other", "").value_or(""), "magic");  // no list: any string
  EXPECT_EQ(t.String("absent", "fixed", {"otsu", "fixed"}).value_or(""), "fixed");
  Expected<std::string> not_allowed = t.String("other", "", {"otsu", "fixed"});
  ASSERT_FALSE(not_allowed);
  EXPECT_THAT(not_allowed.error().message, StartsWith("test.toml:6:"));
  EXPECT_THAT(not_allowed.error().message,
              HasSubstr("\"magic\" is not one of \"otsu\", \"fixed\""));
  EXPECT_THAT(t.String("n", "").error().message, HasSubstr("expected a string"));
}

TEST(ConfigSection, Arrays) {
  const Document document = MustParse(
      "[t]\nbbox = [0, 1.5, 2, 3, 4, 5]\nformats = [\"ply\", \"wrl\"]\nmixed = [1, \"a\"]\n");
  const Section t = MustChild(Section::Root(document), "t");
  EXPECT_EQ(t.Numbers("bbox", {}, 6).value_or(std::vector<double>{}),
            (std::vector<double>{0, 1.5, 2, 3, 4, 5}));
  EXPECT_EQ(t.Numbers("bbox", {}).value_or(std::vector<double>{}).size(), 6u);
  EXPECT_EQ(t.Numbers("absent", {1.0}).value_or(std::vector<double>{}), (std::vector<double>{1.0}));
  Expected<std::vector<double>> wrong_count = t.Numbers("bbox", {}, 3);
  ASSERT_FALSE(wrong_count);
  EXPECT_THAT(wrong_count.error().message, HasSubstr("expected 3 numbers, got 6"));
  EXPECT_FALSE(t.Numbers("mixed", {}));
  EXPECT_FALSE(t.Numbers("formats", {}));

  EXPECT_EQ(t.Strings("formats", {}).value_or(std::vector<std::string>{}),
            (std::vector<std::string>{"ply", "wrl"}));
  EXPECT_EQ(t.Strings("absent", {"glb"}).value_or(std::vector<std::string>{}),
            (std::vector<std::string>{"glb"}));
  Expected<std::vector<std::string>> mixed = t.Strings("mixed", {});
  ASSERT_FALSE(mixed);
  EXPECT_THAT(mixed.error().message, HasSubstr("expected an array of strings"));
  EXPECT_FALSE(t.Strings("bbox", {}));
}

TEST(ConfigSection, ChildTablesAndDottedPaths) {
  const Document document = MustParse(
      "[turntable]\nbackend = \"mock\"\n[turntable.mock]\n"
      "speed_deg_per_s = \"fast\"\n");
  const Section root = Section::Root(document);
  EXPECT_EQ(root.path(), "");
  EXPECT_EQ(root.origin(), "test.toml");
  const Section turntable = MustChild(root, "turntable");
  EXPECT_EQ(turntable.path(), "turntable");
  const Section mock = MustChild(turntable, "mock");
  EXPECT_EQ(mock.path(), "turntable.mock");
  Expected<double> speed = mock.Number("speed_deg_per_s", 1.0, 0.0, 10.0);
  ASSERT_FALSE(speed);
  EXPECT_THAT(speed.error().message, StartsWith("test.toml:4:"));
  EXPECT_THAT(speed.error().message, HasSubstr("turntable.mock.speed_deg_per_s"));

  Expected<Section> not_a_table = turntable.Child("backend");
  ASSERT_FALSE(not_a_table);
  EXPECT_THAT(not_a_table.error().message, HasSubstr("expected a table"));
}

TEST(ConfigSection, AMissingTableBehavesAsEmpty) {
  const Document document = MustParse("[scan]\nstops = 36\n");
  const Section camera = MustChild(Section::Root(document), "camera");
  EXPECT_EQ(camera.path(), "camera");
  EXPECT_FALSE(camera.Has("backend"));
  EXPECT_EQ(camera.String("backend", "synthetic").value_or(""), "synthetic");
  EXPECT_EQ(camera.Number("hfov_deg", 30.0, 1.0, 179.0).value_or(0.0), 30.0);
  const Section deeper = MustChild(camera, "synthetic");
  EXPECT_EQ(deeper.path(), "camera.synthetic");
  EXPECT_TRUE(deeper.CheckNoUnknownKeys());
  EXPECT_TRUE(camera.CheckNoUnknownKeys());
  // BadValue still names the file.
  EXPECT_THAT(camera.BadValue("backend", "nope").message, StartsWith("test.toml"));
}

TEST(ConfigSection, UnknownKeysNameFileLineAndDottedKey) {
  const Document document =
      MustParse("[scan]\nstops = 36\nstep_dg = 10\n[scan.extra]\nx = 1\n[bogus]\ny = 2\n");
  const Section root = Section::Root(document);
  const Section scan = MustChild(root, "scan");
  ASSERT_TRUE(scan.Integer("stops", 36, 1, 360));
  Expected<void> unknown = scan.CheckNoUnknownKeys();
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error().code, ErrorCode::kBadInput);
  // The first unknown key in the file is named (not the alphabetically first, "extra").
  EXPECT_THAT(unknown.error().message, StartsWith("test.toml:3:1:"));
  EXPECT_THAT(unknown.error().message, HasSubstr("unknown key \"scan.step_dg\""));

  // Reading a key (even through a copy, even when absent from the file) marks it as known;
  // a sub-table is known once Child() asked for it and checked on its own.
  const Section copy = scan;  // NOLINT(performance-unnecessary-copy-initialization)
  ASSERT_TRUE(copy.Number("step_dg", 10.0, 0.0, 360.0));
  Expected<void> extra = scan.CheckNoUnknownKeys();
  ASSERT_FALSE(extra);
  EXPECT_THAT(extra.error().message, HasSubstr("unknown key \"scan.extra\""));
  const Section sub = MustChild(scan, "extra");
  EXPECT_TRUE(scan.CheckNoUnknownKeys());
  Expected<void> in_sub = sub.CheckNoUnknownKeys();
  ASSERT_FALSE(in_sub);
  EXPECT_THAT(in_sub.error().message, StartsWith("test.toml:5:"));
  EXPECT_THAT(in_sub.error().message, HasSubstr("scan.extra.x"));

  // The root's unknown top-level table ("scan" is known: Child() asked for it).
  Expected<void> top = root.CheckNoUnknownKeys();
  ASSERT_FALSE(top);
  EXPECT_THAT(top.error().message, StartsWith("test.toml:6:"));
  EXPECT_THAT(top.error().message, HasSubstr("unknown key \"bogus\""));
}

}  // namespace
}  // namespace revolve::config

namespace revolve::config {
namespace {

// Issue 21, cause 1: nan, inf and integers a double cannot hold exactly never pass a number key,
// whatever its range; the error names file:line:column and the key.
TEST(ConfigSection, NonFiniteAndUnrepresentableNumbersAreErrorsNamingTheKey) {
  for (const char* value : {"nan", "+nan", "-nan", "inf", "-inf", "9007199254740993",
                            "-9007199254740993", "9223372036854775807"}) {
    const Document document =
        MustParse(std::string("[quality]\nmax_area_change = ") + value + "\n");
    const Section quality = MustChild(Section::Root(document), "quality");
    const Expected<double> number = quality.Number("max_area_change", 0.35, -1e300, 1e300);
    ASSERT_FALSE(number) << value << " was accepted as " << *number;
    EXPECT_THAT(number.error().message, StartsWith("test.toml:2:19: quality.max_area_change: "))
        << value;
    EXPECT_EQ(number.error().code, ErrorCode::kBadInput);
  }
  // 2^53 itself is exact, and so is any smaller integer.
  const Document exact = MustParse("x = 9007199254740992\ny = -3\n");
  EXPECT_EQ(*Section::Root(exact).Number("x", 0.0, 0.0, 1e300), 9007199254740992.0);
  EXPECT_EQ(*Section::Root(exact).Number("y", 0.0, -10.0, 10.0), -3.0);
}

TEST(ConfigSection, ANanBoundNeverLetsAValueThrough) {
  const Document document = MustParse("x = 1.0\n");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(Section::Root(document).Number("x", 0.0, nan, 2.0));
  EXPECT_FALSE(Section::Root(document).Number("x", 0.0, 0.0, nan));
}

TEST(ConfigSection, NumberArraysRejectNonFiniteElementsNamingTheKey) {
  for (const char* value : {"[1.0, nan]", "[inf]", "[-inf, 2]", "[9007199254740993]"}) {
    const Document document = MustParse(std::string("[segment]\nchroma_key_bgr = ") + value);
    const Section segment = MustChild(Section::Root(document), "segment");
    const Expected<std::vector<double>> numbers = segment.Numbers("chroma_key_bgr", {});
    ASSERT_FALSE(numbers) << value;
    EXPECT_THAT(numbers.error().message, HasSubstr("test.toml:2:"));
    EXPECT_THAT(numbers.error().message, HasSubstr("segment.chroma_key_bgr: element "));
  }
}

}  // namespace
}  // namespace revolve::config
