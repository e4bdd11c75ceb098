// Issue 21 end to end: the real `revolve` given wrong files answers with a non-zero exit that is
// not "internal error" (70), names the file and the key or field, and loses nothing.
#include <sys/resource.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/support/test_files.h"

namespace fs = std::filesystem;

namespace {

using revolve::test_support::ReadAll;
using revolve::test_support::RunResult;
using testing::HasSubstr;
using testing::Not;

constexpr int kExitConfig = 78;
constexpr int kExitSoftware = 70;

RunResult Revolve(const std::string& args, const fs::path& dir) {
  return revolve::test_support::RunShell(std::string(REVOLVE_BIN) + " " + args, dir);
}

void WriteText(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

// ---- Config --------------------------------------------------------------------------------

struct NumberKey {
  std::string dotted;  // "quality.max_area_change"
  int line = 0;        // 1-based
};

// The float keys of the embedded default config (a number with a decimal point).
std::vector<NumberKey> FloatKeys(const std::vector<std::string>& lines) {
  std::vector<NumberKey> keys;
  std::string section;
  const std::regex table(R"(^\[([A-Za-z0-9_.]+)\]\s*(#.*)?$)");
  const std::regex number(R"(^([A-Za-z0-9_]+)\s*=\s*-?[0-9]+\.[0-9]+\s*(#.*)?$)");
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::smatch m;
    if (std::regex_match(lines[i], m, table)) section = m[1];
    if (std::regex_match(lines[i], m, number)) {
      keys.push_back(
          {section.empty() ? m[1].str() : section + "." + m[1].str(), static_cast<int>(i + 1)});
    }
  }
  return keys;
}

class BadInputTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = revolve::test_support::FreshTestDir("revolve_bad_input"); }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  fs::path dir_;
};

// Cause 1: nan, inf and 2^53 + 1 on every float key: check-config and scan both refuse it with
// exit 78, naming FILE:LINE:COLUMN and the key, and the scan creates nothing.
TEST_F(BadInputTest, EveryFloatKeyRefusesNonFiniteAndUnrepresentableNumbers) {
  std::vector<std::string> lines;
  {
    std::istringstream in(ReadAll(REVOLVE_SOURCE_DIR "/config/examples/default.toml"));
    for (std::string line; std::getline(in, line);) lines.push_back(line);
  }
  const std::vector<NumberKey> keys = FloatKeys(lines);
  ASSERT_GE(keys.size(), 20u);
  for (const NumberKey& key : keys) {
    for (const std::string value : {"nan", "-inf", "9007199254740993"}) {
      std::vector<std::string> changed = lines;
      std::string& line = changed[static_cast<std::size_t>(key.line - 1)];
      const std::size_t eq = line.find('=');
      line = line.substr(0, eq + 1) + " " + value;
      std::string text;
      for (const std::string& l : changed) text += l + "\n";
      const fs::path config = dir_ / "bad.toml";
      WriteText(config, text);
      const std::string where = fmt::format("{}:{}:", config.string(), key.line);
      const RunResult check = Revolve("check-config " + config.string(), dir_);
      EXPECT_EQ(check.exit_code, kExitConfig) << key.dotted << " = " << value << "\n" << check.out;
      EXPECT_THAT(check.err, HasSubstr(where)) << key.dotted << " = " << value;
      EXPECT_THAT(check.err, HasSubstr(key.dotted)) << value;
      if (value != "nan") continue;
      const fs::path out = dir_ / "scan_out";
      const RunResult scan =
          Revolve("scan --config " + config.string() + " --out " + out.string(), dir_);
      EXPECT_EQ(scan.exit_code, kExitConfig) << key.dotted << "\n" << scan.err;
      EXPECT_THAT(scan.err, HasSubstr(where)) << key.dotted;
      EXPECT_FALSE(fs::exists(out)) << key.dotted;
    }
  }
}

TEST_F(BadInputTest, CheckConfigSaysWhatItChecked) {
  const RunResult r =
      Revolve("check-config " REVOLVE_SOURCE_DIR "/config/examples/default.toml", dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("every check a scan makes short of opening the devices"));
}

