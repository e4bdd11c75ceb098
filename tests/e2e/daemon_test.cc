// End to end: the real revolved process on the simulated rig, driven through its control socket
// and the real revolve CLI: scans, progress, faults (SIGTERM, camera loss, stall, alarm, disk
// full, config errors), sd_notify, a soak, socket fuzzing, and the Modbus drive simulator.
#include <grp.h>
#include <poll.h>
#include <sys/mount.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/un.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <iostream>
#include <map>
#include <mutex>
#include <random>
#include <regex>
#include <set>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "base/unique_fd.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/metrics/metrics.h"
#include "station/commands/control_client.h"
#include "station/protocol.h"
#include "tests/e2e/daemon_harness.h"
#include "tests/support/control_events.h"

namespace revolve::e2e {
namespace {

using station::ControlClient;

nlohmann::json ReadJson(const fs::path& path) { return nlohmann::json::parse(ReadAll(path)); }

class DaemonE2eTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    dir_ = fmt::format("/tmp/rve_{}_{}", ::getpid(), counter++);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    daemon_.Kill();
    helper_.Kill();
    socat_.Kill();
    if (mounted_) ::umount2((dir_ / "scans").c_str(), MNT_DETACH);
    if (!HasFailure()) fs::remove_all(dir_);
  }

  std::string Config(const std::string& extra = "", double time_scale = 0.01,
                     double settle_ms = 0.0) const {
    return fmt::format(R"([daemon]
socket = "{0}/ctl.sock"
socket_mode = "0640"
[web]
listen = ""
[station]
scans_dir = "{0}/scans"
min_free_mb = 0
camera_retry_delay_ms = 5
[recipes.tiny]
stops = 4
step_deg = 90.0
resolution = 24
[scan]
stops = 8
step_deg = 45.0
settle_ms = {2}
move_timeout_s = 2.0
[turntable.mock]
time_scale = {1}
[camera.synthetic]
object = "sphere"
radius_mm = 40.0
target_height_mm = 40.0
width_px = 160
height_px = 120
[reconstruct]
resolution = 40
volume_radius_mm = 55.0
volume_height_mm = 90.0
{3}
)",
                       dir_.string(), time_scale, settle_ms, extra);
  }

  fs::path WriteConfig(const std::string& text, const std::string& name = "revolved.toml") {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p;
  }

  fs::path Socket() const { return dir_ / "ctl.sock"; }

  // Starts revolved and waits until its socket answers.
  void StartDaemon(const fs::path& config, const std::vector<std::string>& env = {}) {
    daemon_.Kill();
    daemon_ = Child::Spawn({REVOLVED_BIN, "--config", config.string()}, env, dir_ / "revolved.out",
                           dir_ / "revolved.err");
    const auto deadline = std::chrono::steady_clock::now() + 30s;
    while (std::chrono::steady_clock::now() < deadline) {
      if (auto code = daemon_.Wait(0ms)) {
        FAIL() << "revolved exited with " << *code << ": " << ReadAll(dir_ / "revolved.err");
      }
      if (auto c = ControlClient::Connect(Socket())) {
        if (auto r = c->Call({{"cmd", "status"}}, 5s); r && (*r)["ok"] == true) return;
      }
      std::this_thread::sleep_for(20ms);
    }
    FAIL() << "revolved did not serve " << Socket();
  }

  std::string DaemonLog() const { return ReadAll(dir_ / "revolved.err"); }

  CommandResult Cli(std::vector<std::string> args, std::chrono::milliseconds timeout = 120s) {
    args.insert(args.begin(), REVOLVE_BIN);
    return RunCommand(args, {"REVOLVE_SOCKET=" + Socket().string()}, dir_, timeout);
  }

  ControlClient Client() {
    auto c = ControlClient::Connect(Socket());
    EXPECT_TRUE(c.has_value()) << c.error().message;
    return std::move(*c);
  }

  nlohmann::json Status() {
    ControlClient c = Client();
    auto r = c.Call({{"cmd", "status"}}, 10s);
    EXPECT_TRUE(r.has_value());
    return (*r)["status"];
  }

  // Events until one in `states` arrives (or the timeout).
  std::vector<nlohmann::json> EventsUntil(ControlClient& c, const std::set<std::string>& states,
                                          std::chrono::seconds timeout = 90s) {
    return test_support::EventsUntil(c, states, timeout, 500ms);
  }

  fs::path dir_;
  Child daemon_;
  Child helper_;
  Child socat_;
  bool mounted_ = false;
};

bool Contains(const std::string& text, const std::string& what) {
  return text.find(what) != std::string::npos;
}

