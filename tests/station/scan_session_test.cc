#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <stop_token>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <opencv2/imgproc.hpp>

#include "capture/synthetic/synthetic_camera.h"
#include "station/scan_session.h"
#include "tests/support/synthetic_backdrops.h"

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

// An event callback that keeps the notes of the non-terminal events.
std::function<void(const ScanEvent&)> CollectNotes(std::vector<std::string>* notes) {
  return [notes](const ScanEvent& e) {
    if (!e.note.empty() && !IsTerminal(e.state)) notes->push_back(e.note);
  };
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

  // Opens the devices of `cfg` and runs one scan into dir_, passing every event to `on_event`.
  Expected<ScanResult> RunScan(const StationConfig& cfg,
                               std::function<void(const ScanEvent&)> on_event = {}) {
    auto devices = OpenDevices(cfg);
    if (!devices) return std::unexpected(devices.error());
    auto folder = ScanFolder::Create(dir_);
    if (!folder) return std::unexpected(folder.error());
    ScanSession session(cfg, *devices, *folder);
    if (on_event) session.OnEvent(std::move(on_event));
    return session.Run(std::stop_token());
  }

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

std::vector<std::string> States(const std::vector<ScanEvent>& events) {
  std::vector<std::string> out;
  for (const auto& e : events) {
    if (e.note.empty() || IsTerminal(e.state)) out.emplace_back(ToString(e.state));
  }
  return out;
}

TEST_F(ScanSessionTest, EveryTransitionIsAnEventAndDoneComesAfterTheManifest) {
  const StationConfig cfg = QuickConfig(3);
  auto devices = OpenDevices(cfg);
  ASSERT_TRUE(devices.has_value()) << devices.error().message;
  auto folder = ScanFolder::Create(dir_);
  ASSERT_TRUE(folder.has_value());
  ScanSession session(cfg, *devices, *folder, "scan-a");
  std::vector<ScanEvent> events;
  std::string manifest_state_at_done;
  session.OnEvent([&](const ScanEvent& e) {
    events.push_back(e);
    if (e.state == ScanState::kDone) {
      manifest_state_at_done = ReadJson(dir_ / "manifest.json")["state"];
    }
  });
  auto result = session.Run(std::stop_token());
  ASSERT_TRUE(result.has_value()) << result.error().message;
  const std::vector<std::string> expected = {"homing",      "moving",  "settling", "capturing",
                                             "integrating", "moving",  "settling", "capturing",
                                             "integrating", "moving",  "settling", "capturing",
                                             "integrating", "meshing", "writing",  "done"};
  EXPECT_EQ(States(events), expected);
  for (std::size_t k = 1; k < events.size(); ++k) EXPECT_GT(events[k].seq, events[k - 1].seq);
  for (const auto& e : events) {
    EXPECT_EQ(e.scan_id, "scan-a");
    EXPECT_FALSE(e.time.empty());
  }
  EXPECT_EQ(events[5].stop, 1);
  EXPECT_NEAR(events[5].angle_deg, 120.0, 1e-9);
  EXPECT_EQ(events[5].stops_done, 1);
  EXPECT_EQ(events.back().stops_done, 3);
  EXPECT_EQ(manifest_state_at_done, "complete");
}

TEST_F(ScanSessionTest, ALostFrameIsRetriedAndTheScanCompletes) {
  StationConfig cfg = QuickConfig(4);
  cfg.station.camera_retry_delay_ms = 1;
  cfg.station.simulate.camera_fail_after = 1;
  cfg.station.simulate.camera_fail_count = 2;
  std::vector<std::string> notes;
  auto result = RunScan(cfg, CollectNotes(&notes));
  ASSERT_TRUE(result.has_value()) << result.error().message;
  ASSERT_EQ(notes.size(), 2u);
  EXPECT_NE(notes[0].find("re-try 1 of 2"), std::string::npos) << notes[0];
  EXPECT_EQ(ReadJson(dir_ / "manifest.json")["state"], "complete");
}

TEST_F(ScanSessionTest, ACameraThatStaysLostFailsTheScanCleanly) {
  StationConfig cfg = QuickConfig(4);
  cfg.station.camera_retry_delay_ms = 1;
  cfg.station.simulate.camera_fail_after = 2;
  cfg.station.simulate.camera_fail_count = 1000;
  std::optional<ScanEvent> last;
  auto result = RunScan(cfg, [&](const ScanEvent& e) { last = e; });
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kNoDevice);
  EXPECT_NE(result.error().message.find("gave up after 2 re-tries"), std::string::npos)
      << result.error().message;
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->state, ScanState::kFailed);
  EXPECT_EQ(last->stops_done, 2);
  const auto manifest = ReadJson(dir_ / "manifest.json");
  EXPECT_EQ(manifest["state"], "failed");
  EXPECT_EQ(manifest["error"]["code"], "no_device");
  EXPECT_EQ(manifest["stops_done"], 2);
  EXPECT_TRUE(fs::exists(dir_ / "frames/stop_001.png"));
}