// A missing camera exits 78 and creates nothing, whatever the backend (as a missing drive).
TEST_F(BadInputTest, AMissingCameraExits78AndCreatesNothing) {
  for (const std::string backend : {"v4l2", "libcamera", "replay"}) {
    const fs::path config = dir_ / (backend + ".toml");
    std::string text = "[camera]\nbackend = \"" + backend + "\"\n";
    if (backend == "v4l2") text += "[camera.v4l2]\ndevice = \"/dev/video_revolve_missing\"\n";
    if (backend == "libcamera") text += "[camera.libcamera]\ncamera = \"revolve-missing\"\n";
    if (backend == "replay") text += "[camera.replay]\ndir = \"no_such_folder\"\n";
    WriteText(config, text);
    const fs::path out = dir_ / ("out_" + backend);
    const RunResult r =
        Revolve("scan --config " + config.string() + " --out " + out.string(), dir_);
    if (r.err.find("not in this build") != std::string::npos) continue;
    EXPECT_EQ(r.exit_code, kExitConfig) << backend << ": " << r.err;
    EXPECT_FALSE(fs::exists(out)) << backend;
    EXPECT_THAT(r.err, Not(HasSubstr("internal error"))) << backend;
  }
}

// A missing drive too: Modbus on a serial port that is not there, GPIO on a chip that is not.
TEST_F(BadInputTest, AMissingDriveExits78AndCreatesNothing) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"/dev/ttyREVOLVE_missing",
       "[turntable]\nbackend = \"modbus\"\n[turntable.modbus]\nport = "
       "\"/dev/ttyREVOLVE_missing\"\n"},
      {"revolve-missing-chip",
       "[turntable]\nbackend = \"gpio\"\n[turntable.gpio]\nchip = \"revolve-missing-chip\"\nstep = "
       "17\ndir = 27\n"},
  };
  int n = 0;
  for (const auto& [device, text] : cases) {
    const fs::path config = dir_ / fmt::format("drive{}.toml", n);
    WriteText(config, text);
    const fs::path out = dir_ / fmt::format("out_drive{}", n++);
    const RunResult r =
        Revolve("scan --config " + config.string() + " --out " + out.string(), dir_);
    if (r.err.find("not in this build") != std::string::npos) continue;
    EXPECT_EQ(r.exit_code, kExitConfig) << device << ": " << r.err;
    EXPECT_THAT(r.err, HasSubstr(device));
    EXPECT_FALSE(fs::exists(out)) << device;
  }
}

// ---- A scan folder read back ----------------------------------------------------------------

constexpr char kQuickScan[] = R"(
[scan]
stops = 8
step_deg = 45.0
settle_ms = 0
[turntable.mock]
time_scale = 0.01
settle_ms = 0
[quality]
enabled = false
[reconstruct]
resolution = 48
formats = ["ply"]
)";

