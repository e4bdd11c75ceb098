// End to end: the real revolved process with its web console. A real browser (Debian's chromium,
// headless, driven by puppeteer-core: tests/tools/console_browser.js) presses Start and watches
// the 36 stops and the model; the finished model.glb fetched over HTTP passes the Khronos glTF
// validator; a listener reachable from other machines without a token is refused (exit 78).
#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "station/commands/control_client.h"
#include "tests/e2e/daemon_harness.h"

// Last: <resolv.h>, which httplib.h pulls in, defines _res, a name Eigen's headers use.
#include <httplib.h>

namespace revolve::e2e {
namespace {

using Json = nlohmann::json;

class WebConsoleTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / fmt::format("rvweb_{}", ::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    daemon_.Kill();
    if (!HasFailure()) fs::remove_all(dir_);
  }

  std::string Config(const std::string& web, int stops) const {
    return fmt::format(R"([daemon]
socket = "{0}/ctl.sock"
[web]
{1}
[station]
scans_dir = "{0}/scans"
min_free_mb = 0
[scan]
stops = {2}
step_deg = {3}
settle_ms = 0
[turntable.mock]
time_scale = 0.05
[camera.synthetic]
object = "vase"
width_px = 320
height_px = 240
[reconstruct]
resolution = 64
formats = ["glb", "ply"]
)",
                       dir_.string(), web, stops, 360.0 / stops);
  }

  fs::path Write(const std::string& text, const std::string& name) {
    const fs::path path = dir_ / name;
    std::ofstream(path) << text;
    return path;
  }

  // Starts revolved; returns the console's port (from the status on the control socket).
  int StartDaemon(const std::string& config) {
    const fs::path file = Write(config, "revolved.toml");
    daemon_ = Child::Spawn({REVOLVED_BIN, "--config", file.string()}, {}, dir_ / "revolved.out",
                           dir_ / "revolved.err");
    const auto deadline = std::chrono::steady_clock::now() + 20s;
    while (std::chrono::steady_clock::now() < deadline) {
      if (auto code = daemon_.Wait(0ms)) {
        ADD_FAILURE() << "revolved exited with " << *code << ": " << ReadAll(dir_ / "revolved.err");
        return 0;
      }
      if (auto client = station::ControlClient::Connect(dir_ / "ctl.sock")) {
        auto status = client->Call({{"cmd", "status"}}, 10s);
        if (status) {
          const std::string url = (*status)["status"]["daemon"]["web"];
          std::smatch m;
          if (std::regex_search(url, m, std::regex(":([0-9]+)/$"))) return std::stoi(m[1]);
        }
      }
      std::this_thread::sleep_for(20ms);
    }
    ADD_FAILURE() << "revolved did not come up: " << ReadAll(dir_ / "revolved.err");
    return 0;
  }

  fs::path dir_;
  Child daemon_;
};

TEST_F(WebConsoleTest, ABrowserRunsAScanAndSeesEveryStopAndTheModel) {
  const fs::path script = fs::path(REVOLVE_SOURCE_DIR) / "tests/tools/console_browser.js";
  if (!fs::exists(fs::path(REVOLVE_SOURCE_DIR) / "tests/tools/node_modules/puppeteer-core") ||
      RunCommand({"/bin/sh", "-c", "command -v node"}, {}, dir_).exit_code != 0) {
    GTEST_SKIP() << "node or puppeteer-core is missing (npm ci --prefix tests/tools; ./run test "
                    "installs it)";
  }
  const int port = StartDaemon(Config("listen = \"127.0.0.1:0\"", 36));
  ASSERT_GT(port, 0);
  const fs::path build = std::getenv("REVOLVE_BUILD_DIR") != nullptr
                             ? fs::path(std::getenv("REVOLVE_BUILD_DIR"))
                             : dir_;
  const fs::path screenshot = build / "web_console.png";
  const CommandResult r =
      RunCommand({"/usr/bin/node", script.string(), fmt::format("http://127.0.0.1:{}/", port),
                  screenshot.string(), "36"},
                 {}, dir_, 300s);
  if (r.exit_code == 3) GTEST_SKIP() << "the browser cannot run here: " << r.out << r.err;
  std::cout << r.out << "\n";
  const Json report = Json::parse(r.out, nullptr, false);
  ASSERT_FALSE(report.is_discarded()) << r.out << r.err;
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_FALSE(report.contains("error")) << report.dump(2);
  EXPECT_EQ(report["stops_done_cells"], 36);
  EXPECT_EQ(report["frame_shown"], true);
  EXPECT_EQ(report["console_errors"].size(), 0u) << report["console_errors"].dump(2);
  EXPECT_GE(report["scans_listed"].get<int>(), 1);
  EXPECT_EQ(report["thumbnail"], true);
  EXPECT_LE(report["phone_overflow_px"].get<int>(), 0) << "the page scrolls sideways on a phone";
  const std::string downloads = report["downloads"].dump();
  EXPECT_NE(downloads.find("model.glb"), std::string::npos) << downloads;
  EXPECT_NE(report["figures"].dump().find("volume"), std::string::npos);
  if (report["webgl"] == true) {
    EXPECT_EQ(report["live_hull_seen"], true);
    EXPECT_GT(report["viewer"]["differ"].get<int>(), 1000) << report["viewer"].dump();
    RecordProperty("viewer_pixels_drawn", report["viewer"]["differ"].dump());
  } else {
    ADD_FAILURE() << "WebGL is not available in headless chromium here; the viewer was not checked";
  }
  EXPECT_TRUE(fs::exists(screenshot));
  RecordProperty("screenshot", screenshot.string());
}

