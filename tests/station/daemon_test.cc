// The daemon in-process: socket protocol, one scan at a time, abort, the operator panel through a
// fake GPIO seam. (tests/e2e/daemon_test.cc runs the real revolved process.)
#include <sys/eventfd.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "base/unique_fd.h"
#include "station/commands/control_client.h"
#include "station/daemon.h"
#include "tests/support/control_events.h"

namespace revolve::station {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

nlohmann::json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return nlohmann::json::parse(s.str());
}

// A thread-safe fake panel: the test presses buttons, the daemon's loop reads them.
class FakePanel final : public OperatorLines {
 public:
  FakePanel() : wake_(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK)) {}
  bool Has(PanelButton) const override { return true; }
  bool Has(PanelOutput) const override { return true; }
  std::vector<int> EventFds() const override { return {wake_.get()}; }
  Expected<std::vector<ButtonEdge>> ReadEdges() override {
    std::uint64_t n;
    (void)!::read(wake_.get(), &n, sizeof(n));
    std::lock_guard lock(mutex_);
    std::vector<ButtonEdge> out = std::move(pending_);
    pending_.clear();
    return out;
  }
  Expected<bool> Active(PanelButton b) override {
    std::lock_guard lock(mutex_);
    return b == PanelButton::kStart ? start_ : abort_;
  }
  Expected<void> Set(PanelOutput o, bool on) override {
    std::lock_guard lock(mutex_);
    (o == PanelOutput::kLed ? led_ : lamp_).push_back(on);
    return {};
  }
  std::string Describe() const override { return "fake panel"; }

  // Press (with a little bounce) and release `b`.
  void Press(PanelButton b) {
    {
      std::lock_guard lock(mutex_);
      const MonoTime t = MonoNow();
      for (int i = 0; i < 3; ++i) pending_.push_back({b, i % 2 == 0, t + i * 200us});
      pending_.push_back({b, true, t + 600us});
      (b == PanelButton::kStart ? start_ : abort_) = true;
    }
    Wake();
    std::this_thread::sleep_for(100ms);  // held longer than the debounce window
    {
      std::lock_guard lock(mutex_);
      pending_.push_back({b, false, MonoNow()});
      (b == PanelButton::kStart ? start_ : abort_) = false;
    }
    Wake();
  }
  std::vector<bool> Led() {
    std::lock_guard lock(mutex_);
    return led_;
  }
  std::vector<bool> Lamp() {
    std::lock_guard lock(mutex_);
    return lamp_;
  }

 private:
  void Wake() {
    const std::uint64_t one = 1;
    (void)!::write(wake_.get(), &one, sizeof(one));
  }
  UniqueFd wake_;
  std::mutex mutex_;
  std::vector<ButtonEdge> pending_;
  bool start_ = false;
  bool abort_ = false;
  std::vector<bool> led_;
  std::vector<bool> lamp_;
};

class DaemonTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    dir_ = fmt::format("/tmp/rvs_{}_{}", ::getpid(), counter++);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    StopDaemon();
    if (!HasFailure()) fs::remove_all(dir_);
  }

  std::string Config(const std::string& extra = "", double time_scale = 0.01) const {
    return fmt::format(R"([daemon]
socket = "{0}/s.sock"
max_request_bytes = 256
max_clients = 4
[web]
listen = ""
[station]
scans_dir = "{0}/scans"
min_free_mb = 0
camera_retry_delay_ms = 1
[recipes.tiny]
stops = 4
step_deg = 90.0
resolution = 24
[scan]
stops = 6
step_deg = 60.0
settle_ms = 0
[turntable.mock]
time_scale = {1}
[camera.synthetic]
object = "sphere"
radius_mm = 40.0
target_height_mm = 40.0
width_px = 160
height_px = 120
[reconstruct]
resolution = 32
{2}
)",
                       dir_.string(), time_scale, extra);
  }

  void StartDaemon(const std::string& text, std::unique_ptr<OperatorLines> panel = nullptr) {
    auto document = config::Parse(text, "daemon.toml");
    ASSERT_TRUE(document.has_value()) << document.error().message;
    auto cfg = ParseStationConfig(*document);
    ASSERT_TRUE(cfg.has_value()) << cfg.error().message;
    DaemonHooks hooks;
    hooks.panel_lines = std::move(panel);
    auto daemon = Daemon::Create(std::move(*cfg), std::move(hooks));
    ASSERT_TRUE(daemon.has_value()) << daemon.error().message;
    daemon_ = std::move(*daemon);
    runner_ = std::jthread([this] { exit_code_ = daemon_->Run(); });
  }

  void StopDaemon() {
    if (!daemon_) return;
    daemon_->RequestShutdown();
    runner_.join();
    daemon_.reset();
  }

  ControlClient Connect() {
    auto client = ControlClient::Connect(dir_ / "s.sock");
    EXPECT_TRUE(client.has_value()) << client.error().message;
    return std::move(*client);
  }

  // Reads events until `state` (for any scan); returns them all.
  std::vector<nlohmann::json> EventsUntil(ControlClient& c, const std::string& state,
                                          std::chrono::seconds timeout = 60s) {
    return test_support::EventsUntil(c, {state}, timeout, 1000ms);
  }

  nlohmann::json Status() {
    ControlClient c = Connect();
    auto reply = c.Call({{"cmd", "status"}}, 10s);
    EXPECT_TRUE(reply.has_value());
    return (*reply)["status"];
  }

  fs::path dir_;
  std::unique_ptr<Daemon> daemon_;
  std::jthread runner_;
  int exit_code_ = -1;
};

TEST_F(DaemonTest, StartWatchToCompletionThenStatusAndList) {
  StartDaemon(Config());
  ControlClient c = Connect();
  auto watch = c.Call({{"cmd", "watch"}, {"id", 1}}, 10s);
  ASSERT_TRUE(watch.has_value()) << watch.error().message;
  EXPECT_EQ((*watch)["ok"], true);
  EXPECT_EQ((*watch)["id"], 1);
  EXPECT_EQ((*watch)["status"]["state"], "idle");

  auto start = c.Call({{"cmd", "start"}, {"recipe", "tiny"}, {"id", 2}}, 10s);
  ASSERT_TRUE(start.has_value());
  ASSERT_EQ((*start)["ok"], true) << start->dump();
  EXPECT_EQ((*start)["id"], 2);
  const std::string id = (*start)["scan"]["id"];
  const fs::path scan_dir = (*start)["scan"]["dir"].get<std::string>();
  EXPECT_EQ((*start)["scan"]["recipe"], "tiny");

  auto events = EventsUntil(c, "done");
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front()["state"], "homing");
  int integrating = 0;
  for (const auto& e : events) {
    EXPECT_EQ(e["scan_id"], id);
    integrating += e["state"] == "integrating";
  }
  EXPECT_EQ(integrating, 4);
  EXPECT_EQ(events.back()["stops_done"], 4);
  EXPECT_DOUBLE_EQ(events.back()["progress"].get<double>(), 1.0);

  const auto manifest = ReadJson(scan_dir / "manifest.json");
  EXPECT_EQ(manifest["state"], "complete");
  EXPECT_EQ(manifest["recipe"], "tiny");
  EXPECT_TRUE(fs::exists(scan_dir / "model/model.ply"));
  EXPECT_TRUE(fs::exists(scan_dir / "report.json"));
  EXPECT_NE(std::ifstream(scan_dir / "scan.toml").peek(), EOF);

  const auto status = Status();
  EXPECT_EQ(status["state"], "done");
  EXPECT_EQ(status["scan"]["id"], id);
  EXPECT_EQ(status["busy"], false);
  EXPECT_EQ(status["devices"]["ok"], true);

  auto list = c.Call({{"cmd", "list"}}, 10s);
  ASSERT_TRUE(list.has_value());
  ASSERT_EQ((*list)["scans"].size(), 1u);
  EXPECT_EQ((*list)["scans"][0]["id"], id);
  EXPECT_EQ((*list)["scans"][0]["state"], "complete");
}