class ScanFolderInputTest : public BadInputTest {
 protected:
  static void SetUpTestSuite() {
    scan_root_ = revolve::test_support::FreshTestDir("revolve_bad_input_scan");
    WriteText(scan_root_ / "quick.toml", kQuickScan);
    const RunResult r = Revolve("scan --config " + (scan_root_ / "quick.toml").string() +
                                    " --out " + (scan_root_ / "scan").string(),
                                scan_root_);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  static void TearDownTestSuite() { fs::remove_all(scan_root_); }

  // A fresh copy of the scan folder.
  fs::path CopyScan(const std::string& name) {
    const fs::path copy = dir_ / name;
    fs::copy(scan_root_ / "scan", copy, fs::copy_options::recursive);
    return copy;
  }
  nlohmann::json Manifest(const fs::path& scan) {
    return nlohmann::json::parse(ReadAll(scan / "manifest.json"));
  }
  void SetManifest(const fs::path& scan, const nlohmann::json& m) {
    WriteText(scan / "manifest.json", m.dump(2));
  }
  RunResult Reconstruct(const fs::path& scan) {
    return Revolve("reconstruct " + scan.string(), dir_);
  }

  static inline fs::path scan_root_;
};

// Cause 2: the issue's mutations, and every JSON type on each stop field, never escape as an
// internal error; the message names manifest.json and the field.
TEST_F(ScanFolderInputTest, ManifestFieldsOfTheWrongTypeAreNamed) {
  const std::vector<nlohmann::json> values = {
      nullptr, "NaN", 42, true, nlohmann::json::array(), nlohmann::json::object(), -1.5e300};
  int case_number = 0;
  for (const char* field : {"readback_deg", "commanded_deg", "mask", "frame", "index"}) {
    for (const nlohmann::json& value : values) {
      const fs::path scan = CopyScan(fmt::format("m{}", case_number++));
      nlohmann::json m = Manifest(scan);
      m["stops"][2][field] = value;
      SetManifest(scan, m);
      const RunResult r = Reconstruct(scan);
      // Refused, or (a file name that is a string but names no image) the stop is left out
      // with a warning; either way the file and the field are named.
      EXPECT_NE(r.exit_code, kExitSoftware) << r.err;
      EXPECT_THAT(r.err, HasSubstr((scan / "manifest.json").string())) << field << " = " << value;
      EXPECT_THAT(r.err, HasSubstr(fmt::format("stops[2].{}", field))) << value << ": " << r.err;
      if (r.exit_code == 0) {
        EXPECT_TRUE(value.is_string()) << field << " = " << value << " accepted: " << r.err;
      }
      fs::remove_all(scan);
    }
  }
  for (const auto& [key, value] :
       std::vector<std::pair<std::string, nlohmann::json>>{{"state", 5},
                                                           {"stops_planned", "8"},
                                                           {"step_deg", nullptr},
                                                           {"recipe", 3},
                                                           {"stops", 1}}) {
    const fs::path scan = CopyScan(fmt::format("m{}", case_number++));
    nlohmann::json m = Manifest(scan);
    m[key] = value;
    SetManifest(scan, m);
    const RunResult r = Reconstruct(scan);
    EXPECT_NE(r.exit_code, 0) << key;
    EXPECT_NE(r.exit_code, kExitSoftware) << r.err;
    EXPECT_THAT(r.err, HasSubstr("manifest.json: " + key)) << r.err;
  }
}

// Cause 6: a stop listed twice, or 100,000 copies of one, is a contradiction that is named.
TEST_F(ScanFolderInputTest, DuplicateStopsAreNamed) {
  fs::path scan = CopyScan("dup");
  nlohmann::json m = Manifest(scan);
  m["stops"][7] = m["stops"][3];
  SetManifest(scan, m);
  RunResult r = Reconstruct(scan);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_THAT(r.err, HasSubstr("stops[7].index: stop 3 is listed twice (also stops[3])"));

  scan = CopyScan("dup_extra");
  m = Manifest(scan);
  m["stops"].push_back(m["stops"][3]);
  SetManifest(scan, m);
  r = Reconstruct(scan);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_THAT(r.err, HasSubstr("stops: lists 9 stops, more than the 8 planned"));

  scan = CopyScan("many");
  m = Manifest(scan);
  const nlohmann::json stop = m["stops"][0];
  m["stops"] = nlohmann::json::array();
  for (int i = 0; i < 100000; ++i) m["stops"].push_back(stop);
  SetManifest(scan, m);
  r = Reconstruct(scan);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_THAT(r.err, HasSubstr("manifest.json: stops: lists 100000 stops"));
}

// A read-back angle far from the commanded one, or a commanded angle off the plan, would carve
// with the wrong view: refused, naming the field.
TEST_F(ScanFolderInputTest, AnglesThatContradictThePlanAreNamed) {
  for (const auto& [field, value] : std::vector<std::pair<std::string, double>>{
           {"readback_deg", 42.0}, {"commanded_deg", 100.0}}) {
    const fs::path scan = CopyScan("angle_" + field);
    nlohmann::json m = Manifest(scan);
    m["stops"][2][field] = value;
    SetManifest(scan, m);
    const RunResult r = Reconstruct(scan);
    EXPECT_NE(r.exit_code, 0) << field;
    EXPECT_THAT(r.err, HasSubstr("manifest.json: stops[2]." + field));
  }
}

// Cause 5: a mask of another size, or a camera of another size in scan.toml, is an error.
TEST_F(ScanFolderInputTest, SizesThatDisagreeAreErrors) {
  fs::path scan = CopyScan("half_mask");
  cv::Mat mask = cv::imread((scan / "masks/stop_004.png").string(), cv::IMREAD_GRAYSCALE);
  cv::resize(mask, mask, mask.size() / 2, 0, 0, cv::INTER_NEAREST);
  cv::imwrite((scan / "masks/stop_004.png").string(), mask);
  RunResult r = Reconstruct(scan);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, kExitSoftware);
  EXPECT_THAT(r.err, HasSubstr("masks/stop_004.png: 384 x 288 pixels"));

  scan = CopyScan("wide_camera");
  WriteText(scan / "scan.toml",
            ReadAll(scan / "scan.toml") + "\n[camera.synthetic]\nwidth_px = 800\n");
  r = Reconstruct(scan);
  EXPECT_EQ(r.exit_code, kExitConfig) << r.err;
  EXPECT_THAT(r.err, HasSubstr("768x576"));
  EXPECT_THAT(r.err, HasSubstr("800x576"));
}

