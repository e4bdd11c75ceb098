// What watching costs a scan: the daemon in-process on the simulated rig (36 stops, 640 x 480,
// hull 96^3, the mock table at 1/20 of real time), scanned with 0 or 5 "browsers" watching. A
// browser does what the console page does: holds /api/events open and, after each stop, fetches
// /api/live/frame.jpg and /api/live/hull.glb. The time reported is the mean time per stop, from
// the scan's own per-stop timestamps (manifest.json); counters: get_ms, the latency of
// GET /api/status polled every 20 ms during the scan (p50 and max).
//   build/tests/bench/web_bench --benchmark_repetitions=3
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include "base/log.h"
#include "station/commands/control_client.h"
#include "station/daemon.h"

// Last: <resolv.h>, which httplib.h pulls in, defines _res, a name Eigen's headers use.
#include <httplib.h>

namespace revolve::station {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Station {
  fs::path dir;
  std::unique_ptr<Daemon> daemon;
  std::jthread runner;
  int port = 0;

  Station() {
    dir = fmt::format("/tmp/rv_web_bench_{}", ::getpid());
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string text = fmt::format(R"([daemon]
socket = "{0}/s.sock"
[web]
listen = "127.0.0.1:0"
[station]
scans_dir = "{0}/scans"
min_free_mb = 0
[scan]
stops = 36
step_deg = 10.0
settle_ms = 0
[turntable.mock]
time_scale = 0.05
[camera.synthetic]
object = "vase"
width_px = 640
height_px = 480
[reconstruct]
resolution = 96
formats = ["glb"]
)",
                                         dir.string());
    auto cfg = ParseStationConfig(*config::Parse(text, "bench.toml"));
    daemon = std::move(*Daemon::Create(std::move(*cfg), DaemonHooks{}));
    runner = std::jthread([this] { daemon->Run(); });
    auto client = ControlClient::Connect(dir / "s.sock");
    const std::string url = (*client->Call({{"cmd", "status"}}, 10s))["status"]["daemon"]["web"];
    std::smatch m;
    std::regex_search(url, m, std::regex(":([0-9]+)/$"));
    port = std::stoi(m[1]);
  }
  ~Station() {
    daemon->RequestShutdown();
    runner.join();
    daemon.reset();
    fs::remove_all(dir);
  }
};

// Mean ms per stop from the manifest's "captured" timestamps.
double MeanStopMs(const fs::path& scan) {
  std::ifstream in(scan / "manifest.json");
  std::stringstream s;
  s << in.rdbuf();
  const Json manifest = Json::parse(s.str());
  std::vector<double> t;
  for (const Json& stop : manifest["stops"]) {
    const std::string time = stop["captured"];
    std::tm tm{};
    strptime(time.c_str(), "%Y-%m-%dT%H:%M:%S", &tm);
    t.push_back(static_cast<double>(timegm(&tm)) * 1000.0 + std::stod(time.substr(20, 3)));
  }
  return t.size() < 2 ? 0.0 : (t.back() - t.front()) / static_cast<double>(t.size() - 1);
}

// A console page: the event stream, and the live frame and hull after each stop.
void Watch(int port, const std::atomic<bool>& stop, std::atomic<int>& ready) {
  httplib::Client events("127.0.0.1", port);
  httplib::Client live("127.0.0.1", port);
  events.set_read_timeout(60, 0);
  std::string buffer;
  bool counted = false;
  events.Get("/api/events", [&](const char* data, std::size_t n) {
    if (!counted) {
      counted = true;
      ++ready;
    }
    buffer.append(data, n);
    for (std::size_t end; (end = buffer.find("\n\n")) != std::string::npos;) {
      const std::string block = buffer.substr(0, end);
      buffer.erase(0, end + 2);
      if (block.find("\"state\":\"moving\"") != std::string::npos ||
          block.find("\"state\":\"meshing\"") != std::string::npos) {
        (void)live.Get("/api/live/frame.jpg");
        (void)live.Get("/api/live/hull.glb");
      }
      if (block.find("\"state\":\"done\"") != std::string::npos) return false;
    }
    return !stop.load();
  });
}

void BM_ScanWatched(benchmark::State& state) {
  static Station station;
  Logger("station")->set_level(spdlog::level::warn);
  Logger("capture")->set_level(spdlog::level::warn);
  Logger("reconstruct")->set_level(spdlog::level::warn);
  const int watchers = static_cast<int>(state.range(0));
  std::vector<double> get_ms;
  for (auto _ : state) {
    std::atomic<bool> stop{false};
    std::atomic<int> ready{0};
    std::vector<std::jthread> threads;
    for (int i = 0; i < watchers; ++i) {
      threads.emplace_back([&] { Watch(station.port, stop, ready); });
    }
    while (ready.load() < watchers) std::this_thread::sleep_for(1ms);
    httplib::Client c("127.0.0.1", station.port);
    c.set_read_timeout(30, 0);
    auto started = c.Post("/api/scans", "{}", "application/json");
    const std::string id = Json::parse(started->body)["scan"];
    for (;;) {
      const auto t = Clock::now();
      auto status = c.Get("/api/status");
      get_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t).count());
      const Json s = Json::parse(status->body);
      if (s["state"] == "done" || s["state"] == "failed" || s["state"] == "aborted") break;
      std::this_thread::sleep_for(20ms);
    }
    stop = true;
    threads.clear();
    state.SetIterationTime(MeanStopMs(station.dir / "scans" / id) / 1000.0);
  }
  std::sort(get_ms.begin(), get_ms.end());
  state.counters["get_ms_p50"] = get_ms.empty() ? 0.0 : get_ms[get_ms.size() / 2];
  state.counters["get_ms_max"] = get_ms.empty() ? 0.0 : get_ms.back();
  state.counters["watchers"] = watchers;
}
BENCHMARK(BM_ScanWatched)
    ->ArgName("watchers")
    ->Arg(0)
    ->Arg(5)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

}  // namespace
}  // namespace revolve::station

BENCHMARK_MAIN();