TEST_F(DaemonTest, OneScanAtATimeAndAbort) {
  StartDaemon(Config("", 0.2));
  ControlClient c = Connect();
  ASSERT_TRUE(c.Call({{"cmd", "watch"}}, 10s).has_value());
  auto first = c.Call({{"cmd", "start"}}, 10s);
  ASSERT_TRUE(first.has_value());
  ASSERT_EQ((*first)["ok"], true);
  const std::string id = (*first)["scan"]["id"];

  ControlClient other = Connect();
  auto second = other.Call({{"cmd", "start"}}, 10s);
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ((*second)["ok"], false);
  EXPECT_EQ((*second)["error"]["code"], "busy");
  EXPECT_NE((*second)["error"]["message"].get<std::string>().find(id), std::string::npos);

  EventsUntil(c, "moving");
  auto abort = other.Call({{"cmd", "abort"}}, 10s);
  ASSERT_TRUE(abort.has_value());
  EXPECT_EQ((*abort)["ok"], true);
  EXPECT_EQ((*abort)["scan_id"], id);
  auto events = EventsUntil(c, "aborted");
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back()["error"]["code"], "aborted");
  const auto manifest = ReadJson(dir_ / "scans" / id / "manifest.json");
  EXPECT_EQ(manifest["state"], "aborted");

  // Nothing to abort now; a new scan may start.
  auto again = other.Call({{"cmd", "abort"}}, 10s);
  EXPECT_EQ((*again)["ok"], false);
  auto unknown = other.Call({{"cmd", "start"}, {"recipe", "turbo"}}, 10s);
  EXPECT_EQ((*unknown)["ok"], false);
  EXPECT_EQ((*unknown)["error"]["code"], "not_found");
}

TEST_F(DaemonTest, MalformedAndOversizedRequestsGetErrorReplies) {
  StartDaemon(Config());
  ControlClient c = Connect();
  for (const char* bad : {"hello\n", "{\"cmd\":\n", "[]\n", "{\"cmd\":\"fly\"}\n",
                          "\x01\x02\xff\xfe\n", "{\"cmd\":\"start\",\"resume\":\"../../etc\"}\n"}) {
    ASSERT_TRUE(c.SendRaw(bad).has_value());
    auto reply = c.Receive(10s);
    ASSERT_TRUE(reply.has_value()) << bad;
    EXPECT_EQ((*reply)["ok"], false) << bad;
    EXPECT_TRUE((*reply)["error"]["message"].is_string());
  }
  ASSERT_TRUE(c.SendRaw(std::string(5000, 'x') + "\n").has_value());
  auto too_long = c.Receive(10s);
  ASSERT_TRUE(too_long.has_value());
  EXPECT_EQ((*too_long)["error"]["code"], "protocol");
  EXPECT_NE((*too_long)["error"]["message"].get<std::string>().find("256"), std::string::npos);
  // Blank lines are ignored; the connection still works.
  ASSERT_TRUE(c.SendRaw("\n\r\n").has_value());
  auto status = c.Call({{"cmd", "status"}}, 10s);
  ASSERT_TRUE(status.has_value());
  EXPECT_EQ((*status)["ok"], true);
}

TEST_F(DaemonTest, TooManyClientsAreTurnedAway) {
  StartDaemon(Config());
  std::vector<ControlClient> clients;
  for (int i = 0; i < 4; ++i) {
    clients.push_back(Connect());
    ASSERT_TRUE(clients.back().Call({{"cmd", "status"}}, 10s).has_value());
  }
  ControlClient extra = Connect();
  auto reply = extra.Receive(10s);
  ASSERT_TRUE(reply.has_value());
  EXPECT_EQ((*reply)["error"]["code"], "busy");
  clients.pop_back();
  // A slot frees when a client leaves.
  bool served = false;
  for (int attempt = 0; attempt < 50 && !served; ++attempt) {
    ControlClient late = Connect();
    auto r = late.Call({{"cmd", "status"}}, 2s);
    served = r.has_value() && (*r)["ok"] == true;
    if (!served) std::this_thread::sleep_for(20ms);
  }
  EXPECT_TRUE(served);
}

