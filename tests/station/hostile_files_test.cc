// Issue 21: "internal error" is unreachable from any input. Every reader of a file revolve did
// not just write (the config and a scan's scan.toml, manifest.json, a --cameras file, a
// calibration file) is fed its valid file mutated field by field (wrong types, a missing field,
// nan, inf, huge and negative numbers, deep nesting, non-UTF-8, very long strings) and whole
// (empty, binary, cut short at many points). Each must answer a value or an error naming the
// file (and the field, when one field was changed); never an exception.
#include <sys/stat.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <regex>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "calibrate/calibration.h"
#include "reconstruct/cameras/camera_file.h"
#include "station/scan_folder.h"
#include "station/station_config.h"
#include "tests/calibrate/sim_rigs.h"
#include "tests/support/test_files.h"

namespace revolve {
namespace {

namespace fs = std::filesystem;
using testing::HasSubstr;

// One mutated file: its text, the key or field changed ("" for the whole file), and whether it
// must be refused (a value of the wrong type).
struct Mutant {
  std::string text;
  std::string field;
  std::string what;
  bool must_fail = false;
};

std::string Deep(int depth, char open, char close) {
  return std::string(static_cast<std::size_t>(depth), open) +
         std::string(static_cast<std::size_t>(depth), close);
}

// Whole-file damage, for any format.
std::vector<Mutant> WholeFileMutants(const std::string& valid) {
  std::vector<Mutant> out = {
      {"", "", "empty", false},  // valid TOML (every default); a JSON or camera file refuses it
      {std::string("\xff\xfe\xfd\x00\x01garbage", 12), "", "binary", true},
      {std::string(1 << 16, '\0'), "", "zeros", true},
      {"a = " + Deep(100000, '[', ']'), "", "deep TOML", true},
      {Deep(100000, '[', ']'), "", "deep JSON", true},
      {Deep(100000, '{', '}'), "", "deep braces", true},
      {valid + "\n\xc3\x28 = 1\n", "", "non-UTF-8 key", true},
  };
  for (int part = 1; part < 8; ++part) {
    out.push_back({valid.substr(0, valid.size() * static_cast<std::size_t>(part) / 8), "",
                   fmt::format("cut to {}/8", part), false});
  }
  return out;
}

// Each `key = value` line of a TOML text, its value replaced or the line removed.
std::vector<Mutant> TomlMutants(const std::string& valid) {
  std::vector<Mutant> out = WholeFileMutants(valid);
  const std::regex line_re(R"(^([ \t]*)([A-Za-z0-9_]+)([ \t]*=[ \t]*)([^\n]*)$)");
  std::size_t start = 0;
  while (start < valid.size()) {
    std::size_t end = valid.find('\n', start);
    if (end == std::string::npos) end = valid.size();
    const std::string line = valid.substr(start, end - start);
    std::smatch m;
    if (std::regex_match(line, m, line_re)) {
      const std::string key = m[2];
      const std::string value = m[4];
      const bool is_string = !value.empty() && value[0] == '"';
      const bool is_array = !value.empty() && value[0] == '[';
      // An array over several lines: replacing its first line breaks the TOML syntax, an error
      // naming the line, not the key.
      const bool multi_line = is_array && value.find(']') == std::string::npos;
      const auto with = [&](const std::string& replacement, const std::string& what,
                            bool must_fail) {
        std::string text = valid;
        text.replace(start, end - start, m[1].str() + key + m[3].str() + replacement);
        out.push_back({std::move(text), key, what, must_fail && !multi_line});
      };
      // Of the wrong type: always refused.
      if (!is_string) with("\"text\"", "a string", true);
      if (is_string) with("42", "a number", true);
      if (!is_array) with("[1, 2]", "an array", true);
      with("{ a = 1 }", "a table", true);
      // Out of range, not representable or odd: a value or an error, never an exception.
      for (const char* odd : {"nan", "inf", "-inf", "9007199254740993", "-9223372036854775808",
                              "1e308", "-1", "0", "true", "\"\"", "\"\xff\xfe\"", "[]"}) {
        with(odd, odd, false);
      }
      with("\"" + std::string(100000, 'a') + "\"", "a long string", false);
      with(Deep(5000, '[', ']'), "deep nesting", false);
      {
        std::string text = valid;
        text.erase(start, end - start);
        out.push_back({std::move(text), key, "removed", false});
      }
    }
    start = end + 1;
  }
  return out;
}

// Each field of a JSON document (every depth) set to every JSON type, or removed.
std::vector<Mutant> JsonMutants(const std::string& valid_text) {
  std::vector<Mutant> out = WholeFileMutants(valid_text);
  const nlohmann::json valid = nlohmann::json::parse(valid_text);
  const nlohmann::json flat = valid.flatten();
  std::vector<std::string> pointers;
  for (const auto& [pointer, value] : flat.items()) pointers.push_back(pointer);
  // The containers too: "/stops/1" and "/stops".
  for (std::size_t i = 0, n = pointers.size(); i < n; ++i) {
    for (std::string p = pointers[i]; p.rfind('/') != std::string::npos && p.rfind('/') > 0;) {
      p = p.substr(0, p.rfind('/'));
      pointers.push_back(p);
    }
  }
  std::sort(pointers.begin(), pointers.end());
  pointers.erase(std::unique(pointers.begin(), pointers.end()), pointers.end());
  const std::vector<std::pair<nlohmann::json, std::string>> values = {
      {nullptr, "null"},
      {true, "true"},
      {42, "42"},
      {-1, "-1"},
      {1e308, "1e308"},
      {"NaN", "\"NaN\""},
      {"", "\"\""},
      {nlohmann::json::array(), "[]"},
      {nlohmann::json::object(), "{}"},
      {std::uint64_t{18446744073709551615ull}, "2^64-1"},
      {std::int64_t{-9223372036854775807LL - 1}, "-2^63"}};
  for (const std::string& pointer : pointers) {
    const nlohmann::json::json_pointer at(pointer);
    const std::string field = pointer.substr(pointer.rfind('/') + 1);
    for (const auto& [value, what] : values) {
      nlohmann::json m = valid;
      m[at] = value;
      out.push_back({m.dump(1), field, what, false});
    }
    nlohmann::json m = valid;
    nlohmann::json& parent = m[at.parent_pointer()];
    if (parent.is_object()) parent.erase(field);
    if (parent.is_array()) parent.erase(std::stoul(field));
    out.push_back({m.dump(1), field, "removed", false});
    // Deep nesting and non-UTF-8 bytes in place of the value (the text, not a json value).
    nlohmann::json marked = valid;
    marked[at] = "@@HERE@@";
    std::string text = marked.dump(1);
    const std::size_t here = text.find("\"@@HERE@@\"");
    out.push_back({text.substr(0, here) + Deep(20000, '[', ']') + text.substr(here + 10), field,
                   "deep", false});
    out.push_back({text.substr(0, here) + "\"\xff\xfe\"" + text.substr(here + 10), field,
                   "non-UTF-8", false});
    out.push_back({text.substr(0, here) + "1e999" + text.substr(here + 10), field, "1e999", false});
  }
  return out;
}

// Each whitespace-separated token of a text replaced by odd ones, or removed.
std::vector<Mutant> TokenMutants(const std::string& valid) {
  std::vector<Mutant> out = WholeFileMutants(valid);
  for (std::size_t at = 0; at < valid.size();) {
    const std::size_t start = valid.find_first_not_of(" \t\n", at);
    if (start == std::string::npos) break;
    std::size_t end = valid.find_first_of(" \t\n", start);
    if (end == std::string::npos) end = valid.size();
    for (const char* odd : {"nan", "inf", "abc", "1e999", "-1e999", "1e-400", "0x10", "\xff\xfe",
                            "9007199254740993", "0", "", "1 2"}) {
      std::string text = valid;
      text.replace(start, end - start, odd);
      out.push_back({std::move(text), "", odd, false});
    }
    at = end;
  }
  return out;
}

struct HostileReader {
  std::string name;
  std::string file_name;
  std::string valid;
  std::function<std::vector<Mutant>(const std::string&)> mutate;
  // Reads the file at `path`; the error's message.
  std::function<std::optional<std::string>(const fs::path&)> read;
};

template <typename T>
std::optional<std::string> ErrorOf(const Expected<T>& result) {
  if (result) return std::nullopt;
  return result.error().message;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string ValidManifest() {
  nlohmann::json m = {{"version", 1},
                      {"scan_id", "20261126-101010"},
                      {"recipe", "default"},
                      {"state", "complete"},
                      {"started", "2026-11-26T10:10:10.000Z"},
                      {"finished", "2026-11-26T10:11:10.000Z"},
                      {"config", "scan.toml"},
                      {"stops_planned", 2},
                      {"step_deg", 180.0},
                      {"stops_done", 2},
                      {"resumed", nlohmann::json::array()},
                      {"stops", nlohmann::json::array()}};
  for (int i = 0; i < 2; ++i) {
    m["stops"].push_back(
        {{"index", i},
         {"commanded_deg", 180.0 * i},
         {"readback_deg", 180.0 * i + 0.01},
         {"frame", fmt::format("frames/stop_{:03d}.png", i)},
         {"mask", fmt::format("masks/stop_{:03d}.png", i)},
         {"quality", nlohmann::json::array({{{"code", "blurred"}, {"message", "m"}}})}});
  }
  return m.dump(1);
}

std::string ValidCalibration() {
  calibrate::Calibration c;
  c.software_version = "0.1.0";
  c.created = "2024-05-01T12:34:56Z";
  c.board = calibrate::sim::TestBoard();
  c.camera = calibrate::sim::TrueLens();
  calibrate::AxisCalibration a;
  a.cam_from_table = calibrate::sim::OffRig(c.camera.intrinsics).cam_from_table;
  a.stops = 36;
  a.span_deg = 350.0;
  c.axis = a;
  return calibrate::FormatCalibration(c);
}

std::vector<HostileReader> Readers() {
  const std::string config = ReadText(REVOLVE_SOURCE_DIR "/config/examples/default.toml");
  const auto station_config = [](const fs::path& path) {
    return ErrorOf(station::LoadStationConfig(path));
  };
  return {
      {"config", "revolved.toml", config, TomlMutants, station_config},
      // A scan's scan.toml is read by the same typed reader (reconstruct, resume).
      {"scan.toml", "scan.toml", config, TomlMutants, station_config},
      {"manifest.json", "manifest.json", ValidManifest(), JsonMutants,
       [](const fs::path& path) { return ErrorOf(station::ReadManifest(path.parent_path())); }},
      {"cameras", "cameras_par.txt",
       "2\n"
       "a.png 1000 0 320 0 1000 240 0 0 1 1 0 0 0 1 0 0 0 1 0 0 0.5\n"
       "b.png 1000 0 320 0 1000 240 0 0 1 0 0 1 0 1 0 -1 0 0 0 0 0.5\n",
       TokenMutants,
       [](const fs::path& path) { return ErrorOf(reconstruct::ReadCameraFile(path)); }},
      {"calibration", "calibration.toml", ValidCalibration(), TomlMutants,
       [](const fs::path& path) { return ErrorOf(calibrate::LoadCalibration(path)); }},
  };
}

class HostileFilesTest : public testing::TestWithParam<int> {};

TEST_P(HostileFilesTest, EveryMutantIsAValueOrAnErrorNamingTheFileNeverAnException) {
  const HostileReader reader = Readers()[static_cast<std::size_t>(GetParam())];
  test_support::TempDir dir("revolve_hostile");
  const fs::path path = dir.path() / reader.file_name;
  {
    std::ofstream(path, std::ios::binary) << reader.valid;
    ASSERT_EQ(reader.read(path), std::nullopt) << reader.name << ": the valid file is refused";
  }
  int refused = 0;
  int accepted = 0;
  for (const Mutant& mutant : reader.mutate(reader.valid)) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << mutant.text;
    const std::string label = fmt::format("{} {}: {}", reader.name, mutant.field, mutant.what);
    std::optional<std::string> error;
    try {
      error = reader.read(path);
    } catch (const std::exception& e) {
      ADD_FAILURE() << label << ": an exception escaped: " << e.what();
      continue;
    }
    if (!error) {
      ++accepted;
      EXPECT_FALSE(mutant.must_fail) << label << " was accepted";
      continue;
    }
    ++refused;
    EXPECT_THAT(*error, HasSubstr(path.string())) << label;
    if (!mutant.field.empty() && mutant.must_fail) {
      EXPECT_THAT(*error, HasSubstr(mutant.field)) << label;
    }
  }
  EXPECT_GT(refused, 10) << reader.name;
  RecordProperty("refused", refused);
  RecordProperty("accepted", accepted);
}

// A device, a FIFO or a folder where the file should be: an error naming it at once, never a
// read that does not end (/dev/zero) or waits for a writer (a FIFO).
TEST_P(HostileFilesTest, ADeviceAFifoOrAFolderIsRefusedAtOnce) {
  const HostileReader reader = Readers()[static_cast<std::size_t>(GetParam())];
  test_support::TempDir dir("revolve_special");
  const fs::path path = dir.path() / reader.file_name;
  const auto refused = [&](const std::string& what) {
    std::optional<std::string> error;
    ASSERT_NO_THROW(error = reader.read(path)) << what;
    ASSERT_TRUE(error) << reader.name << ": " << what << " was accepted";
    EXPECT_THAT(*error, HasSubstr(path.string())) << what;
  };
  fs::create_symlink("/dev/zero", path);
  refused("a link to /dev/zero");
  fs::remove(path);
  ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
  refused("a FIFO");
  fs::remove(path);
  fs::create_directory(path);
  refused("a folder");
}

std::string ReaderName(const testing::TestParamInfo<int>& param) {
  const char* names[] = {"config", "scan_toml", "manifest", "cameras", "calibration"};
  return names[param.param];
}

INSTANTIATE_TEST_SUITE_P(Readers, HostileFilesTest, testing::Range(0, 5), ReaderName);

}  // namespace
}  // namespace revolve