TEST_F(WebConsoleTest, TheModelFetchedOverHttpPassesTheKhronosValidator) {
  const fs::path validator = fs::path(REVOLVE_SOURCE_DIR) / "tests/tools/validate_gltf.js";
  if (!fs::exists(fs::path(REVOLVE_SOURCE_DIR) / "tests/tools/node_modules/gltf-validator")) {
    GTEST_SKIP() << "the glTF validator is not installed (npm ci --prefix tests/tools)";
  }
  const int port = StartDaemon(Config("listen = \"127.0.0.1:0\"", 12));
  ASSERT_GT(port, 0);
  httplib::Client c("127.0.0.1", port);
  c.set_read_timeout(30, 0);
  auto started = c.Post("/api/scans", "{}", "application/json");
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 202) << started->body;
  const std::string id = Json::parse(started->body)["scan"];
  std::string hull;
  for (int i = 0; i < 1200; ++i) {
    auto status = c.Get("/api/status");
    ASSERT_TRUE(status);
    if (hull.empty()) {
      if (auto h = c.Get("/api/live/hull.glb"); h && h->status == 200) hull = h->body;
    }
    if (Json::parse(status->body)["state"] == "done") break;
    std::this_thread::sleep_for(50ms);
  }
  for (const auto& [name, url] :
       {std::pair{"model.glb", "/api/scans/" + id + "/files/model/model.glb"},
        std::pair{"hull.glb", std::string("/api/live/hull.glb")}}) {
    SCOPED_TRACE(name);
    auto res = c.Get(url.c_str());
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    std::ofstream(dir_ / name, std::ios::binary) << res->body;
    const CommandResult r =
        RunCommand({"/usr/bin/node", validator.string(), (dir_ / name).string()}, {}, dir_);
    ASSERT_NE(r.exit_code, 2) << r.err;
    const Json report = Json::parse(r.out, nullptr, false);
    ASSERT_FALSE(report.is_discarded()) << r.out;
    EXPECT_EQ(report["issues"]["numErrors"], 0) << r.out;
    EXPECT_EQ(r.exit_code, 0);
  }
}

TEST_F(WebConsoleTest, AListenerForOtherMachinesWithoutATokenIsRefused) {
  const fs::path file = Write(Config("listen = \"0.0.0.0:0\"", 4), "open.toml");
  CommandResult r = RunCommand({REVOLVED_BIN, "--config", file.string()}, {}, dir_, 20s);
  EXPECT_EQ(r.exit_code, 78) << r.err;
  EXPECT_NE(r.err.find("web.listen"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("token_file"), std::string::npos) << r.err;

  const fs::path missing = Write(
      Config(fmt::format("listen = \"0.0.0.0:0\"\ntoken_file = \"{}/none\"", dir_.string()), 4),
      "missing.toml");
  r = RunCommand({REVOLVED_BIN, "--config", missing.string()}, {}, dir_, 20s);
  EXPECT_EQ(r.exit_code, 78) << r.err;
  EXPECT_NE(r.err.find("web.token_file"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace revolve::e2e