TEST_F(DaemonTest, TheStartButtonStartsAScanTheLedBlinksAndTheLampLights) {
  auto panel = std::make_unique<FakePanel>();
  FakePanel* fake = panel.get();
  StartDaemon(Config("", 0.2), std::move(panel));
  ControlClient c = Connect();
  ASSERT_TRUE(c.Call({{"cmd", "watch"}}, 10s).has_value());
  fake->Press(PanelButton::kStart);
  EventsUntil(c, "homing");
  EXPECT_EQ(Status()["led"], "scanning");
  EventsUntil(c, "done");
  std::this_thread::sleep_for(200ms);
  const auto status = Status();
  EXPECT_EQ(status["led"], "ready");
  EXPECT_EQ(status["panel"], "fake panel");
  // The lamp was on during the scan and is off again; the LED blinked (several changes) and
  // ends lit.
  const auto lamp = fake->Lamp();
  ASSERT_GE(lamp.size(), 3u);
  EXPECT_EQ(lamp[0], false);
  EXPECT_EQ(lamp[1], true);
  EXPECT_EQ(lamp.back(), false);
  const auto led = fake->Led();
  EXPECT_GE(led.size(), 3u);
  EXPECT_EQ(led.back(), true);
}

TEST_F(DaemonTest, ADriveAlarmIsAFaultWithItsCodeAndTheDaemonKeepsServing) {
  auto panel = std::make_unique<FakePanel>();
  StartDaemon(Config("[station.simulate]\ndrive_fault = \"alarm\"\ndrive_fault_move = 2\n"
                     "drive_alarm_code = 49\n"),
              std::move(panel));
  ControlClient c = Connect();
  ASSERT_TRUE(c.Call({{"cmd", "watch"}}, 10s).has_value());
  ASSERT_EQ((*c.Call({{"cmd", "start"}}, 10s))["ok"], true);
  auto events = EventsUntil(c, "failed");
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back()["error"]["code"], "alarm");
  EXPECT_EQ(events.back()["alarm"]["code"], 49);
  const auto status = Status();
  EXPECT_EQ(status["state"], "failed");
  EXPECT_EQ(status["led"], "fault");
  EXPECT_EQ(status["alarm"]["code"], 49);
  // The next scan homes (clearing the alarm) and completes.
  ASSERT_EQ((*c.Call({{"cmd", "start"}, {"recipe", "tiny"}}, 10s))["ok"], true);
  EventsUntil(c, "done");
  EXPECT_EQ(Status()["led"], "ready");
}

TEST_F(DaemonTest, NotEnoughFreeSpaceRefusesTheStart) {
  std::string text = Config();
  text.replace(text.find("min_free_mb = 0"), 15, "min_free_mb = 9999999");
  StartDaemon(text);
  ControlClient c = Connect();
  auto reply = c.Call({{"cmd", "start"}}, 10s);
  ASSERT_TRUE(reply.has_value());
  EXPECT_EQ((*reply)["ok"], false);
  EXPECT_EQ((*reply)["error"]["code"], "io");
  EXPECT_NE((*reply)["error"]["message"].get<std::string>().find("min_free_mb"), std::string::npos);
}

TEST_F(DaemonTest, AnotherDaemonOnTheSameSocketIsRefused) {
  StartDaemon(Config());
  auto document = config::Parse(Config(), "daemon.toml");
  auto cfg = ParseStationConfig(*document);
  ASSERT_TRUE(cfg.has_value());
  auto second = Daemon::Create(std::move(*cfg), DaemonHooks{});
  ASSERT_FALSE(second.has_value());
  EXPECT_EQ(second.error().code, ErrorCode::kBusy);
  // The first one still serves.
  EXPECT_EQ(Status()["state"], "idle");
}

}  // namespace
}  // namespace revolve::station
