// The web console's HTTP API through real sockets on loopback: the daemon in-process with [web]
// on a free port, httplib::Client (and raw sockets) as the clients. docs/api/openapi.json is
// checked against the server: every documented path and method answers with a documented status,
// and JSON bodies carry the documented required fields.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <regex>
#include <sstream>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "base/unique_fd.h"
#include "station/commands/control_client.h"
#include "station/daemon.h"
#include "station/web_server.h"
#include "tests/support/control_events.h"

// Last: <resolv.h>, which httplib.h pulls in, defines _res, a name Eigen's headers use.
#include <httplib.h>

namespace revolve::station {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Json = nlohmann::json;

Json ReadJsonFile(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return Json::parse(s.str());
}

// One server-sent event.
struct Sse {
  std::uint64_t id = 0;
  std::string event;
  Json data;
};

// Reads /api/events on a thread of its own until Stop() or `until` returns true.
class SseReader {
 public:
  SseReader(int port, httplib::Headers headers, std::function<bool(const Sse&)> until = {},
            std::string path = "/api/events")
      : until_(std::move(until)) {
    thread_ = std::jthread([this, port, headers, path] {
      httplib::Client client("127.0.0.1", port);
      client.set_read_timeout(60, 0);
      client.Get(path, headers, [this](const char* data, std::size_t n) {
        std::lock_guard lock(mutex_);
        buffer_.append(data, n);
        for (std::size_t end; (end = buffer_.find("\n\n")) != std::string::npos;) {
          Parse(buffer_.substr(0, end));
          buffer_.erase(0, end + 2);
        }
        return !stop_.load() && !done_;
      });
      std::lock_guard lock(mutex_);
      done_ = true;
    });
  }
  ~SseReader() { Stop(); }
  void Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  std::vector<Sse> Events() {
    std::lock_guard lock(mutex_);
    return events_;
  }
  // Waits until the stream's first event, the status it opens with, has come: from then on the
  // reader is subscribed, and sees every event published (a scan started before that could end
  // before the reader subscribes, and its end would never come).
  bool WaitForStatus(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      {
        std::lock_guard lock(mutex_);
        for (const Sse& e : events_) {
          if (e.event == "status") return true;
        }
        if (done_) return false;
      }
      std::this_thread::sleep_for(10ms);
    }
    return false;
  }
  // Waits until the reader ends (its `until` matched, or the stream closed).
  bool WaitDone(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      {
        std::lock_guard lock(mutex_);
        if (done_) return true;
      }
      std::this_thread::sleep_for(10ms);
    }
    return false;
  }

 private:
  void Parse(const std::string& block) {
    Sse e;
    std::istringstream lines(block);
    std::string line;
    bool any = false;
    while (std::getline(lines, line)) {
      if (line.rfind("id: ", 0) == 0) e.id = std::stoull(line.substr(4));
      if (line.rfind("event: ", 0) == 0) e.event = line.substr(7);
      if (line.rfind("data: ", 0) == 0) {
        e.data = Json::parse(line.substr(6));
        any = true;
      }
    }
    if (!any) return;
    events_.push_back(e);
    if (until_ && until_(e)) done_ = true;
  }

  std::function<bool(const Sse&)> until_;
  std::mutex mutex_;
  std::string buffer_;
  std::vector<Sse> events_;
  bool done_ = false;
  std::atomic<bool> stop_{false};
  std::jthread thread_;
};

bool IsTerminalEvent(const Sse& e) {
  const std::string state = e.data.value("state", "");
  return e.event == "scan" && (state == "done" || state == "failed" || state == "aborted");
}

class WebServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    dir_ = fmt::format("/tmp/rvw_{}_{}", ::getpid(), counter++);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    StopDaemon();
    if (!HasFailure()) fs::remove_all(dir_);
  }

  std::string Config(const std::string& web = "", int stops = 12, double time_scale = 0.01) const {
    return fmt::format(R"([daemon]
socket = "{0}/s.sock"
[web]
listen = "127.0.0.1:0"
{1}
[station]
scans_dir = "{0}/scans"
min_free_mb = 0
[recipes.tiny]
stops = 4
step_deg = 90.0
resolution = 24
[scan]
stops = {2}
step_deg = {3}
settle_ms = 0
[turntable.mock]
time_scale = {4}
[camera.synthetic]
object = "sphere"
radius_mm = 40.0
target_height_mm = 40.0
width_px = 160
height_px = 120
[reconstruct]
resolution = 32
formats = ["glb", "ply"]
)",
                       dir_.string(), web, stops, 360.0 / stops, time_scale);
  }

  void StartDaemon(const std::string& text) {
    auto document = config::Parse(text, "web.toml");
    ASSERT_TRUE(document.has_value()) << document.error().message;
    auto cfg = ParseStationConfig(*document);
    ASSERT_TRUE(cfg.has_value()) << cfg.error().message;
    auto daemon = Daemon::Create(std::move(*cfg), DaemonHooks{});
    ASSERT_TRUE(daemon.has_value()) << daemon.error().message;
    daemon_ = std::move(*daemon);
    runner_ = std::jthread([this] { daemon_->Run(); });
    auto client = ControlClient::Connect(dir_ / "s.sock");
    ASSERT_TRUE(client.has_value());
    auto status = client->Call({{"cmd", "status"}}, 10s);
    ASSERT_TRUE(status.has_value());
    const std::string url = (*status)["status"]["daemon"]["web"].get<std::string>();
    std::smatch m;
    ASSERT_TRUE(std::regex_search(url, m, std::regex(":([0-9]+)/$"))) << url;
    port_ = std::stoi(m[1]);
  }

  void StopDaemon() {
    if (!daemon_) return;
    daemon_->RequestShutdown();
    runner_.join();
    daemon_.reset();
  }

  httplib::Client Client() const {
    httplib::Client c("127.0.0.1", port_);
    c.set_read_timeout(30, 0);
    c.set_connection_timeout(5, 0);
    return c;
  }

  Json GetJson(const std::string& path, int expect = 200) {
    auto c = Client();
    auto res = c.Get(path);
    EXPECT_TRUE(res) << path;
    if (!res) return {};
    EXPECT_EQ(res->status, expect) << path << ": " << res->body;
    return Json::parse(res->body, nullptr, false);
  }

  // Starts a scan over HTTP and waits for its terminal event on the stream; returns its id.
  std::string ScanToEnd(const std::string& body = "{}") {
    SseReader reader(port_, {}, IsTerminalEvent);
    EXPECT_TRUE(reader.WaitForStatus(30s));
    auto c = Client();
    auto res = c.Post("/api/scans", body, "application/json");
    EXPECT_TRUE(res);
    if (!res) return "";
    EXPECT_EQ(res->status, 202) << res->body;
    const std::string id = Json::parse(res->body).value("scan", "");
    EXPECT_TRUE(reader.WaitDone(120s));
    return id;
  }

  fs::path dir_;
  std::unique_ptr<Daemon> daemon_;
  std::jthread runner_;
  int port_ = 0;
};