// A scan.toml cut short (still valid TOML) falls back to other defaults: refused, not carved
// with another camera.
TEST_F(ScanFolderInputTest, AScanTomlCutShortIsRefused) {
  const fs::path scan = CopyScan("cut_toml");
  WriteText(scan / "scan.toml",
            ReadAll(scan / "scan.toml") + "\n[camera.synthetic]\nhfov_deg = 35.0\n");
  const RunResult r = Reconstruct(scan);
  EXPECT_EQ(r.exit_code, kExitConfig) << r.err;
  EXPECT_THAT(r.err, HasSubstr("scan.toml: the camera it describes"));
  EXPECT_THAT(r.err, HasSubstr("hfov 35 deg"));
}

// Damaged frames are named, not silently dropped from the texture.
TEST_F(ScanFolderInputTest, ADamagedFrameIsNamed) {
  const fs::path scan = CopyScan("cut_frame");
  const std::string png = ReadAll(scan / "frames/stop_001.png");
  WriteText(scan / "frames/stop_001.png", png.substr(0, png.size() / 2));
  const RunResult r = Reconstruct(scan);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("frames/stop_001.png: PNG: the file is cut short"));
}

// Cause 7 (the report half): reconstruct SCAN_DIR replaces the scan's report.json with its own.
TEST_F(ScanFolderInputTest, ReconstructWritesAFreshReport) {
  const fs::path scan = CopyScan("report");
  const RunResult r = Revolve("reconstruct " + scan.string() + " --resolution 40", dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(ReadAll(scan / "report.json"));
  EXPECT_EQ(report["source"], "revolve reconstruct");
  EXPECT_EQ(report["resolution"], 40);
  EXPECT_EQ(report["stops_used"], 8);
}

// --out on a read-only file system says so, before any work.
TEST_F(ScanFolderInputTest, OutOnAReadOnlyMountSaysSo) {
  if (std::system("unshare -m true >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "cannot make a mount namespace here (unshare -m)";
  }
  const fs::path scan = CopyScan("ro");
  const fs::path ro = dir_ / "ro_mount";
  fs::create_directories(ro);
  const RunResult r = revolve::test_support::RunShell(
      "unshare -m sh -c 'mount -t tmpfs -o ro tmpfs " + ro.string() + " && " + REVOLVE_BIN +
          " reconstruct " + scan.string() + " --out " + (ro / "out").string() + "'",
      dir_);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_THAT(r.err, HasSubstr((ro / "out").string() + ": cannot create the output folder: "
                                                       "Read-only file system"));
  EXPECT_THAT(r.err, Not(HasSubstr("No such file or directory")));
}

// ---- Folders of images --------------------------------------------------------------------

// Eight views of a bright disc on black.
void WriteViews(const fs::path& dir, const std::string& ext) {
  fs::create_directories(dir);
  for (int i = 0; i < 8; ++i) {
    cv::Mat image(120, 160, CV_8UC3, cv::Scalar::all(0));
    cv::ellipse(image, {80, 60}, {30 + (i % 2) * 4, 45}, 0, 0, 360, {220, 200, 180}, -1);
    cv::imwrite((dir / fmt::format("view_{:03d}{}", i, ext)).string(), image);
  }
}

long ChildrenMaxRssKb() {
  rusage usage{};
  getrusage(RUSAGE_CHILDREN, &usage);
  return usage.ru_maxrss;
}

// Cause 4: a JPEG cut to half is an error naming it, not a grey lower half carved as object.
TEST_F(BadInputTest, ATruncatedJpegAmongTheImagesIsNamed) {
  const fs::path images = dir_ / "views";
  WriteViews(images, ".jpg");
  const std::string jpeg = ReadAll(images / "view_005.jpg");
  WriteText(images / "view_005.jpg", jpeg.substr(0, jpeg.size() / 2));
  const RunResult r = Revolve(
      "reconstruct --images " + images.string() + " --step-deg 45 --out " + (dir_ / "o").string(),
      dir_);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, kExitSoftware);
  EXPECT_THAT(r.err, HasSubstr("view_005.jpg: JPEG: the file is cut short"));
  // Refused before anything was written: no empty output folder is left behind.
  EXPECT_FALSE(fs::exists(dir_ / "o"));
}

// The odd image is named, even when it is the first: the set's size and kind are those of most
// of its images, not of whichever comes first.
TEST_F(BadInputTest, AnOddFirstImageIsTheOneNamed) {
  const fs::path images = dir_ / "views";
  WriteViews(images, ".png");
  cv::Mat small(60, 80, CV_8UC3, cv::Scalar::all(0));
  cv::circle(small, {40, 30}, 20, {220, 200, 180}, -1);
  cv::imwrite((images / "view_000.png").string(), small);
  RunResult r = Revolve(
      "reconstruct --images " + images.string() + " --step-deg 45 --out " + (dir_ / "o").string(),
      dir_);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, kExitSoftware);
  EXPECT_THAT(r.err,
              HasSubstr("view_000.png: is 80 x 60 pixels, but the other images are 160 x 120"));

  // A binary silhouette first among photos: the silhouette is the odd one.
  cv::Mat silhouette(120, 160, CV_8UC1, cv::Scalar::all(0));
  cv::circle(silhouette, {80, 60}, 30, cv::Scalar::all(255), -1);
  cv::imwrite((images / "view_000.png").string(), silhouette);
  r = Revolve(
      "reconstruct --images " + images.string() + " --step-deg 45 --out " + (dir_ / "o").string(),
      dir_);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_THAT(r.err, HasSubstr("view_000.png: a binary silhouette among photos"));
}