// The quality gates: a bad frame is captured again; one that stays bad is kept with a warning
// in the manifest, and the scan still completes.
TEST_F(ScanSessionTest, ABlankFrameIsCapturedAgainAndTheScanIsClean) {
  StationConfig cfg = QuickConfig(4);
  cfg.station.simulate.camera_glitch = "blank";
  cfg.station.simulate.camera_glitch_after = 2;  // stop 2's first capture
  cfg.station.simulate.camera_glitch_count = 1;
  std::vector<std::string> notes;
  auto result = RunScan(cfg, CollectNotes(&notes));
  ASSERT_TRUE(result.has_value()) << result.error().message;
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("stop 2:"), std::string::npos) << notes[0];
  EXPECT_NE(notes[0].find("capturing again (1 of 2)"), std::string::npos) << notes[0];
  const auto manifest = ReadJson(dir_ / "manifest.json");
  EXPECT_EQ(manifest["state"], "complete");
  for (const auto& stop : manifest["stops"]) EXPECT_FALSE(stop.contains("quality")) << stop;
  EXPECT_GT(manifest["stops"][2]["mask_area_px"].get<int>(), 1000);
}

TEST_F(ScanSessionTest, AFrameThatStaysBadIsKeptWithAWarning) {
  for (const auto& [glitch, code] : std::vector<std::pair<std::string, std::string>>{
           {"blank", "empty_mask"}, {"blurred", "blurred"}, {"overexposed", "overexposed"}}) {
    SCOPED_TRACE(glitch);
    fs::remove_all(dir_);
    StationConfig cfg = QuickConfig(4);
    cfg.quality.recaptures = 1;
    cfg.station.simulate.camera_glitch = glitch;
    cfg.station.simulate.camera_glitch_after = 1;  // stop 1, both captures
    cfg.station.simulate.camera_glitch_count = 2;
    std::vector<std::string> notes;
    auto result = RunScan(cfg, CollectNotes(&notes));
    ASSERT_TRUE(result.has_value()) << result.error().message;
    ASSERT_EQ(notes.size(), 2u);
    EXPECT_NE(notes[0].find("capturing again (1 of 1)"), std::string::npos) << notes[0];
    EXPECT_NE(notes[1].find("stop 1: warning:"), std::string::npos) << notes[1];
    const auto manifest = ReadJson(dir_ / "manifest.json");
    EXPECT_EQ(manifest["state"], "complete");
    ASSERT_TRUE(manifest["stops"][1].contains("quality")) << manifest["stops"][1];
    std::vector<std::string> codes;
    for (const auto& w : manifest["stops"][1]["quality"]) {
      codes.push_back(w["code"]);
      EXPECT_FALSE(w["message"].get<std::string>().empty());
    }
    EXPECT_NE(std::find(codes.begin(), codes.end(), code), codes.end()) << manifest["stops"][1];
    for (int k : {0, 2, 3}) EXPECT_FALSE(manifest["stops"][k].contains("quality")) << k;
  }
}