TEST_F(DaemonE2eTest, StartWatchStatusAndListThroughTheCli) {
  StartDaemon(WriteConfig(Config()));
  const CommandResult start = Cli({"start", "--watch", "--recipe", "tiny"});
  ASSERT_EQ(start.exit_code, 0) << start.out << start.err;
  EXPECT_TRUE(Contains(start.out, "revolve start: scan ")) << start.out;
  EXPECT_TRUE(Contains(start.out, "stop 4/4")) << start.out;
  EXPECT_TRUE(Contains(start.out, "done")) << start.out;

  const CommandResult status = Cli({"status"});
  ASSERT_EQ(status.exit_code, 0) << status.err;
  EXPECT_TRUE(Contains(status.out, "state     done")) << status.out;
  EXPECT_TRUE(Contains(status.out, "recipe tiny")) << status.out;
  const CommandResult watch = Cli({"watch"});  // nothing running: prints the state, exits 0
  EXPECT_EQ(watch.exit_code, 0) << watch.err;
  EXPECT_TRUE(Contains(watch.out, "done")) << watch.out;

  const CommandResult list = Cli({"list"});
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_TRUE(Contains(list.out, "complete")) << list.out;
  EXPECT_TRUE(Contains(list.out, "model/model.ply")) << list.out;

  // The scan folder and its model.
  const auto json = nlohmann::json::parse(Cli({"status", "--json"}).out);
  const fs::path scan = json["scan"]["dir"].get<std::string>();
  for (const char* f : {"scan.toml", "manifest.json", "report.json", "contact_sheet.png",
                        "model/model.ply", "frames/stop_003.png", "masks/stop_003.png"}) {
    EXPECT_TRUE(fs::exists(scan / f)) << f;
  }
  const auto manifest = ReadJson(scan / "manifest.json");
  EXPECT_EQ(manifest["state"], "complete");
  EXPECT_EQ(manifest["stops"].size(), 4u);
  auto mesh = reconstruct::ReadPly(scan / "model/model.ply");
  ASSERT_TRUE(mesh.has_value()) << mesh.error().message;
  const auto stats = reconstruct::ComputeStats(*mesh);
  EXPECT_TRUE(stats.closed);
  EXPECT_GT(stats.triangle_count, 100);
  // The socket's mode comes from the config.
  struct stat st {};
  ASSERT_EQ(::stat(Socket().c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
}

TEST_F(DaemonE2eTest, WatchShowsProgressAndASecondStartIsRefused) {
  StartDaemon(WriteConfig(Config("", 0.2, 60.0)));
  const CommandResult start = Cli({"start"});
  ASSERT_EQ(start.exit_code, 0) << start.out << start.err;
  const CommandResult again = Cli({"start"});
  EXPECT_EQ(again.exit_code, 75) << again.out << again.err;
  EXPECT_TRUE(Contains(again.err, "one scan at a time")) << again.err;
  const CommandResult watch = Cli({"watch"});
  ASSERT_EQ(watch.exit_code, 0) << watch.out << watch.err;
  EXPECT_TRUE(Contains(watch.out, "ETA")) << watch.out;
  EXPECT_TRUE(Contains(watch.out, "[#")) << watch.out;
  EXPECT_TRUE(Contains(watch.out, "stop 8/8")) << watch.out;
  EXPECT_TRUE(Contains(watch.out, "done")) << watch.out;
  // Each transition was logged.
  EXPECT_TRUE(Contains(DaemonLog(), ": capturing stop 8/8")) << DaemonLog();
}

TEST_F(DaemonE2eTest, SigtermMidScanStopsTheMotorThenReconstructAndResume) {
  const fs::path config = WriteConfig(Config("", 0.2, 60.0));
  StartDaemon(config);
  ControlClient c = Client();
  ASSERT_TRUE(c.Call({{"cmd", "watch"}}, 10s).has_value());
  auto start = c.Call({{"cmd", "start"}}, 10s);
  ASSERT_TRUE(start.has_value());
  ASSERT_EQ((*start)["ok"], true) << start->dump();
  const std::string id = (*start)["scan"]["id"];
  const fs::path scan = (*start)["scan"]["dir"].get<std::string>();
  // Wait until two stops are saved and the table moves to the third.
  for (;;) {
    auto events = EventsUntil(c, {"moving", "done", "failed", "aborted"});
    ASSERT_FALSE(events.empty());
    ASSERT_EQ(events.back()["state"], "moving");
    if (events.back()["stop"] == 2) break;
  }
  const auto t = std::chrono::steady_clock::now();
  daemon_.Signal(SIGTERM);
  const auto code = daemon_.Wait(10s);
  const double exit_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  ASSERT_TRUE(code.has_value()) << "revolved did not exit after SIGTERM";
  EXPECT_EQ(*code, 0) << DaemonLog();
  EXPECT_LT(exit_s, 5.0);
  // The watcher saw the end.
  auto last = EventsUntil(c, {"aborted", "done", "failed"}, 5s);
  ASSERT_FALSE(last.empty());
  EXPECT_EQ(last.back()["state"], "aborted");

  const auto manifest = ReadJson(scan / "manifest.json");
  EXPECT_EQ(manifest["state"], "aborted");
  EXPECT_TRUE(Contains(manifest["abort"]["reason"].get<std::string>(), "SIGTERM"));
  EXPECT_LT(manifest["abort"]["motor_stop_ms"].get<double>(), 1000.0);
  const int done = manifest["stops_done"];
  EXPECT_GE(done, 2);
  EXPECT_LT(done, 8);
  for (const auto& s : manifest["stops"]) {
    EXPECT_TRUE(fs::exists(scan / s["frame"].get<std::string>()));
    EXPECT_TRUE(fs::exists(scan / s["mask"].get<std::string>()));
  }
  std::smatch m;
  const std::string log = DaemonLog();
  ASSERT_TRUE(std::regex_search(log, m, std::regex("motor stopped and disabled in ([0-9.]+) ms")))
      << log;
  EXPECT_LT(std::stod(m[1]), 1000.0);
  EXPECT_FALSE(fs::exists(Socket()));

  // A model from the stops it has.
  const CommandResult rebuilt = Cli(
      {"reconstruct", scan.string(), "--out", (dir_ / "rebuilt").string(), "--resolution", "24"});
  ASSERT_EQ(rebuilt.exit_code, 0) << rebuilt.out << rebuilt.err;
  EXPECT_TRUE(Contains(rebuilt.out, fmt::format("{} of 8 stops", done))) << rebuilt.out;
  EXPECT_TRUE(fs::exists(dir_ / "rebuilt/model.ply"));

  // Resume: re-home and finish the missing stops.
  StartDaemon(config);
  const CommandResult list = Cli({"list"});
  EXPECT_TRUE(Contains(list.out, "aborted")) << list.out;
  const CommandResult resume = Cli({"start", "--resume", id, "--watch"});
  ASSERT_EQ(resume.exit_code, 0) << resume.out << resume.err;
  EXPECT_TRUE(Contains(resume.out, "resumed")) << resume.out;
  const auto finished = ReadJson(scan / "manifest.json");
  EXPECT_EQ(finished["state"], "complete");
  EXPECT_EQ(finished["stops"].size(), 8u);
  EXPECT_EQ(finished["resumed"].size(), 1u);
  EXPECT_TRUE(fs::exists(scan / "model/model.ply"));
  // Unknown or malformed ids are refused.
  EXPECT_EQ(Cli({"start", "--resume", "nope"}).exit_code, 1);
  EXPECT_EQ(Cli({"start", "--resume", "../etc"}).exit_code, 1);
}

TEST_F(DaemonE2eTest, ALostCameraIsRetriedThenFailsCleanlyAndTheDaemonKeepsServing) {
  StartDaemon(
      WriteConfig(Config("[station.simulate]\ncamera_fail_after = 3\n"
                         "camera_fail_count = 4\n")));
  const CommandResult first = Cli({"start", "--watch", "--recipe", "tiny"});
  EXPECT_EQ(first.exit_code, 1) << first.out << first.err;
  EXPECT_TRUE(Contains(first.err, "gave up after 2 re-tries")) << first.err;
  EXPECT_TRUE(Contains(first.out, "re-try 1 of 2")) << first.out;
  const auto status = Status();
  EXPECT_EQ(status["state"], "failed");
  EXPECT_EQ(status["error"]["code"], "no_device");
  EXPECT_EQ(status["led"], "fault");
  EXPECT_EQ(status["stops_done"], 3);
  const auto manifest =
      ReadJson(fs::path(status["scan"]["dir"].get<std::string>()) / "manifest.json");
  EXPECT_EQ(manifest["state"], "failed");
  // The camera comes back: the next scan re-tries one frame and completes.
  const CommandResult second = Cli({"start", "--watch", "--recipe", "tiny"});
  EXPECT_EQ(second.exit_code, 0) << second.out << second.err;
  EXPECT_EQ(Status()["led"], "ready");
}

TEST_F(DaemonE2eTest, ADriveStallAbortsTheScanWithAClearStatus) {
  StartDaemon(
      WriteConfig(Config("[station.simulate]\ndrive_fault = \"stall\"\n"
                         "drive_fault_move = 1\n")));
  const CommandResult r = Cli({"start", "--watch", "--recipe", "tiny"});
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  const CommandResult status = Cli({"status"});
  EXPECT_TRUE(Contains(status.out, "state     failed")) << status.out;
  EXPECT_TRUE(Contains(status.out, "error     stalled")) << status.out;
  EXPECT_TRUE(Contains(status.out, "led       fault")) << status.out;
  EXPECT_EQ(Status()["stops_done"], 1);
}

TEST_F(DaemonE2eTest, ADriveAlarmPutsItsCodeInTheStatus) {
  StartDaemon(
      WriteConfig(Config("[station.simulate]\ndrive_fault = \"alarm\"\n"
                         "drive_fault_move = 2\ndrive_alarm_code = 49\n")));
  const CommandResult r = Cli({"start", "--watch", "--recipe", "tiny"});
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_TRUE(Contains(r.out, "drive alarm 49")) << r.out;
  const CommandResult status = Cli({"status"});
  EXPECT_TRUE(Contains(status.out, "drive alarm 49 (0x31)")) << status.out;
  EXPECT_TRUE(Contains(status.out, "led       fault")) << status.out;
  EXPECT_TRUE(Contains(DaemonLog(), "drive alarm 0x31")) << DaemonLog();
}

TEST_F(DaemonE2eTest, AFullDiskFailsTheScanAndKeepsEarlierScans) {
  fs::create_directories(dir_ / "scans");
  mounted_ =
      ::geteuid() == 0 && ::mount("tmpfs", (dir_ / "scans").c_str(), "tmpfs", 0, "size=3m") == 0;
  if (!mounted_) {
    // No tmpfs here (not root): the simulated disk of [station.simulate] disk_limit_bytes.
    StartDaemon(WriteConfig(Config("[station.simulate]\ndisk_limit_bytes = 30000\n")));
    const CommandResult r = Cli({"start", "--watch"});
    EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
    EXPECT_TRUE(Contains(r.err, "No space left on device")) << r.err;
    EXPECT_EQ(Status()["error"]["code"], "io");
    return;
  }
  StartDaemon(WriteConfig(Config()));
  ASSERT_EQ(Cli({"start", "--watch", "--recipe", "tiny"}).exit_code, 0);
  const fs::path first = Status()["scan"]["dir"].get<std::string>();
  std::map<std::string, std::string> before;
  for (const auto& e : fs::recursive_directory_iterator(first)) {
    if (e.is_regular_file()) before[e.path().string()] = ReadAll(e.path());
  }
  // Fill the disk, leaving ~40 kB: a frame or two of the next scan.
  struct statvfs vfs {};
  ASSERT_EQ(::statvfs((dir_ / "scans").c_str(), &vfs), 0);
  const long long free_bytes = static_cast<long long>(vfs.f_bavail) * vfs.f_frsize;
  {
    std::ofstream filler(dir_ / "scans" / "filler", std::ios::binary);
    const std::string block(4096, 'x');
    for (long long n = 0; n + 40000 < free_bytes; n += 4096) filler << block;
  }
  const CommandResult full = Cli({"start", "--watch"});
  EXPECT_EQ(full.exit_code, 1) << full.out << full.err;
  EXPECT_TRUE(Contains(full.err, "No space left on device")) << full.err;
  const auto status = Status();
  EXPECT_EQ(status["state"], "failed");
  EXPECT_EQ(status["error"]["code"], "io");
  // Nothing half-written; the earlier scan untouched.
  for (const auto& e : fs::recursive_directory_iterator(dir_ / "scans")) {
    EXPECT_FALSE(Contains(e.path().filename().string(), ".tmp-")) << e.path();
  }
  for (const auto& [path, bytes] : before) EXPECT_EQ(ReadAll(path), bytes) << path;
  // Room again: the daemon scans again.
  fs::remove(dir_ / "scans" / "filler");
  EXPECT_EQ(Cli({"start", "--watch", "--recipe", "tiny"}).exit_code, 0);
}

TEST_F(DaemonE2eTest, ConfigErrorsExitWith78AndNameTheFileAndLine) {
  const fs::path syntax = WriteConfig("[scan]\nstops = 36\nstep_deg = = 10\n", "bad.toml");
  CommandResult r = RunCommand({REVOLVED_BIN, "--config", syntax.string()}, {}, dir_, 30s);
  EXPECT_EQ(r.exit_code, 78);
  EXPECT_TRUE(Contains(r.err, "bad.toml:3:")) << r.err;

  const fs::path key = WriteConfig("[daemon]\nsocket = \"/tmp/x.sock\"\nsockett = 1\n", "key.toml");
  r = RunCommand({REVOLVED_BIN, "--config", key.string()}, {}, dir_, 30s);
  EXPECT_EQ(r.exit_code, 78);
  EXPECT_TRUE(Contains(r.err, "key.toml:3:")) << r.err;
  EXPECT_TRUE(Contains(r.err, "daemon.sockett")) << r.err;

  const fs::path recipe =
      WriteConfig("[recipes.wide]\nstep_deg = 20.0\n[scan]\nstops = 36\n", "recipe.toml");
  r = RunCommand({REVOLVED_BIN, "--config", recipe.string()}, {}, dir_, 30s);
  EXPECT_EQ(r.exit_code, 78);
  EXPECT_TRUE(Contains(r.err, "recipe.toml:")) << r.err;
  EXPECT_TRUE(Contains(r.err, "wide")) << r.err;

  r = RunCommand({REVOLVED_BIN, "--config", (dir_ / "missing.toml").string()}, {}, dir_, 30s);
  EXPECT_EQ(r.exit_code, 78);
  EXPECT_TRUE(Contains(r.err, "missing.toml")) << r.err;

  r = Cli({"check-config", key.string()});
  EXPECT_EQ(r.exit_code, 78);
  EXPECT_TRUE(Contains(r.err, "daemon.sockett")) << r.err;
}

TEST_F(DaemonE2eTest, CheckConfigPrintsTheEffectiveConfig) {
  const CommandResult r = Cli({"check-config", REVOLVE_SOURCE_DIR "/systemd/revolved.toml"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* want :
       {"valid", "[daemon]", "socket_mode = \"0660\"", "max_request_bytes = 4096", "[station]",
        "camera_retries = 2", "quick", "fine", "72 stops", "capture_timeout_s = 5"}) {
    EXPECT_TRUE(Contains(r.out, want)) << want << "\n" << r.out;
  }
}

TEST_F(DaemonE2eTest, SdNotifyReadyStatusWatchdogAndStopping) {
  const fs::path notify = dir_ / "notify.sock";
  UniqueFd fd(::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s", notify.c_str());
  ASSERT_EQ(::bind(fd.get(), reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  std::vector<std::string> messages;
  std::mutex mutex;
  std::atomic<bool> stop{false};
  std::jthread reader([&] {
    while (!stop) {
      pollfd p{fd.get(), POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      char buf[4096];
      const ssize_t n = ::recv(fd.get(), buf, sizeof(buf), 0);
      if (n <= 0) continue;
      std::lock_guard lock(mutex);
      messages.emplace_back(buf, static_cast<std::size_t>(n));
    }
  });
  auto count = [&](const std::string& prefix) {
    std::lock_guard lock(mutex);
    return std::count_if(messages.begin(), messages.end(),
                         [&](const std::string& m) { return Contains(m, prefix); });
  };
  StartDaemon(WriteConfig(Config()),
              {"NOTIFY_SOCKET=" + notify.string(), "WATCHDOG_USEC=200000", "WATCHDOG_PID=self"});
  std::this_thread::sleep_for(600ms);
  EXPECT_EQ(count("READY=1"), 1);
  EXPECT_GE(count("WATCHDOG=1"), 3);  // every 100 ms
  ASSERT_EQ(Cli({"start", "--watch", "--recipe", "tiny"}).exit_code, 0);
  EXPECT_GE(count("STATUS=Scanning"), 4);
  EXPECT_GE(count("STATUS=Idle; scan"), 1);
  daemon_.Signal(SIGTERM);
  EXPECT_EQ(daemon_.Wait(10s), 0);
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(count("STOPPING=1"), 1);
  stop = true;
  {
    std::lock_guard lock(mutex);
    ASSERT_FALSE(messages.empty());
    EXPECT_TRUE(Contains(messages.front(), "READY=1\nSTATUS=Idle")) << messages.front();
  }
}

TEST_F(DaemonE2eTest, SocketGroupComesFromTheConfig) {
  const group* g = ::getgrgid(::getegid());
  ASSERT_NE(g, nullptr);
  StartDaemon(WriteConfig(std::regex_replace(
      Config(), std::regex("socket_mode = \"0640\""),
      fmt::format("socket_mode = \"0660\"\nsocket_group = \"{}\"", g->gr_name))));
  struct stat st {};
  ASSERT_EQ(::stat(Socket().c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0660u);
  EXPECT_EQ(st.st_gid, g->gr_gid);
  // A group that does not exist is a config error.
  const fs::path bad = WriteConfig(
      std::regex_replace(
          Config(), std::regex("socket = \"[^\"]*\""),
          fmt::format("socket = \"{}/other.sock\"\nsocket_group = \"no-such-group-xyz\"",
                      dir_.string())),
      "badgroup.toml");
  const CommandResult r = RunCommand({REVOLVED_BIN, "--config", bad.string()}, {}, dir_, 30s);
  EXPECT_EQ(r.exit_code, 78) << r.err;
  EXPECT_TRUE(Contains(r.err, "no-such-group-xyz")) << r.err;
}

// 50 scans through the daemon: every folder complete, no growth in memory or descriptors.
TEST_F(DaemonE2eTest, SoakFiftyScansWithoutGrowth) {
  StartDaemon(
      WriteConfig(Config("[recipes.soak]\nstops = 4\nstep_deg = 90.0\nresolution = 16\n", 0.001)));
  ControlClient c = Client();
  ASSERT_TRUE(c.Call({{"cmd", "watch"}}, 10s).has_value());
  long rss_warm = 0;
  int fds_warm = 0;
  constexpr int kScans = 50;
  constexpr int kWarmUp = 5;
  const auto t = std::chrono::steady_clock::now();
  for (int i = 0; i < kScans; ++i) {
    ASSERT_TRUE(c.Send({{"cmd", "start"}, {"recipe", "soak"}}).has_value());
    auto events = EventsUntil(c, {"done", "failed", "aborted"}, 60s);
    ASSERT_FALSE(events.empty());
    ASSERT_EQ(events.back()["state"], "done") << events.back().dump();
    if (i + 1 == kWarmUp) {
      rss_warm = RssKb(daemon_.pid());
      fds_warm = OpenFds(daemon_.pid());
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  const long rss_end = RssKb(daemon_.pid());
  const int fds_end = OpenFds(daemon_.pid());
  std::cout << fmt::format(
      "soak: {} scans in {:.1f} s; RSS {} kB after {} scans, {} kB after {} "
      "(growth {} kB); fds {} -> {}\n",
      kScans, seconds, rss_warm, kWarmUp, rss_end, kScans, rss_end - rss_warm, fds_warm, fds_end);
  RecordProperty("rss_warm_kb", static_cast<int>(rss_warm));
  RecordProperty("rss_end_kb", static_cast<int>(rss_end));
  RecordProperty("fds_warm", fds_warm);
  RecordProperty("fds_end", fds_end);
  EXPECT_LE(fds_end, fds_warm + 1);
  EXPECT_LT(rss_end - rss_warm, 24 * 1024);  // generous: allocator caches, spdlog buffers

  auto list = c.Call({{"cmd", "list"}}, 10s);
  // The reply may come after a late event line.
  while (list && !list->contains("scans")) list = c.Receive(10s);
  ASSERT_TRUE(list.has_value());
  ASSERT_EQ((*list)["scans"].size(), static_cast<std::size_t>(kScans));
  for (const auto& s : (*list)["scans"]) {
    EXPECT_EQ(s["state"], "complete") << s.dump();
    const fs::path scan = dir_ / "scans" / s["id"].get<std::string>();
    EXPECT_TRUE(fs::exists(scan / "model/model.ply")) << scan;
    EXPECT_EQ(ReadJson(scan / "manifest.json")["stops"].size(), 4u) << scan;
  }
}

// Random and malformed lines from many connections while a scan runs: the daemon answers every
// complete line, never crashes, and the scan completes.
TEST_F(DaemonE2eTest, FuzzedSocketInputNeverCrashesOrWedgesAScan) {
  StartDaemon(WriteConfig(Config("", 0.05, 20.0)));
  ControlClient watcher = Client();
  ASSERT_TRUE(watcher.Call({{"cmd", "watch"}}, 10s).has_value());
  auto start = watcher.Call({{"cmd", "start"}}, 10s);
  ASSERT_TRUE(start.has_value());
  ASSERT_EQ((*start)["ok"], true);

  std::mt19937 rng(20261122);
  const std::vector<std::string> seeds = {
      R"({"cmd":"status"})", R"({"cmd":"list"})", R"({"cmd":"watch","id":3})",
      R"({"cmd":"start","recipe":"tiny"})", R"({"cmd":"abort"})"};
  auto random_line = [&]() {
    std::string line;
    switch (rng() % 4) {
      case 0: {
        const int n = static_cast<int>(rng() % 200);
        for (int k = 0; k < n; ++k) line += static_cast<char>(rng() % 256);
        break;
      }
      case 1:
        line = std::string(5000 + rng() % 5000, static_cast<char>('a' + rng() % 26));
        break;
      default: {
        line = seeds[rng() % seeds.size()];
        for (int k = 0, edits = 1 + static_cast<int>(rng() % 5); k < edits; ++k) {
          const std::size_t at = rng() % (line.size() + 1);
          line.insert(at, 1, static_cast<char>(rng() % 256));
        }
      }
    }
    // Blank lines get no reply; make them malformed instead.
    if (line.find_first_not_of(" \t\r\n") == std::string::npos) line = "{";
    // Never send a valid start or abort: the scan must run to its end.
    for (std::size_t nl; (nl = line.find('\n')) != std::string::npos;) line[nl] = ' ';
    nlohmann::json id;
    auto request = station::ParseRequest(line, &id);
    if (request && (request->kind == station::RequestKind::kStart ||
                    request->kind == station::RequestKind::kAbort)) {
      line = "{";
    }
    return line + "\n";
  };
  int replies = 0;
  for (int round = 0; round < 8; ++round) {
    ControlClient c = Client();
    int sent = 0;
    for (int i = 0; i < 150; ++i) {
      std::string line = random_line();
      // Some lines in pieces, some connections cut mid-line.
      if (rng() % 5 == 0 && line.size() > 2) {
        ASSERT_TRUE(c.SendRaw(line.substr(0, line.size() / 2)).has_value());
        std::this_thread::sleep_for(1ms);
        line = line.substr(line.size() / 2);
      }
      ASSERT_TRUE(c.SendRaw(line).has_value());
      ++sent;
    }
    // Every complete line gets exactly one reply (watch adds events, which are skipped).
    int got = 0;
    while (got < sent) {
      auto reply = c.Receive(20s);
      ASSERT_TRUE(reply.has_value()) << reply.error().message << " after " << got;
      if (reply->contains("event")) continue;
      ASSERT_TRUE(reply->contains("ok")) << reply->dump();
      ++got;
    }
    replies += got;
    if (round % 2 == 1) {
      ASSERT_TRUE(c.SendRaw("{\"cmd\":\"sta").has_value());  // cut mid-line
    }
  }
  EXPECT_EQ(replies, 8 * 150);
  auto events = EventsUntil(watcher, {"done", "failed", "aborted"}, 120s);
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back()["state"], "done");
  EXPECT_FALSE(daemon_.Wait(0ms).has_value()) << "revolved died";
  EXPECT_EQ(Status()["state"], "done");
}

// The Modbus path: revolved drives `revolve simulate-drive` over TCP on loopback and over a
// socat pseudo-terminal pair (RTU). Skipped until the simulator is in the build.
class ModbusE2eTest : public DaemonE2eTest {
 protected:
  void SetUp() override {
    DaemonE2eTest::SetUp();
    const CommandResult help = RunCommand({REVOLVE_BIN, "simulate-drive", "--help"}, {}, dir_, 30s);
    if (help.exit_code != 0) {
      GTEST_SKIP() << "revolve simulate-drive is not built yet";
    }
  }

  std::string ModbusConfig(const std::string& link) const {
    std::string text = Config(fmt::format(R"([turntable.modbus]
{}
profile = "generic"
speed_deg_per_s = 360.0
acceleration_deg_per_s2 = 3600.0
)",
                                          link));
    return std::regex_replace(text, std::regex("\\[turntable\\.mock\\]\ntime_scale = [0-9.]+\n"),
                              "[turntable]\nbackend = \"modbus\"\n");
  }

  void ScanTiny() {
    const CommandResult r = Cli({"start", "--watch", "--recipe", "tiny"}, 180s);
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err << DaemonLog();
    const auto status = Status();
    const auto manifest =
        ReadJson(fs::path(status["scan"]["dir"].get<std::string>()) / "manifest.json");
    EXPECT_EQ(manifest["state"], "complete");
    EXPECT_NEAR(manifest["stops"][3]["readback_deg"].get<double>(), 270.0, 0.1);
    EXPECT_TRUE(Contains(manifest["turntable"].get<std::string>(), "modbus"))
        << manifest["turntable"];
  }
};

TEST_F(ModbusE2eTest, ScanThroughTheDriveSimulatorOverTcp) {
  const fs::path port_file = dir_ / "port";
  helper_ = Child::Spawn({REVOLVE_BIN, "simulate-drive", "--profile", "generic", "--tcp",
                          "127.0.0.1:0", "--port-file", port_file.string()},
                         {}, dir_ / "sim.out", dir_ / "sim.err");
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (ReadAll(port_file).empty() && std::chrono::steady_clock::now() < deadline) {
    ASSERT_FALSE(helper_.Wait(0ms).has_value()) << ReadAll(dir_ / "sim.err");
    std::this_thread::sleep_for(20ms);
  }
  const int port = std::stoi(ReadAll(port_file));
  StartDaemon(WriteConfig(
      ModbusConfig(fmt::format("transport = \"tcp\"\nhost = \"127.0.0.1\"\nport = {}", port))));
  ScanTiny();
}

TEST_F(ModbusE2eTest, ScanThroughTheDriveSimulatorOnASocatPtyPair) {
  if (RunCommand({"/bin/sh", "-c", "command -v socat"}, {}, dir_, 10s).exit_code != 0) {
    GTEST_SKIP() << "socat is not installed";
  }
  const fs::path a = dir_ / "ttyA";
  const fs::path b = dir_ / "ttyB";
  socat_ = Child::Spawn({"/usr/bin/socat", "-d", "-d", "pty,raw,echo=0,link=" + a.string(),
                         "pty,raw,echo=0,link=" + b.string()},
                        {}, dir_ / "socat.out", dir_ / "socat.err");
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (!(fs::exists(a) && fs::exists(b)) && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(20ms);
  }
  ASSERT_TRUE(fs::exists(a) && fs::exists(b)) << ReadAll(dir_ / "socat.err");
  helper_ =
      Child::Spawn({REVOLVE_BIN, "simulate-drive", "--profile", "generic", "--rtu", a.string()}, {},
                   dir_ / "sim.out", dir_ / "sim.err");
  std::this_thread::sleep_for(300ms);
  ASSERT_FALSE(helper_.Wait(0ms).has_value()) << ReadAll(dir_ / "sim.err");
  StartDaemon(
      WriteConfig(ModbusConfig(fmt::format("transport = \"rtu\"\nport = \"{}\"", b.string()))));
  ScanTiny();
}

}  // namespace
}  // namespace revolve::e2e

namespace revolve::e2e {
namespace {

// Issue 21: 32 clients that connect and say nothing must not lock `revolve status` out; the one
// idle longest gives its slot, and every silent client is closed after daemon.idle_timeout_s.
TEST_F(DaemonE2eTest, SilentClientsCannotHoldTheControlSlots) {
  StartDaemon(WriteConfig(Config()));
  std::vector<ControlClient> silent;
  for (int i = 0; i < 32; ++i) silent.push_back(Client());
  std::this_thread::sleep_for(700ms);  // longer than the eviction grace
  const CommandResult status = Cli({"status"}, 20s);
  EXPECT_EQ(status.exit_code, 0) << status.out << status.err;
  EXPECT_TRUE(Contains(status.out, "state")) << status.out;
  EXPECT_FALSE(Contains(status.err, "too many clients")) << status.err;
}

TEST_F(DaemonE2eTest, ASilentClientIsClosedAfterTheIdleTimeout) {
  std::string config = Config();
  const std::string mode = "socket_mode = \"0640\"\n";
  config.replace(config.find(mode), mode.size(), mode + "idle_timeout_s = 1.0\n");
  StartDaemon(WriteConfig(config));
  const fs::path socket = Socket();
  UniqueFd fd(::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0));
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s", socket.c_str());
  ASSERT_EQ(::connect(fd.get(), reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  pollfd p{fd.get(), POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 5000), 1) << "the daemon kept a silent client for 5 s";
  char buf[512] = {};
  const ssize_t n = ::recv(fd.get(), buf, sizeof(buf) - 1, 0);
  ASSERT_GT(n, 0);
  EXPECT_TRUE(Contains(buf, "closed: idle")) << buf;
  EXPECT_EQ(::recv(fd.get(), buf, sizeof(buf), 0), 0);  // then the daemon hangs up
}

// Issue 21, cause 7: resuming a complete scan is refused at once, not answered "resumed".
TEST_F(DaemonE2eTest, ResumingACompleteScanIsRefused) {
  StartDaemon(WriteConfig(Config()));
  const CommandResult start = Cli({"start", "--watch", "--recipe", "tiny"});
  ASSERT_EQ(start.exit_code, 0) << start.out << start.err;
  const auto json = nlohmann::json::parse(Cli({"status", "--json"}).out);
  const std::string id = fs::path(json["scan"]["dir"].get<std::string>()).filename().string();
  const fs::path manifest = fs::path(json["scan"]["dir"].get<std::string>()) / "manifest.json";
  const std::string before = ReadAll(manifest);
  const CommandResult resume = Cli({"start", "--resume", id});
  EXPECT_NE(resume.exit_code, 0) << resume.out;
  EXPECT_TRUE(Contains(resume.err, "the scan is complete, nothing to resume")) << resume.err;
  EXPECT_FALSE(Contains(resume.out, "resumed")) << resume.out;
  EXPECT_EQ(ReadAll(manifest), before);  // nothing touched
}

// A missing device refuses `revolve start` as `revolve scan` refuses it: exit 78, the device
// named, no scan folder made, whatever the backend; revolved itself keeps serving (status says
// what is missing, so the device can be plugged in and the start tried again).
TEST_F(DaemonE2eTest, AMissingDeviceRefusesTheStartWith78AndCreatesNothing) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"/dev/video_revolve_missing",
       "[camera]\nbackend = \"v4l2\"\n[camera.v4l2]\ndevice = \"/dev/video_revolve_missing\"\n"},
      {"revolve-missing-camera",
       "[camera]\nbackend = \"libcamera\"\n[camera.libcamera]\ncamera = "
       "\"revolve-missing-camera\"\n"},
      {"no_such_replay_folder",
       "[camera]\nbackend = \"replay\"\n[camera.replay]\ndir = \"no_such_replay_folder\"\n"},
      {"/dev/ttyREVOLVE_missing",
       "[turntable]\nbackend = \"modbus\"\n[turntable.modbus]\nport = "
       "\"/dev/ttyREVOLVE_missing\"\n"},
      {"revolve-missing-chip",
       "[turntable]\nbackend = \"gpio\"\n[turntable.gpio]\nchip = \"revolve-missing-chip\"\nstep = "
       "17\ndir = 27\n"},
  };
  for (const auto& [device, extra] : cases) {
    SCOPED_TRACE(device);
    StartDaemon(WriteConfig(Config(extra), "missing.toml"));
    if (HasFatalFailure()) return;
    const CommandResult start = Cli({"start", "--recipe", "tiny"});
    if (Contains(start.err, "not in this build")) continue;
    EXPECT_EQ(start.exit_code, 78) << start.out << start.err;
    EXPECT_TRUE(Contains(start.err, device)) << start.err;
    EXPECT_FALSE(Contains(start.err, "internal error")) << start.err;
    std::error_code ec;
    EXPECT_TRUE(fs::is_empty(dir_ / "scans", ec)) << "a scan folder was left behind";
    EXPECT_FALSE(Status()["devices"]["ok"].get<bool>());
    daemon_.Kill();
  }
}

}  // namespace
}  // namespace revolve::e2e