TEST_F(WebServerTest, ScanOverHttpStreamsEveryStopAndServesItsFiles) {
  StartDaemon(Config());
  const Json idle = GetJson("/api/status");
  EXPECT_EQ(idle["state"], "idle");
  EXPECT_EQ(idle["busy"], false);
  for (const char* key : {"state", "scan", "stop", "stops", "eta_s", "event_id", "web"}) {
    EXPECT_TRUE(idle.contains(key)) << key;
  }
  EXPECT_EQ(GetJson("/api/live/frame.jpg", 404)["error"]["code"], "not_found");

  SseReader reader(port_, {}, IsTerminalEvent);
  ASSERT_TRUE(reader.WaitForStatus(30s));
  auto c = Client();
  auto started = c.Post("/api/scans", "{}", "application/json");
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 202) << started->body;
  const std::string id = Json::parse(started->body)["scan"];
  EXPECT_FALSE(id.empty());
  // One scan at a time.
  auto again = c.Post("/api/scans", R"({"recipe": "tiny"})", "application/json");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 409) << again->body;
  EXPECT_EQ(Json::parse(again->body)["error"]["code"], "busy");

  // Mid-scan: the live frame (JPEG) once the first stop is saved, and a GET answers.
  std::optional<httplib::Result> frame;
  for (int i = 0; i < 400; ++i) {
    auto r = c.Get("/api/live/frame.jpg");
    if (r && r->status == 200) {
      frame.emplace(std::move(r));
      break;
    }
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_TRUE(frame.has_value()) << "no live frame mid-scan";
  const std::string& jpeg = (*frame)->body;
  ASSERT_GT(jpeg.size(), 100u);
  EXPECT_EQ(static_cast<unsigned char>(jpeg[0]), 0xFF);
  EXPECT_EQ(static_cast<unsigned char>(jpeg[1]), 0xD8);
  EXPECT_EQ((*frame)->get_header_value("Content-Type"), "image/jpeg");
  EXPECT_EQ((*frame)->get_header_value("X-Revolve-Scan"), id);

  ASSERT_TRUE(reader.WaitDone(120s));
  const std::vector<Sse> events = reader.Events();
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front().event, "status");
  EXPECT_EQ(events.back().data["state"], "done");
  // Every stop is streamed (its integrating event carries the silhouette's area), ids rise by 1.
  std::set<int> stops;
  std::uint64_t last_id = events.front().id;
  for (std::size_t i = 1; i < events.size(); ++i) {
    EXPECT_EQ(events[i].id, last_id + 1);
    last_id = events[i].id;
    if (events[i].data["state"] == "integrating") {
      stops.insert(events[i].data["stop"].get<int>());
      EXPECT_GT(events[i].data.value("mask_area_px", 0), 100);
      EXPECT_TRUE(events[i].data["eta_s"].is_number() || events[i].data["stop"] == 0);
    }
  }
  EXPECT_EQ(stops.size(), 12u);

  // The hull of the scan's stops.
  auto hull = c.Get("/api/live/hull.glb");
  ASSERT_TRUE(hull);
  ASSERT_EQ(hull->status, 200);
  EXPECT_EQ(hull->body.substr(0, 4), "glTF");
  EXPECT_EQ(hull->get_header_value("Content-Type"), "model/gltf-binary");
  EXPECT_GE(std::stoi(hull->get_header_value("X-Revolve-Stops-In")), 2);

  const Json list = GetJson("/api/scans");
  ASSERT_EQ(list["scans"].size(), 1u);
  const Json& s = list["scans"][0];
  EXPECT_EQ(s["id"], id);
  EXPECT_EQ(s["state"], "complete");
  EXPECT_EQ(s["stops_done"], 12);
  EXPECT_EQ(s["stops"], 12);
  EXPECT_EQ(s["recipe"], "default");
  EXPECT_EQ(s["contact_sheet"], true);
  EXPECT_NE(std::find(s["model"].begin(), s["model"].end(), "model/model.glb"), s["model"].end());

  const Json detail = GetJson("/api/scans/" + id);
  EXPECT_EQ(detail["manifest"]["state"], "complete");
  EXPECT_EQ(detail["report"]["stops_done"], 12);

  auto glb = c.Get(("/api/scans/" + id + "/files/model/model.glb").c_str());
  ASSERT_TRUE(glb);
  EXPECT_EQ(glb->status, 200);
  EXPECT_EQ(glb->get_header_value("Content-Type"), "model/gltf-binary");
  EXPECT_EQ(glb->body.size(), fs::file_size(dir_ / "scans" / id / "model/model.glb"));
  auto png = c.Get(("/api/scans/" + id + "/files/frames/stop_000.png?download=1").c_str());
  ASSERT_TRUE(png);
  EXPECT_EQ(png->status, 200);
  EXPECT_EQ(png->get_header_value("Content-Type"), "image/png");
  EXPECT_NE(png->get_header_value("Content-Disposition").find("attachment"), std::string::npos);

  // Abort with nothing running.
  auto abort = c.Post("/api/abort", "", "application/json");
  ASSERT_TRUE(abort);
  EXPECT_EQ(abort->status, 400);
}