// [segment] background_file: the empty scene from a file (as a real camera needs), and a clear
// error when the file is missing.
TEST_F(ScanSessionTest, TheBackgroundMethodTakesTheEmptySceneFromAFile) {
  StationConfig cfg = QuickConfig(4);
  cfg.segment.method = "background";
  const fs::path empty =
      fs::temp_directory_path() / ("revolve_session_empty_" + std::to_string(::getpid()) + ".png");
  {
    auto devices = OpenDevices(cfg);
    ASSERT_TRUE(devices.has_value()) << devices.error().message;
    ASSERT_TRUE(devices->camera->Start().has_value());
    auto frame = devices->camera->CaptureBackground(capture::Clock::now(), std::chrono::seconds(5));
    ASSERT_TRUE(frame.has_value()) << frame.error().message;
    ASSERT_TRUE(cv::imwrite(empty.string(), frame->image));
  }
  cfg.segment.background_file = empty;
  {
    auto result = RunScan(cfg);
    ASSERT_TRUE(result.has_value()) << result.error().message;
    const auto manifest = ReadJson(dir_ / "manifest.json");
    for (const auto& stop : manifest["stops"]) {
      EXPECT_GT(stop["mask_area_px"].get<int>(), 1000) << stop;
      EXPECT_FALSE(stop.contains("quality")) << stop;
    }
    EXPECT_TRUE(fs::exists(dir_ / "frames" / "background.png"));
  }
  fs::remove(empty);
  fs::remove_all(dir_);
  cfg.segment.background_file = empty;  // now missing
  auto result = RunScan(cfg);
  ASSERT_FALSE(result.has_value());
  EXPECT_NE(result.error().message.find("[segment] background_file"), std::string::npos)
      << result.error().message;
  EXPECT_NE(result.error().message.find(empty.string()), std::string::npos);
  EXPECT_EQ(ReadJson(dir_ / "manifest.json")["state"], "failed");
}

double IoU(const cv::Mat& a, const cv::Mat& b) {
  const double inter = cv::countNonZero(a & b);
  const double uni = cv::countNonZero(a | b);
  return uni > 0 ? inter / uni : 1.0;
}

