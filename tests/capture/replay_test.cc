// The replay camera: patterns, natural order, serving by plate angle or in sequence, and a full
// scan of a simulated scan's saved frames through the station, matching the original scan.

#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "capture/replay/replay_camera.h"
#include "capture/synthetic/synthetic_camera.h"
#include "station/scan_session.h"
#include "tests/support/test_files.h"

namespace revolve::capture {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

TEST(ReplayPattern, ExpandsAngleAndIndexWithPadding) {
  EXPECT_EQ(ExpandReplayPattern("bw_shoe{angle}.tif", 350, 35), "bw_shoe350.tif");
  EXPECT_EQ(ExpandReplayPattern("stop_{index:03}.png", 30, 3), "stop_003.png");
  EXPECT_EQ(ExpandReplayPattern("{index}_{angle:04}.jpg", 90, 9), "9_0090.jpg");
  EXPECT_TRUE(CheckReplayPattern("").has_value());
  for (const char* bad : {"plain.png", "x{angel}.png", "x{angle.png", "x}.png",
                          "{angle}{angle}.png", "{index:3}.png"}) {
    EXPECT_FALSE(CheckReplayPattern(bad).has_value()) << bad;
  }
}

TEST(ReplayPattern, NaturalOrder) {
  EXPECT_TRUE(NaturalLess("img2.png", "img10.png"));
  EXPECT_FALSE(NaturalLess("img10.png", "img2.png"));
  EXPECT_TRUE(NaturalLess("a.png", "b.png"));
  EXPECT_TRUE(NaturalLess("shoe9", "shoe10"));
  EXPECT_TRUE(NaturalLess("x", "x1"));
  EXPECT_FALSE(NaturalLess("x1", "x1"));
}

// Writes `count` images whose pixel (0, 0) holds their number.
void WriteNumbered(const fs::path& dir, const std::string& pattern, int count, double step_deg) {
  for (int i = 0; i < count; ++i) {
    cv::Mat image(24, 32, CV_8UC3, cv::Scalar::all(0));
    image.at<cv::Vec3b>(0, 0) = cv::Vec3b(static_cast<std::uint8_t>(i), 0, 0);
    const int angle = static_cast<int>(std::lround(i * step_deg)) % 360;
    ASSERT_TRUE(cv::imwrite((dir / ExpandReplayPattern(pattern, angle, i)).string(), image));
  }
}

int Number(const Frame& frame) { return frame.image.at<cv::Vec3b>(0, 0)[0]; }

TEST(ReplayCamera, ServesTheImageForThePlatesAngle) {
  test_support::TempDir dir("revolve_replay");
  WriteNumbered(dir.path(), "bw_shoe{angle}.png", 36, 10.0);
  ReplayOptions o;
  o.dir = dir.path().string();
  o.pattern = "bw_shoe{angle}.png";
  auto plate = std::make_shared<SimulatedPlate>();
  auto camera = ReplayCamera::Create(o, plate);
  ASSERT_TRUE(camera.has_value()) << camera.error().ToString();
  auto format = (*camera)->Start();
  ASSERT_TRUE(format.has_value());
  EXPECT_EQ(format->width_px, 32);
  for (const auto& [angle, expected] : std::vector<std::pair<double, int>>{
           {0.0, 0}, {30.02, 3}, {349.9, 35}, {360.0, 0}, {-10.0, 35}}) {
    plate->angle_deg = angle;
    auto frame = (*camera)->Capture(Clock::now(), 1s);
    ASSERT_TRUE(frame.has_value()) << frame.error().ToString();
    EXPECT_EQ(Number(*frame), expected) << angle;
  }
  EXPECT_EQ((*camera)->PathForStop(35).filename(), "bw_shoe350.png");
  EXPECT_FALSE((*camera)->KnownRig().has_value());
  EXPECT_EQ((*camera)->CaptureBackground(Clock::now(), 1s).error().code, ErrorCode::kUnsupported);
}

TEST(ReplayCamera, ServesAFolderInNaturalOrderInSequence) {
  test_support::TempDir dir("revolve_replay");
  WriteNumbered(dir.path(), "img{index}.png", 12, 30.0);
  ReplayOptions o;
  o.dir = dir.path().string();
  o.order = "sequence";
  auto camera = ReplayCamera::Create(o, nullptr);
  ASSERT_TRUE(camera.has_value());
  ASSERT_TRUE((*camera)->Start().has_value());
  for (int i = 0; i < 12; ++i) {
    auto frame = (*camera)->Capture(Clock::now(), 1s);
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(Number(*frame), i);  // img10 after img9, not after img1
  }
  auto past_the_end = (*camera)->Capture(Clock::now(), 1s);
  ASSERT_FALSE(past_the_end.has_value());
  EXPECT_EQ(past_the_end.error().code, ErrorCode::kNotFound);
}

TEST(ReplayCamera, ReportsMissingFilesAndServesTheBackground) {
  test_support::TempDir dir("revolve_replay");
  WriteNumbered(dir.path(), "s{index}.png", 3, 10.0);
  cv::imwrite((dir.path() / "empty.png").string(), cv::Mat(24, 32, CV_8UC3, cv::Scalar::all(7)));
  ReplayOptions o;
  o.dir = dir.path().string();
  o.pattern = "s{index}.png";
  o.background = (dir.path() / "empty.png").string();
  auto plate = std::make_shared<SimulatedPlate>();
  auto camera = ReplayCamera::Create(o, plate);
  ASSERT_TRUE(camera.has_value());
  ASSERT_TRUE((*camera)->Start().has_value());
  plate->angle_deg = 50.0;  // stop 5: no such file
  auto missing = (*camera)->Capture(Clock::now(), 1s);
  ASSERT_FALSE(missing.has_value());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("s5.png"), std::string::npos);
  auto background = (*camera)->CaptureBackground(Clock::now(), 1s);
  ASSERT_TRUE(background.has_value());
  EXPECT_EQ(background->image.at<cv::Vec3b>(3, 3), cv::Vec3b(7, 7, 7));