TEST_F(WebServerTest, AbortOverHttpStopsTheScan) {
  StartDaemon(Config("", 36, 0.2));
  SseReader reader(port_, {}, IsTerminalEvent);
  ASSERT_TRUE(reader.WaitForStatus(30s));
  auto c = Client();
  auto started = c.Post("/api/scans", R"({"recipe": "default"})", "application/json");
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 202);
  const std::string id = Json::parse(started->body)["scan"];
  std::this_thread::sleep_for(300ms);
  auto abort = c.Post("/api/abort", "{}", "application/json");
  ASSERT_TRUE(abort);
  EXPECT_EQ(abort->status, 200) << abort->body;
  EXPECT_EQ(Json::parse(abort->body)["scan"], id);
  ASSERT_TRUE(reader.WaitDone(60s));
  EXPECT_EQ(reader.Events().back().data["state"], "aborted");
  const Json list = GetJson("/api/scans");
  EXPECT_EQ(list["scans"][0]["state"], "aborted");
  // Resume it over HTTP: 202, then done.
  const std::string resumed = ScanToEnd(Json{{"resume", id}}.dump());
  EXPECT_EQ(resumed, id);
  EXPECT_EQ(GetJson("/api/scans")["scans"][0]["state"], "complete");
}

TEST_F(WebServerTest, ReconnectWithLastEventIdMissesNothing) {
  StartDaemon(Config("", 24, 0.05));
  std::uint64_t cut = 0;
  {
    // Read until stop 5 is being worked on, then drop the connection mid-scan.
    SseReader first(port_, {},
                    [](const Sse& e) { return e.event == "scan" && e.data["stop"] == 5; });
    auto c = Client();
    auto started = c.Post("/api/scans", "{}", "application/json");
    ASSERT_TRUE(started);
    ASSERT_EQ(started->status, 202);
    ASSERT_TRUE(first.WaitDone(60s));
    first.Stop();
    cut = first.Events().back().id;
  }
  std::this_thread::sleep_for(200ms);  // events go by while nobody listens
  SseReader second(port_, {{"Last-Event-ID", std::to_string(cut)}}, IsTerminalEvent);
  ASSERT_TRUE(second.WaitDone(120s));
  const std::vector<Sse> events = second.Events();
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front().event, "scan") << "a replay starts with the missed events, no status";
  EXPECT_EQ(events.front().id, cut + 1);
  for (std::size_t i = 1; i < events.size(); ++i) EXPECT_EQ(events[i].id, events[i - 1].id + 1);
  std::set<int> later_stops;
  for (const Sse& e : events) {
    if (e.data["state"] == "integrating") later_stops.insert(e.data["stop"].get<int>());
  }
  EXPECT_EQ(later_stops.size(), 24u - 5u);  // stops 5..23
  EXPECT_EQ(events.back().data["state"], "done");

  // The same through ?last_event_id= (for a client that cannot set the header): the replay
  // comes at once, from the event after the one named.
  SseReader third(
      port_, {}, [](const Sse& e) { return e.event == "scan"; },
      fmt::format("/api/events?last_event_id={}", cut));
  ASSERT_TRUE(third.WaitDone(10s));
  ASSERT_FALSE(third.Events().empty());
  EXPECT_EQ(third.Events().front().event, "scan");
  EXPECT_EQ(third.Events().front().id, cut + 1);
}

