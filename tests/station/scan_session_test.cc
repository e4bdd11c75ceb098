#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stop_token>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "station/scan_session.h"

namespace revolve::station {
namespace {

namespace fs = std::filesystem;

nlohmann::json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return nlohmann::json::parse(s.str());
}

// A quick simulated scan: few stops, small images, a coarse grid.
StationConfig QuickConfig(int stops) {
  auto document = config::Parse(R"(
[scan]
settle_ms = 0
[turntable.mock]
time_scale = 0.01
[camera.synthetic]
object = "sphere"
radius_mm = 40.0
target_height_mm = 40.0
width_px = 320
height_px = 240
[reconstruct]
resolution = 48
)",
                                "quick.toml");
  EXPECT_TRUE(document.has_value());
  auto cfg = ParseStationConfig(*document);
  EXPECT_TRUE(cfg.has_value()) << cfg.error().message;
  cfg->scan.stops = stops;
  cfg->scan.step_deg = 360.0 / stops;
  return *cfg;
}

class ScanSessionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("revolve_session_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(ScanSessionTest, CompleteScanWritesEveryPieceAndReportsEachStop) {
  const StationConfig cfg = QuickConfig(8);
  auto devices = OpenDevices(cfg);
  ASSERT_TRUE(devices.has_value()) << devices.error().message;
  auto folder = ScanFolder::Create(dir_);
  ASSERT_TRUE(folder.has_value());
  ScanSession session(cfg, *devices, *folder);
  std::vector<StopProgress> progress;
  session.OnStop([&](const StopProgress& p) { progress.push_back(p); });
  auto result = session.Run(std::stop_token());
  ASSERT_TRUE(result.has_value()) << result.error().message;

  ASSERT_EQ(progress.size(), 8u);
  for (int k = 0; k < 8; ++k) {
    EXPECT_EQ(progress[k].index, k);
    EXPECT_NEAR(progress[k].readback_deg, 45.0 * k, 0.05);
    EXPECT_GT(progress[k].mask_area_px, 0);
  }
  EXPECT_DOUBLE_EQ(progress.back().eta_s, 0.0);
  EXPECT_EQ(result->stops_done, 8);
  EXPECT_GT(result->triangles, 100u);

  const auto manifest = ReadJson(dir_ / "manifest.json");
  EXPECT_EQ(manifest["state"], "complete");
  EXPECT_EQ(manifest["stops_done"], 8);
  EXPECT_TRUE(fs::exists(dir_ / "masks/stop_007.png"));
  EXPECT_TRUE(fs::exists(dir_ / "model/model.ply"));
  EXPECT_TRUE(fs::exists(dir_ / "report.json"));
  EXPECT_TRUE(fs::exists(dir_ / "contact_sheet.png"));
  // The turntable is left stopped and disabled.
  auto state = devices->turntable->State();
  ASSERT_TRUE(state.has_value());
  EXPECT_FALSE(state->moving);
  EXPECT_FALSE(state->enabled);
}

TEST_F(ScanSessionTest, AbortKeepsWhatWasCapturedAndSaysHowFarItGot) {
  const StationConfig cfg = QuickConfig(8);
  auto devices = OpenDevices(cfg);
  ASSERT_TRUE(devices.has_value()) << devices.error().message;
  auto folder = ScanFolder::Create(dir_);
  ASSERT_TRUE(folder.has_value());
  ScanSession session(cfg, *devices, *folder);
  std::stop_source stop;
  session.OnStop([&](const StopProgress& p) {
    if (p.index == 2) stop.request_stop();
  });
  auto result = session.Run(stop.get_token());
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kAborted);

  const auto manifest = ReadJson(dir_ / "manifest.json");
  EXPECT_EQ(manifest["state"], "aborted");
  EXPECT_EQ(manifest["stops_done"], 3);
  EXPECT_EQ(manifest["stops"].size(), 3u);
  EXPECT_TRUE(fs::exists(dir_ / "frames/stop_002.png"));
  EXPECT_FALSE(fs::exists(dir_ / "frames/stop_003.png"));
  EXPECT_FALSE(fs::exists(dir_ / "report.json"));
}

}  // namespace
}  // namespace revolve::station