// A box no voxel grid can span is a typing error, refused before any work.
TEST_F(BadInputTest, AnAbsurdBoxIsRefused) {
  const fs::path images = dir_ / "views";
  WriteViews(images, ".png");
  const RunResult r =
      Revolve("reconstruct --images " + images.string() +
                  " --step-deg 45 --bbox 0 0 0 1e308 1e308 1e308 --out " + (dir_ / "o").string(),
              dir_);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, kExitSoftware);
  EXPECT_THAT(r.err, HasSubstr("--bbox"));
  EXPECT_FALSE(fs::exists(dir_ / "o"));
}

TEST_F(BadInputTest, ADanglingSymlinkAmongTheImagesIsNamed) {
  const fs::path images = dir_ / "views";
  WriteViews(images, ".png");
  fs::create_symlink(dir_ / "nowhere.png", images / "view_008.png");
  const RunResult r = Revolve(
      "reconstruct --images " + images.string() + " --step-deg 45 --out " + (dir_ / "o").string(),
      dir_);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_THAT(r.err, HasSubstr("view_008.png: a dangling symbolic link"));
}

// Cause 3: eight small JPEGs whose headers claim 20000 x 20000: refused from their headers,
// the process stays far under 300 MB.
TEST_F(BadInputTest, AHeaderBombIsRefusedWithBoundedMemory) {
  const fs::path images = dir_ / "bomb";
  WriteViews(images, ".jpg");
  for (int i = 0; i < 8; ++i) {
    const fs::path file = images / fmt::format("view_{:03d}.jpg", i);
    std::string bytes = ReadAll(file);
    const std::size_t sof = bytes.find("\xFF\xC0");
    ASSERT_NE(sof, std::string::npos);
    bytes[sof + 5] = '\x4E', bytes[sof + 6] = '\x20', bytes[sof + 7] = '\x4E',
                bytes[sof + 8] = '\x20';
    WriteText(file, bytes);
  }
  const RunResult r = Revolve(
      "reconstruct --images " + images.string() + " --step-deg 45 --out " + (dir_ / "o").string(),
      dir_);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, kExitSoftware) << r.err;
  EXPECT_THAT(r.err, HasSubstr("view_000.jpg: JPEG: "));
  EXPECT_THAT(r.err, HasSubstr("20000 x 20000"));
  EXPECT_LT(ChildrenMaxRssKb(), 300 * 1024);
}

TEST_F(BadInputTest, AnImageOverTheLimitIsRefusedFromItsHeader) {
  const fs::path images = dir_ / "views";
  WriteViews(images, ".png");
  const RunResult r =
      Revolve("reconstruct --images " + images.string() +
                  " --step-deg 45 --max-image-mp 0.01 --out " + (dir_ / "o").string(),
              dir_);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_THAT(r.err, HasSubstr("view_000.png: 160 x 120 pixels"));
  EXPECT_THAT(r.err, HasSubstr("--max-image-mp"));
}

// The README's zero-padded pattern works.
TEST_F(BadInputTest, AZeroPaddedPatternWorks) {
  const fs::path images = dir_ / "views";
  WriteViews(images, ".png");
  const RunResult r =
      Revolve("reconstruct --images " + images.string() +
                  " --pattern 'view_{index:03}.png' --step-deg 45 --out " + (dir_ / "o").string(),
              dir_);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir_ / "o/report.json"));
}

}  // namespace