TEST_F(WebServerTest, FilesStayInsideTheScanFolder) {
  StartDaemon(Config("", 4));
  const std::string id = ScanToEnd();
  ASSERT_FALSE(id.empty());
  const fs::path scan = dir_ / "scans" / id;
  std::ofstream(dir_ / "secret.txt") << "TOP-SECRET-CONTENT";
  std::ofstream(dir_ / "scans" / "outside.txt") << "OUTSIDE-CONTENT";
  fs::create_symlink(dir_ / "secret.txt", scan / "link_out.txt");
  fs::create_symlink(dir_, scan / "dir_out");
  fs::create_symlink(scan / "report.json", scan / "link_in.json");
  auto c = Client();
  const std::string base = "/api/scans/" + id + "/files/";
  for (const std::string& bad : {base + "../outside.txt",
                                 base + "../../secret.txt",
                                 base + "%2e%2e/outside.txt",
                                 base + "%2E%2E%2Foutside.txt",
                                 base + "..%2f..%2fsecret.txt",
                                 base + "frames/../../outside.txt",
                                 base + "/etc/passwd",
                                 base + "%2fetc%2fpasswd",
                                 base + "./report.json",
                                 base + "frames//stop_000.png",
                                 base + "link_out.txt",
                                 base + "dir_out/secret.txt",
                                 base + "frames%5c..%5c..%5coutside.txt",
                                 base + "report.json%00.png",
                                 base,
                                 base + "missing.png",
                                 std::string("/api/scans/../files/secret.txt"),
                                 std::string("/api/scans/..%2f/files/secret.txt"),
                                 std::string("/api/scans/%2e%2e/files/secret.txt"),
                                 "/api/scans/" + id + "%2f..%2f..%2f/files/secret.txt"}) {
    auto r = c.Get(bad.c_str());
    ASSERT_TRUE(r) << bad;
    EXPECT_GE(r->status, 400) << bad;
    EXPECT_LT(r->status, 500) << bad;
    EXPECT_EQ(r->body.find("TOP-SECRET-CONTENT"), std::string::npos) << bad;
    EXPECT_EQ(r->body.find("OUTSIDE-CONTENT"), std::string::npos) << bad;
  }
  for (const std::string& good : {base + "report.json", base + "link_in.json",
                                  base + "frames%2Fstop_000.png", base + "contact_sheet.png"}) {
    auto r = c.Get(good.c_str());
    ASSERT_TRUE(r) << good;
    EXPECT_EQ(r->status, 200) << good;
  }
  // The pure check too.
  EXPECT_FALSE(ResolveScanFile(dir_ / "scans", id, "/etc/passwd"));
  EXPECT_FALSE(ResolveScanFile(dir_ / "scans", "..", "secret.txt"));
  EXPECT_FALSE(ResolveScanFile(dir_ / "scans", id, "dir_out/secret.txt"));
  EXPECT_TRUE(ResolveScanFile(dir_ / "scans", id, "frames/stop_000.png"));
}

TEST_F(WebServerTest, OversizedAndMalformedBodiesAreRefused) {
  StartDaemon(Config("max_request_bytes = 2048"));
  auto c = Client();
  auto big = c.Post("/api/scans", std::string(100000, ' '), "application/json");
  ASSERT_TRUE(big);
  EXPECT_EQ(big->status, 413);
  for (const char* body : {"[1]", "not json", R"({"recipe": 3})", R"({"bogus": 1})",
                           R"({"recipe": "tiny", "resume": "x"})", R"({"resume": "../x"})"}) {
    auto r = c.Post("/api/scans", body, "application/json");
    ASSERT_TRUE(r) << body;
    EXPECT_EQ(r->status, 400) << body << ": " << r->body;
    EXPECT_TRUE(Json::parse(r->body)["error"].contains("message")) << body;
  }
  auto unknown = c.Post("/api/scans", R"({"recipe": "nope"})", "application/json");
  ASSERT_TRUE(unknown);
  EXPECT_EQ(unknown->status, 404);
  EXPECT_EQ(GetJson("/api/nothing", 404)["error"]["code"], "not_found");
  EXPECT_EQ(GetJson("/api/status")["state"], "idle");  // nothing started
}