// A real camera cannot capture the empty scene, and without [segment] background_file the
// backdrop is learned from the first stops as they arrive: a replayed turntable sequence (a vase
// over an uneven dark cloth, no background image) scanned with method background and auto.
TEST_F(ScanSessionTest, WithoutAnEmptySceneTheBackdropIsLearnedFromTheFirstStops) {
  constexpr int kStops = 8;
  const fs::path frames = dir_.string() + "_frames";
  fs::create_directories(frames);
  capture::SyntheticOptions o;
  o.object = "vase";
  o.width_px = 320;
  o.height_px = 240;
  o.noise_sigma = 0.0;
  o.backdrop_bgr = {0, 0, 0};
  auto camera = capture::SyntheticCamera::Create(o, std::make_shared<SimulatedPlate>());
  ASSERT_TRUE(camera.has_value()) << camera.error().message;
  const cv::Mat cloth = test_support::Cloth(cv::Size(320, 240), 6.0, 90.0, 23);
  std::vector<cv::Mat> truths;
  for (int k = 0; k < kStops; ++k) {
    const capture::RenderOutput render = (*camera)->RenderWithTruth(k * 360.0 / kStops, k);
    cv::Mat photo = cloth.clone();
    render.image.copyTo(photo, render.true_mask);
    truths.push_back(render.true_mask);
    ASSERT_TRUE(cv::imwrite((frames / fmt::format("stop_{:03}.png", k)).string(), photo));
  }
  for (const std::string method : {"background", "auto"}) {
    SCOPED_TRACE(method);
    fs::remove_all(dir_);
    StationConfig cfg = QuickConfig(kStops);
    cfg.camera.backend = "replay";
    cfg.camera.replay.dir = frames.string();
    cfg.camera.replay.pattern = "stop_{index:03}.png";
    cfg.camera.replay.step_deg = 360.0 / kStops;
    cfg.segment.method = method;
    std::vector<std::string> notes;
    auto result = RunScan(cfg, CollectNotes(&notes));
    ASSERT_TRUE(result.has_value()) << result.error().message;
    const auto manifest = ReadJson(dir_ / "manifest.json");
    ASSERT_TRUE(manifest.contains("segmentation")) << manifest.dump();
    EXPECT_EQ(manifest["segmentation"]["method"], "background") << manifest["segmentation"];
    EXPECT_EQ(manifest["segmentation"]["learned_after_stop"], 3);
    EXPECT_EQ(result->report["segmentation"], manifest["segmentation"]);
    EXPECT_TRUE(fs::exists(dir_ / "frames" / "background.png"));
    EXPECT_TRUE(std::any_of(notes.begin(), notes.end(), [](const std::string& n) {
      return n.find("backdrop learned") != std::string::npos;
    })) << fmt::format("{}", fmt::join(notes, "\n"));
    double sum = 0.0;
    for (int k = 0; k < kStops; ++k) {
      const cv::Mat mask = cv::imread(
          (dir_ / "masks" / manifest["stops"][k]["mask"].get<std::string>().substr(6)).string(),
          cv::IMREAD_GRAYSCALE);
      ASSERT_FALSE(mask.empty()) << k;
      const double iou = IoU(mask, truths[static_cast<std::size_t>(k)]);
      EXPECT_GE(iou, 0.97) << "stop " << k;
      if (k >= 4) sum += iou;
    }
    std::printf("%s: stops 4..7 (against the learned backdrop) mean IoU %.4f\n", method.c_str(),
                sum / 4.0);
  }
  fs::remove_all(frames);
}

TEST_F(ScanSessionTest, ADriveAlarmFailsTheScanWithTheAlarmCode) {
  StationConfig cfg = QuickConfig(4);
  cfg.station.simulate.drive_fault = "alarm";
  cfg.station.simulate.drive_fault_move = 2;
  cfg.station.simulate.drive_alarm_code = 0x31;
  std::optional<ScanEvent> last;
  auto result = RunScan(cfg, [&](const ScanEvent& e) { last = e; });
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kAlarm);
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->state, ScanState::kFailed);
  ASSERT_TRUE(last->alarm_code.has_value());
  EXPECT_EQ(*last->alarm_code, 0x31);
  const auto manifest = ReadJson(dir_ / "manifest.json");
  EXPECT_EQ(manifest["error"]["alarm_code"], 0x31);
  EXPECT_EQ(manifest["stops_done"], 2);
}

TEST_F(ScanSessionTest, AFullDiskFailsTheScanWithAClearError) {
  const StationConfig cfg = QuickConfig(8);
  auto devices = OpenDevices(cfg);
  ASSERT_TRUE(devices.has_value());
  auto folder = ScanFolder::Create(dir_);
  ASSERT_TRUE(folder.has_value());
  folder->SetByteLimit(60000);
  ScanSession session(cfg, *devices, *folder);
  auto result = session.Run(std::stop_token());
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kIo);
  EXPECT_NE(result.error().message.find("No space left on device"), std::string::npos)
      << result.error().message;
  // Whatever got written is whole: every listed stop has its files.
  const auto manifest = ReadJson(dir_ / "manifest.json");
  for (const auto& stop : manifest["stops"]) {
    EXPECT_TRUE(fs::exists(dir_ / stop["frame"].get<std::string>()));
    EXPECT_TRUE(fs::exists(dir_ / stop["mask"].get<std::string>()));
  }
  for (const auto& entry : fs::recursive_directory_iterator(dir_)) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path();
  }
}

