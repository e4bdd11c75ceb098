// docs/configuration.md is the output of `revolve check-config --reference`: these tests fail
// when the file no longer matches the parsers or a key lacks its description.
#include "station/commands/config_reference.h"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace revolve::station {
namespace {

constexpr const char* kRegenerate =
    "docs/configuration.md differs from the configuration parsers. Regenerate it with\n"
    "    build/station/apps/revolve check-config --reference > docs/configuration.md\n"
    "(describe a new key in its module's option_docs.cc first) and commit it.";

TEST(ConfigReference, TheCommittedFileIsTheCommandsOutput) {
  const std::filesystem::path path =
      std::filesystem::path(REVOLVE_SOURCE_DIR) / "docs" / "configuration.md";
  std::ifstream in(path, std::ios::binary);
  ASSERT_TRUE(in) << "cannot read " << path << "\n" << kRegenerate;
  std::ostringstream file;
  file << in.rdbuf();
  Expected<std::string> markdown = ConfigReferenceMarkdown();
  ASSERT_TRUE(markdown) << markdown.error().ToString();
  if (*markdown == file.str()) return;
  // The first line that differs, to say where.
  std::istringstream a(*markdown), b(file.str());
  std::string want, have;
  int line = 0;
  while (true) {
    ++line;
    const bool more_want = static_cast<bool>(std::getline(a, want));
    const bool more_have = static_cast<bool>(std::getline(b, have));
    if (!more_want && !more_have) break;
    if (want != have || more_want != more_have) break;
  }
  ADD_FAILURE() << kRegenerate << "\nfirst difference at line " << line << ":\n  code: " << want
                << "\n  file: " << have;
}

TEST(ConfigReference, EveryKeyHasADescriptionAndEveryDescriptionAKey) {
  Expected<std::vector<std::string>> gaps = ConfigReferenceGaps();
  ASSERT_TRUE(gaps) << gaps.error().ToString();
  EXPECT_THAT(*gaps, testing::IsEmpty())
      << "describe each key in its module's option_docs.cc (or remove the description of a "
         "key that is gone)";
}

TEST(ConfigReference, ListsEveryTableWithItsKeys) {
  Expected<std::string> markdown = ConfigReferenceMarkdown();
  ASSERT_TRUE(markdown) << markdown.error().ToString();
  for (const char* heading : {"## `[scan]`", "## `[turntable.modbus]`", "## `[turntable.gpio]`",
                              "## `[camera.v4l2]`", "## `[segment]`", "## `[reconstruct]`",
                              "## `[calibration.board]`", "## `[daemon]`", "## `[recipes.NAME]`"}) {
    EXPECT_THAT(*markdown, testing::HasSubstr(heading));
  }
  // Keys read on one branch only are there too: Modbus TCP, GPIO lines, recipes.
  EXPECT_THAT(*markdown, testing::HasSubstr("| `unit_id` | integer | `1` | [0, 255] |"));
  EXPECT_THAT(*markdown, testing::HasSubstr("| `host` |"));
  EXPECT_THAT(*markdown, testing::HasSubstr("| `stops` | integer (count) | unset | [1, 3600] |"));
}

}  // namespace
}  // namespace revolve::station