TEST_F(WebServerTest, LoopbackWithTokenOpensGetsAndGuardsPosts) {
  std::ofstream(dir_ / "token") << "s3cret-token-123\n";
  StartDaemon(Config(fmt::format("token_file = \"{}/token\"", dir_.string()), 4));
  auto c = Client();
  EXPECT_EQ(c.Get("/api/status")->status, 200);
  EXPECT_EQ(c.Get("/api/scans")->status, 200);
  auto none = c.Post("/api/scans", "{}", "application/json");
  EXPECT_EQ(none->status, 401);
  EXPECT_NE(none->get_header_value("WWW-Authenticate").find("Bearer"), std::string::npos);
  auto wrong =
      c.Post("/api/scans", {{"Authorization", "Bearer nope-nope-nope"}}, "{}", "application/json");
  EXPECT_EQ(wrong->status, 401);
  EXPECT_EQ(c.Post("/api/abort", "", "application/json")->status, 401);
  SseReader reader(port_, {}, IsTerminalEvent);
  ASSERT_TRUE(reader.WaitForStatus(30s));
  auto right = c.Post("/api/scans", {{"Authorization", "Bearer s3cret-token-123"}}, "{}",
                      "application/json");
  EXPECT_EQ(right->status, 202) << right->body;
  ASSERT_TRUE(reader.WaitDone(60s));
}

TEST_F(WebServerTest, AnyAddressNeedsTheTokenForEveryApiRequest) {
  std::ofstream(dir_ / "token") << "s3cret-token-123\n";
  std::string config = Config(fmt::format("token_file = \"{}/token\"", dir_.string()), 4);
  config = std::regex_replace(config, std::regex("127\\.0\\.0\\.1:0"), "0.0.0.0:0");
  StartDaemon(config);
  auto c = Client();
  for (const char* path : {"/api/status", "/api/scans", "/api/events", "/api/live/frame.jpg"}) {
    EXPECT_EQ(c.Get(path)->status, 401) << path;
    EXPECT_EQ(c.Get(path, {{"Authorization", "Bearer wrong-wrong"}})->status, 401) << path;
  }
  EXPECT_EQ(c.Get("/api/status", {{"Authorization", "Bearer s3cret-token-123"}})->status, 200);
  EXPECT_EQ(c.Get("/")->status, 200) << "the page asks for the token itself";
  EXPECT_EQ(c.Post("/api/login", R"({"token": "wrong-wrong"})", "application/json")->status, 401);
  auto login = c.Post("/api/login", R"({"token": "s3cret-token-123"})", "application/json");
  ASSERT_EQ(login->status, 200);
  const std::string cookie = login->get_header_value("Set-Cookie");
  EXPECT_NE(cookie.find("HttpOnly"), std::string::npos);
  EXPECT_NE(cookie.find("SameSite=Strict"), std::string::npos);
  const std::string pair = cookie.substr(0, cookie.find(';'));
  EXPECT_EQ(c.Get("/api/status", {{"Cookie", pair}})->status, 200);
  EXPECT_EQ(
      c.Post("/api/scans", {{"Cookie", pair}}, R"({"recipe": "nope"})", "application/json")->status,
      404);
}