TEST_F(ScanSessionTest, AnInterruptedScanIsResumedFromItsSavedStops) {
  const StationConfig cfg = QuickConfig(6);
  {
    auto devices = OpenDevices(cfg);
    ASSERT_TRUE(devices.has_value());
    auto folder = ScanFolder::Create(dir_);
    ASSERT_TRUE(folder.has_value());
    ScanSession session(cfg, *devices, *folder);
    std::stop_source stop;
    session.OnStop([&](const StopProgress& p) {
      if (p.index == 2) stop.request_stop();
    });
    ASSERT_FALSE(session.Run(stop.get_token()).has_value());
  }
  ASSERT_EQ(ReadJson(dir_ / "manifest.json")["stops_done"], 3);

  auto devices = OpenDevices(cfg);
  ASSERT_TRUE(devices.has_value());
  auto folder = ScanFolder::Open(dir_);
  ASSERT_TRUE(folder.has_value()) << folder.error().message;
  ScanSession session(cfg, *devices, *folder);
  std::vector<int> captured;
  session.OnStop([&](const StopProgress& p) { captured.push_back(p.index); });
  std::vector<ScanEvent> events;
  session.OnEvent([&](const ScanEvent& e) { events.push_back(e); });
  auto result = session.Resume(std::stop_token());
  ASSERT_TRUE(result.has_value()) << result.error().message;
  EXPECT_EQ(captured, (std::vector<int>{3, 4, 5}));
  EXPECT_EQ(result->stops_done, 6);
  ASSERT_GE(events.size(), 2u);
  EXPECT_EQ(events[0].state, ScanState::kHoming);
  EXPECT_EQ(events[0].stops_done, 3);
  EXPECT_NE(events[1].note.find("resuming"), std::string::npos);
  const auto manifest = ReadJson(dir_ / "manifest.json");
  EXPECT_EQ(manifest["state"], "complete");
  EXPECT_EQ(manifest["stops"].size(), 6u);
  for (int k = 0; k < 6; ++k) EXPECT_EQ(manifest["stops"][k]["index"], k);
  EXPECT_EQ(manifest["resumed"].size(), 1u);
  EXPECT_TRUE(fs::exists(dir_ / "model/model.ply"));

  // A complete scan is not resumed again.
  ScanSession again(cfg, *devices, *folder);
  auto twice = again.Resume(std::stop_token());
  ASSERT_FALSE(twice.has_value());
  EXPECT_EQ(twice.error().code, ErrorCode::kBadInput);
}

TEST_F(ScanSessionTest, AStopRequestStopsTheMotorFromTheRequestingThread) {
  StationConfig cfg = QuickConfig(8);
  cfg.turntable.mock.time_scale = 1.0;  // slow real-time moves: the stop lands mid-move
  auto devices = OpenDevices(cfg);
  ASSERT_TRUE(devices.has_value());
  auto folder = ScanFolder::Create(dir_);
  ASSERT_TRUE(folder.has_value());
  ScanSession session(cfg, *devices, *folder);
  std::stop_source stop;
  std::atomic<bool> moving{false};
  session.OnEvent([&](const ScanEvent& e) {
    if (e.state == ScanState::kMoving && e.stop == 1) moving = true;
  });
  std::jthread scanner([&] {
    auto result = session.Run(stop.get_token());
    EXPECT_FALSE(result.has_value());
  });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!moving && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(moving);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  session.SetAbortReason("test");
  stop.request_stop();
  // The motor is stopped by the time request_stop() returns.
  auto state = devices->turntable->State();
  ASSERT_TRUE(state.has_value());
  EXPECT_FALSE(state->moving);
  scanner.join();
  const auto manifest = ReadJson(dir_ / "manifest.json");
  EXPECT_EQ(manifest["state"], "aborted");
  EXPECT_EQ(manifest["abort"]["reason"], "test");
  EXPECT_LT(manifest["abort"]["motor_stop_ms"].get<double>(), 1000.0);
  EXPECT_NE(manifest["error"]["message"].get<std::string>().find("aborted (test)"),
            std::string::npos);
}

}  // namespace
}  // namespace revolve::station