  o.dir = (dir.path() / "nowhere").string();
  EXPECT_EQ(ReplayCamera::Create(o, plate).error().code, ErrorCode::kNotFound);
  o.dir = dir.path().string();
  o.pattern = "t{index}.png";
  EXPECT_EQ(ReplayCamera::Create(o, plate).error().code, ErrorCode::kNotFound);
}

nlohmann::json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return nlohmann::json::parse(s.str());
}

station::StationConfig Config(const std::string& text) {
  auto document = config::Parse(text, "replay_scan.toml");
  EXPECT_TRUE(document.has_value()) << document.error().message;
  auto cfg = station::ParseStationConfig(*document);
  EXPECT_TRUE(cfg.has_value()) << cfg.error().message;
  return *cfg;
}

Expected<station::ScanResult> RunScan(const station::StationConfig& cfg, const fs::path& dir) {
  auto devices = station::OpenDevices(cfg);
  if (!devices) return std::unexpected(devices.error());
  auto folder = station::ScanFolder::Create(dir);
  if (!folder) return std::unexpected(folder.error());
  station::ScanSession session(cfg, *devices, *folder);
  return session.Run(std::stop_token());
}

constexpr char kCommon[] = R"(
[scan]
stops = 12
step_deg = 30.0
settle_ms = 0
[turntable.mock]
time_scale = 0.01
[reconstruct]
resolution = 64
)";

TEST(ReplayScan, ReplayingASimulatedScanGivesTheSameModel) {
  test_support::TempDir dir("revolve_replay");
  // 1. A simulated scan of the vase.
  const auto simulated = Config(std::string(kCommon) + R"(
[camera.synthetic]
object = "vase"
width_px = 384
height_px = 288
)");
  auto first = RunScan(simulated, dir.path() / "simulated");
  ASSERT_TRUE(first.has_value()) << first.error().ToString();
  // 2. The same scan from its saved frames, the replay camera standing in for the camera.
  const auto replayed = Config(std::string(kCommon) + R"(
[camera]
backend = "replay"
[camera.replay]
dir = ")" + (dir.path() / "simulated" / "frames").string() +
                               R"("
pattern = "stop_{index:03}.png"
step_deg = 30.0
hfov_deg = 30.0
distance_mm = 450.0
target_height_mm = 50.0
)");
  auto second = RunScan(replayed, dir.path() / "replayed");
  ASSERT_TRUE(second.has_value()) << second.error().ToString();
  EXPECT_EQ(second->stops_done, 12);
  // Same frames, same masks, same model.
  for (int k = 0; k < 12; ++k) {
    const std::string name = station::StopFileName(k);
    const cv::Mat a =
        cv::imread((dir.path() / "simulated/masks" / name).string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat b =
        cv::imread((dir.path() / "replayed/masks" / name).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(a.empty());
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << name;
  }
  const double volume_a = first->report["model"]["volume_mm3"];
  const double volume_b = second->report["model"]["volume_mm3"];
  EXPECT_NEAR(volume_b, volume_a, 1e-6 * volume_a);
  // The simulated scan knew its truth; its accuracy holds for the replay too.
  const double error_percent = first->report["accuracy"]["volume_error_percent"];
  EXPECT_LT(std::abs(error_percent), 10.0);
  EXPECT_EQ(ReadJson(dir.path() / "replayed" / "manifest.json")["state"], "complete");
}

}  // namespace
}  // namespace revolve::capture