TEST(WebConfigTest, AnyAddressWithoutTokenIsRefusedNamingTheKey) {
  auto document = config::Parse("[web]\nlisten = \"0.0.0.0:8080\"\n", "web.toml");
  ASSERT_TRUE(document);
  auto cfg = ParseStationConfig(*document);
  ASSERT_FALSE(cfg);
  EXPECT_EQ(cfg.error().code, ErrorCode::kBadInput);
  EXPECT_NE(cfg.error().message.find("listen"), std::string::npos) << cfg.error().message;
  EXPECT_NE(cfg.error().message.find("token_file"), std::string::npos) << cfg.error().message;
  for (const char* bad : {"nohost", ":8080", "127.0.0.1:99999", "127.0.0.1:x", "[::1]8080"}) {
    auto d = config::Parse(fmt::format("[web]\nlisten = \"{}\"\n", bad), "web.toml");
    EXPECT_FALSE(ParseStationConfig(*d)) << bad;
  }
  for (const char* good : {"", "127.0.0.1:8080", "[::1]:0", "localhost:80"}) {
    auto d = config::Parse(fmt::format("[web]\nlisten = \"{}\"\n", good), "web.toml");
    EXPECT_TRUE(ParseStationConfig(*d)) << good;
  }
  auto defaults = config::Parse("", "web.toml");
  EXPECT_EQ(ParseStationConfig(*defaults)->web.listen, "127.0.0.1:8080");
}

// Per-stop intervals (ms) from the manifest's own timestamps.
std::vector<double> StopIntervalsMs(const fs::path& scan) {
  const Json manifest = ReadJsonFile(scan / "manifest.json");
  std::vector<double> t;
  for (const Json& stop : manifest["stops"]) {
    const std::string time = stop["captured"];  // 2026-11-21T23:01:05.123Z
    std::tm tm{};
    strptime(time.c_str(), "%Y-%m-%dT%H:%M:%S", &tm);
    t.push_back(static_cast<double>(timegm(&tm)) * 1000.0 + std::stod(time.substr(20, 3)));
  }
  std::vector<double> intervals;
  for (std::size_t i = 1; i < t.size(); ++i) intervals.push_back(t[i] - t[i - 1]);
  return intervals;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

TEST_F(WebServerTest, HundredIdleConnectionsLeaveTheStopTimingUnchanged) {
  StartDaemon(Config("timeout_s = 30\nmax_connections = 128", 24, 0.1));
  const std::string baseline = ScanToEnd();
  ASSERT_FALSE(baseline.empty());

  std::vector<UniqueFd> idle;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port_));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  for (int i = 0; i < 100; ++i) {
    UniqueFd fd(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
    ASSERT_EQ(::connect(fd.get(), reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
    idle.push_back(std::move(fd));
  }
  // Plus one that sends half a request and stalls.
  UniqueFd stalled(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  ASSERT_EQ(::connect(stalled.get(), reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  ASSERT_GT(::send(stalled.get(), "GET /api/status HTTP/1.1\r\nHost: x\r\n", 35, 0), 0);

  SseReader reader(port_, {}, IsTerminalEvent);
  ASSERT_TRUE(reader.WaitForStatus(30s));
  auto c = Client();
  auto started = c.Post("/api/scans", "{}", "application/json");
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 202);
  const std::string loaded = Json::parse(started->body)["scan"];
  // A GET still answers while they are held.
  auto status = c.Get("/api/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 200);
  EXPECT_GE(Json::parse(status->body)["web"]["connections"].get<int>(), 100);
  ASSERT_TRUE(reader.WaitDone(120s));

  const double before = Median(StopIntervalsMs(dir_ / "scans" / baseline));
  const double during = Median(StopIntervalsMs(dir_ / "scans" / loaded));
  RecordProperty("stop_median_ms_baseline", std::to_string(before));
  RecordProperty("stop_median_ms_idle100", std::to_string(during));
  std::cout << "median stop interval: " << before << " ms alone, " << during
            << " ms with 100 idle connections\n";
  ASSERT_GT(before, 0.0);
  EXPECT_LT(during, before * 1.5) << "the idle connections slowed the stops";
  idle.clear();
}

// Every path and method of docs/api/openapi.json answers with a status it documents, and JSON
// bodies carry the documented required fields.
class OpenApi {
 public:
  explicit OpenApi(Json doc) : doc_(std::move(doc)) {}
  const Json& Resolve(const Json& schema) const {
    if (!schema.contains("$ref")) return schema;
    const std::string ref = schema["$ref"];  // "#/components/schemas/X"
    return doc_.at(Json::json_pointer(ref.substr(1)));
  }
  // Missing required fields of `value` against `schema` (recursing into allOf and properties).
  void Check(const Json& schema_in, const Json& value, const std::string& where,
             std::vector<std::string>* missing) const {
    const Json& schema = Resolve(schema_in);
    if (schema.contains("allOf")) {
      for (const Json& s : schema["allOf"]) Check(s, value, where, missing);
    }
    if (!value.is_object()) return;
    const Json required = schema.value("required", Json::array());
    const Json properties = schema.value("properties", Json::object());
    for (const Json& key : required) {
      if (!value.contains(key.get<std::string>()))
        missing->push_back(where + "." + key.get<std::string>());
    }
    for (const auto& [key, sub] : properties.items()) {
      if (value.contains(key) && !value[key].is_null())
        Check(sub, value[key], where + "." + key, missing);
    }
    if (schema.contains("items") && value.is_array()) {
      for (const Json& v : value) Check(schema["items"], v, where + "[]", missing);
    }
  }
  const Json& doc() const { return doc_; }

 private:
  Json doc_;
};

TEST_F(WebServerTest, ServerMatchesTheOpenApiDocument) {
  const OpenApi api(ReadJsonFile(fs::path(REVOLVE_SOURCE_DIR) / "docs/api/openapi.json"));
  StartDaemon(Config("", 4));
  const std::string id = ScanToEnd();
  ASSERT_FALSE(id.empty());
  auto c = Client();
  int checked = 0;
  for (const auto& [path, item] : api.doc()["paths"].items()) {
    for (const auto& [method, op] : item.items()) {
      std::string url = std::regex_replace(path, std::regex("\\{id\\}"), id);
      url = std::regex_replace(url, std::regex("\\{path\\}"), "report.json");
      if (method == "get" && path == "/api/events") {
        SseReader reader(port_, {}, [](const Sse& e) { return e.event == "status"; });
        ASSERT_TRUE(reader.WaitDone(10s));
        std::vector<std::string> missing;
        api.Check(Json{{"$ref", "#/components/schemas/Status"}}, reader.Events()[0].data, path,
                  &missing);
        EXPECT_TRUE(missing.empty()) << fmt::format("{}", fmt::join(missing, ", "));
        ++checked;
        continue;
      }
      ASSERT_TRUE(method == "get" || method == "post") << "undocumented method " << method;
      const std::string body = path == "/api/login" ? R"({"token": "x"})" : "{}";
      httplib::Result res =
          method == "get" ? c.Get(url.c_str()) : c.Post(url.c_str(), body, "application/json");
      ASSERT_TRUE(res) << method << " " << url;
      const std::string status = std::to_string(res->status);
      ASSERT_TRUE(op["responses"].contains(status))
          << method << " " << url << " answered " << status << ", not documented: " << res->body;
      const Json response = api.Resolve(op["responses"][status]);
      if (response.contains("content") && response["content"].contains("application/json") &&
          res->get_header_value("Content-Type") == "application/json") {
        std::vector<std::string> missing;
        api.Check(response["content"]["application/json"]["schema"], Json::parse(res->body),
                  method + " " + path, &missing);
        EXPECT_TRUE(missing.empty()) << fmt::format("{}", fmt::join(missing, ", "));
      } else if (response.contains("content")) {
        const std::string type = res->get_header_value("Content-Type");
        bool documented = response["content"].contains("application/octet-stream");
        for (const auto& [media, schema] : response["content"].items()) {
          if (type.rfind(media, 0) == 0) documented = true;
        }
        EXPECT_TRUE(documented) << method << " " << url << ": " << type;
      }
      ++checked;
    }
  }
  EXPECT_GE(checked, 12);
}

}  // namespace
}  // namespace revolve::station
