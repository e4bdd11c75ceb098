#include "station/web_server.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <deque>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <httplib.h>

#include "base/atomic_file.h"
#include "base/log.h"
#include "base/unique_fd.h"
#include "station/protocol.h"
#include "station/web_assets.h"

#ifndef REVOLVE_THREE_DIR
#define REVOLVE_THREE_DIR "/usr/share/javascript/three"
#endif

namespace revolve::station {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr char kCookieName[] = "revolve_token";
// An event stream with nothing to say sends a comment this often (finds dead clients).
constexpr auto kKeepAliveEvery = std::chrono::seconds(15);
// An event stream re-checks whether the server stops this often.
constexpr auto kStreamWait = std::chrono::milliseconds(250);
// The daemon has this long to answer a call (status, start, ...).
constexpr char kJson[] = "application/json";

// Serves each connection on a thread of its own, up to `max` threads (started as needed, then
// kept); connections beyond wait for a free thread. httplib's own pool has a fixed size.
class ConnectionThreads final : public httplib::TaskQueue {
 public:
  explicit ConnectionThreads(std::size_t max, std::atomic<int>* active)
      : max_(max), active_(active) {}

  void enqueue(std::function<void()> fn) override {
    {
      std::lock_guard lock(mutex_);
      jobs_.push_back(std::move(fn));
      // More waiting connections than idle threads to take them: one more thread.
      if (jobs_.size() > idle_ && threads_.size() < max_) threads_.emplace_back([this] { Work(); });
    }
    cv_.notify_one();
  }

  void shutdown() override {
    {
      std::lock_guard lock(mutex_);
      shutdown_ = true;
    }
    cv_.notify_all();
    for (std::thread& t : threads_) t.join();
  }

 private:
  void Work() {
    for (;;) {
      std::function<void()> fn;
      {
        std::unique_lock lock(mutex_);
        ++idle_;
        cv_.wait(lock, [this] { return shutdown_ || !jobs_.empty(); });
        --idle_;
        if (jobs_.empty()) return;  // shutting down
        fn = std::move(jobs_.front());
        jobs_.pop_front();
      }
      ++*active_;
      fn();
      --*active_;
    }
  }

  std::size_t max_;
  std::atomic<int>* active_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> jobs_;
  std::vector<std::thread> threads_;
  std::size_t idle_ = 0;
  bool shutdown_ = false;
};

std::string ErrorBody(std::string_view code, std::string_view message) {
  return nlohmann::json{{"error", {{"code", code}, {"message", message}}}}.dump(
      -1, ' ', false, nlohmann::json::error_handler_t::replace);
}

void SendJson(httplib::Response& res, int status, const nlohmann::json& body) {
  res.status = status;
  res.set_content(body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), kJson);
}

void SendError(httplib::Response& res, int status, std::string_view code,
               std::string_view message) {
  res.status = status;
  res.set_content(ErrorBody(code, message), kJson);
}

void SendError(httplib::Response& res, const Error& error) {
  SendError(res, HttpStatusFor(error.code), ToString(error.code), error.message);
}

// Constant-time comparison (the token must not leak through timing).
bool SameToken(std::string_view a, std::string_view b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  for (std::size_t i = 0; i < a.size(); ++i) {
    diff |= static_cast<unsigned char>(a[i] ^ (i < b.size() ? b[i] : 0));
  }
  return diff == 0;
}

std::optional<std::string> CookieValue(const httplib::Request& req, std::string_view name) {
  const std::size_t n = req.get_header_value_count("Cookie");
  for (std::size_t i = 0; i < n; ++i) {
    const std::string value = req.get_header_value("Cookie", i);
    std::string_view header = value;
    // name=value; name2=value2
    while (!header.empty()) {
      const std::size_t end = std::min(header.find(';'), header.size());
      std::string_view pair = header.substr(0, end);
      while (!pair.empty() && pair.front() == ' ') pair.remove_prefix(1);
      if (pair.size() > name.size() && pair.starts_with(name) && pair[name.size()] == '=') {
        return std::string(pair.substr(name.size() + 1));
      }
      header.remove_prefix(std::min(end + 1, header.size()));
    }
  }
  return std::nullopt;
}

}  // namespace

int HttpStatusFor(ErrorCode code) {
  switch (code) {
    case ErrorCode::kBadInput:
    case ErrorCode::kProtocol:
      return 400;
    case ErrorCode::kNotFound:
      return 404;
    case ErrorCode::kBusy:
      return 409;
    case ErrorCode::kNoDevice:
    case ErrorCode::kLinkDown:
    case ErrorCode::kUnsupported:
      return 503;
    case ErrorCode::kTimeout:
      return 504;
    case ErrorCode::kIo:
      return 507;
    default:
      return 500;
  }
}

Expected<fs::path> ResolveScanFile(const fs::path& scans_dir, std::string_view scan_id,
                                   std::string_view relative) {
  if (!IsValidScanId(scan_id)) {
    return MakeError(ErrorCode::kBadInput, "not a scan id ([A-Za-z0-9._-]+, not . or ..)");
  }
  if (relative.empty()) return MakeError(ErrorCode::kBadInput, "no file named");
  if (relative.front() == '/') {
    return MakeError(ErrorCode::kBadInput, "an absolute path: name a file inside the scan");
  }
  if (relative.find('\0') != std::string_view::npos ||
      relative.find('\\') != std::string_view::npos) {
    return MakeError(ErrorCode::kBadInput, "a file name holds a NUL or a backslash");
  }
  std::string_view rest = relative;
  while (true) {
    const std::size_t slash = rest.find('/');
    const std::string_view part = rest.substr(0, slash);
    if (part.empty() || part == "." || part == "..") {
      return MakeError(ErrorCode::kBadInput,
                       "a path component is empty, \".\" or \"..\": name a file inside the scan");
    }
    if (slash == std::string_view::npos) break;
    rest.remove_prefix(slash + 1);
  }
  std::error_code ec;
  const fs::path dir = fs::canonical(scans_dir / std::string(scan_id), ec);
  if (ec) return MakeError(ErrorCode::kNotFound, fmt::format("no scan \"{}\"", scan_id));
  const fs::path file = fs::canonical(dir / std::string(relative), ec);
  if (ec)
    return MakeError(ErrorCode::kNotFound,
                     fmt::format("no file \"{}\" in scan {}", relative, scan_id));
  // The real path (symlinks resolved) must stay inside the scan's folder.
  const auto [d, f] = std::mismatch(dir.begin(), dir.end(), file.begin(), file.end());
  if (d != dir.end() || !fs::is_regular_file(file, ec)) {
    return MakeError(ErrorCode::kNotFound,
                     fmt::format("no file \"{}\" in scan {}", relative, scan_id));
  }
  return file;
}

std::string_view ContentTypeFor(const fs::path& path) {
  static const std::pair<std::string_view, std::string_view> kTypes[] = {
      {".png", "image/png"},
      {".jpg", "image/jpeg"},
      {".jpeg", "image/jpeg"},
      {".json", "application/json"},
      {".glb", "model/gltf-binary"},
      {".gltf", "model/gltf+json"},
      {".obj", "model/obj"},
      {".mtl", "model/mtl"},
      {".stl", "model/stl"},
      {".ply", "application/octet-stream"},
      {".wrl", "model/vrml"},
      {".toml", "application/toml"},
      {".txt", "text/plain; charset=utf-8"},
      {".html", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"}};
  const std::string ext = path.extension().string();
  for (const auto& [e, type] : kTypes) {
    if (ext == e) return type;
  }
  return "application/octet-stream";
}

Expected<std::string> ReadWebToken(const fs::path& token_file) {
  std::error_code ec;
  if (!fs::exists(token_file, ec)) {
    return MakeError(ErrorCode::kNotFound,
                     fmt::format("web.token_file: {} does not exist (write one line, e.g. "
                                 "`head -c 24 /dev/urandom | base64 > {}`)",
                                 token_file.string(), token_file.string()));
  }
  Expected<std::string> text = ReadWholeFile(token_file);
  if (!text) return MakeError(text.error().code, "web.token_file: " + text.error().message);
  std::string token = text->substr(0, text->find('\n'));
  while (!token.empty() && (token.back() == '\r' || token.back() == ' ' || token.back() == '\t')) {
    token.pop_back();
  }
  token.erase(0, token.find_first_not_of(" \t"));
  const bool printable = std::all_of(token.begin(), token.end(), [](char c) {
    return c > ' ' && c < 127 && c != '"' && c != ',' && c != ';' && c != '\\';
  });
  if (token.size() < 8 || !printable) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("web.token_file: {} must hold a token of at least 8 printable "
                                 "characters (no blanks, quotes, commas, semicolons or "
                                 "backslashes) on its first line",
                                 token_file.string()));
  }
  return token;
}

std::optional<fs::path> FindThreeJs() {
  std::vector<fs::path> candidates;
  if (const char* env = std::getenv("REVOLVE_THREE_DIR"); env != nullptr && *env != '\0') {
    candidates.emplace_back(env);
  }
  candidates.emplace_back(REVOLVE_THREE_DIR);
  candidates.emplace_back("/usr/share/javascript/three");
  std::error_code ec;
  for (const fs::path& dir : candidates) {
    if (fs::exists(dir / "three.min.js", ec)) return dir;
  }
  return std::nullopt;
}

class WebServer::Impl {
 public:
  Impl(const WebOptions& options, std::string token, fs::path scans_dir, StationControl control,
       const EventHub& hub, LiveView* live)
      : options_(options),
        token_(std::move(token)),
        scans_dir_(std::move(scans_dir)),
        control_(std::move(control)),
        hub_(hub),
        live_(live),
        log_(Logger("station")) {}

  ~Impl() { Stop(); }

  Expected<void> Bind() {
    auto address = ParseListenAddress(options_.listen);
    if (!address) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("web.listen: {}", address.error().message));
    }
    loopback_ = address->loopback;
    host_ = address->host;
    LoadThree();
    Configure();
    if (address->port == 0) {
      port_ = server_.bind_to_any_port(address->host);
    } else {
      port_ = server_.bind_to_port(address->host, address->port) ? address->port : -1;
    }
    if (port_ < 0) {
      return MakeError(ErrorCode::kIo,
                       fmt::format("web.listen: cannot listen on {} (is the port in use, or the "
                                   "address not this machine's? `ss -ltnp` shows who listens)",
                                   options_.listen));
    }
    thread_ = std::thread([this] { server_.listen_after_bind(); });
    return {};
  }

  void Stop() {
    if (stopping_.exchange(true)) return;
    server_.stop();
    if (thread_.joinable()) thread_.join();
  }

  int port() const { return port_; }
  std::string url() const {
    const std::string host = host_.find(':') != std::string::npos ? "[" + host_ + "]" : host_;
    return fmt::format("http://{}:{}/", host == "0.0.0.0" || host == "[::]" ? "localhost" : host,
                       port_);
  }

 private:
  void LoadThree() {
    const auto dir = FindThreeJs();
    if (!dir) {
      log_->warn("web: three.js not found (install libjs-three): the console shows no 3D view");
      return;
    }
    const std::pair<const char*, fs::path> files[] = {
        {"three.min.js", *dir / "three.min.js"},
        {"OrbitControls.js", *dir / "examples/js/controls/OrbitControls.js"},
        {"GLTFLoader.js", *dir / "examples/js/loaders/GLTFLoader.js"}};
    for (const auto& [name, path] : files) {
      if (auto bytes = ReadWholeFile(path)) {
        three_[name] = std::move(*bytes);
      } else {
        log_->warn("web: {} is missing: the console shows no 3D view", path.string());
      }
    }
  }

  // Whether `req` may pass; otherwise answers 401.
  bool Authorize(const httplib::Request& req, httplib::Response& res) const {
    if (token_.empty()) return true;
    const bool api = req.path.starts_with("/api/");
    if (!api || req.path == "/api/login") return true;  // the page itself asks for the token
    if (loopback_ && req.method != "POST") return true;
    std::optional<std::string> given;
    const std::string auth = req.get_header_value("Authorization");
    if (auth.starts_with("Bearer ")) given = auth.substr(7);
    if (!given) given = CookieValue(req, kCookieName);
    if (given && SameToken(*given, token_)) return true;
    res.set_header("WWW-Authenticate", "Bearer realm=\"revolve\"");
    SendError(res, 401, "unauthorized",
              given ? "wrong token"
                    : "this needs the console's token: "
                      "Authorization: Bearer <token> (web.token_file)");
    return false;
  }

  // The daemon's status with what the server adds: the last event's id (for /api/events) and
  // the server's own figures.
  nlohmann::json StatusBody(nlohmann::json status, std::uint64_t event_id) const {
    status["event_id"] = event_id;
    status["web"] = {{"url", url()},
                     {"connections", active_.load()},
                     {"token", !token_.empty()},
                     {"viewer", three_.size() == 3}};
    return status;
  }

  void Configure();
  void RouteStatic();
  void RouteApi();
  void RouteScanFiles();
  void RouteEvents();
  void RouteLive();

  // Runs `call` (a StationControl function); answers its error, or hands its value to `ok`.
  template <class Ok>
  void Answer(httplib::Response& res, const std::function<Expected<nlohmann::json>()>& call,
              const Ok& ok) {
    if (!call) {
      SendError(res, 503, "unsupported", "the daemon does not serve this");
      return;
    }
    Expected<nlohmann::json> value = call();
    if (!value) {
      SendError(res, value.error());
      return;
    }
    ok(*value);
  }

  WebOptions options_;
  std::string token_;
  fs::path scans_dir_;
  StationControl control_;
  const EventHub& hub_;
  LiveView* live_;
  std::shared_ptr<spdlog::logger> log_;
  httplib::Server server_;
  std::thread thread_;
  std::atomic<bool> stopping_{false};
  std::atomic<int> active_{0};
  bool loopback_ = true;
  std::string host_;
  int port_ = -1;
  std::map<std::string, std::string> three_;
};

void WebServer::Impl::Configure() {
  const auto timeout = std::chrono::duration<double>(options_.timeout_s);
  const auto usec = std::chrono::duration_cast<std::chrono::microseconds>(timeout).count();
  server_.new_task_queue = [this] {
    return new ConnectionThreads(static_cast<std::size_t>(options_.max_connections), &active_);
  };
  server_.set_read_timeout(usec / 1000000, usec % 1000000);
  server_.set_write_timeout(usec / 1000000, usec % 1000000);
  server_.set_keep_alive_timeout(std::max<time_t>(1, static_cast<time_t>(options_.timeout_s)));
  server_.set_keep_alive_max_count(100);
  server_.set_payload_max_length(static_cast<std::size_t>(options_.max_request_bytes));
  server_.set_tcp_nodelay(true);
  server_.set_default_headers({{"X-Content-Type-Options", "nosniff"},
                               {"Referrer-Policy", "no-referrer"},
                               {"X-Frame-Options", "DENY"}});
  server_.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    return Authorize(req, res) ? httplib::Server::HandlerResponse::Unhandled
                               : httplib::Server::HandlerResponse::Handled;
  });
  server_.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;
    if (res.status == 413) {
      SendError(res, 413, "bad_input", "the request is larger than web.max_request_bytes");
    } else if (res.status == 404) {
      SendError(res, 404, "not_found", fmt::format("nothing at {} {}", req.method, req.path));
    } else {
      SendError(res, res.status, "bad_input", fmt::format("HTTP {}", res.status));
    }
  });
  server_.set_exception_handler(
      [this](const httplib::Request& req, httplib::Response& res, std::exception_ptr ep) {
        std::string what = "unknown";
        try {
          std::rethrow_exception(std::move(ep));
        } catch (const std::exception& e) {
          what = e.what();
        } catch (...) {
        }
        log_->error("web: {} {}: {}", req.method, req.path, what);
        SendError(res, 500, "internal", what);
      });
  RouteStatic();
  RouteApi();
  RouteScanFiles();
  RouteEvents();
  RouteLive();
}

void WebServer::Impl::RouteStatic() {
  for (const WebAsset& asset : WebAssets()) {
    server_.Get(std::string(asset.path), [asset](const httplib::Request&, httplib::Response& res) {
      res.set_header("Cache-Control", "no-cache");
      if (asset.path == "/") {
        res.set_header("Content-Security-Policy",
                       "default-src 'self'; img-src 'self' blob: data:; connect-src 'self' blob:; "
                       "style-src 'self'; script-src 'self'; object-src 'none'; "
                       "frame-ancestors 'none'; base-uri 'none'");
      }
      res.set_content(asset.bytes.data(), asset.bytes.size(), std::string(asset.content_type));
    });
  }
  server_.Get("/three/([A-Za-z.]+)", [this](const httplib::Request& req, httplib::Response& res) {
    const auto it = three_.find(req.matches[1].str());
    if (it == three_.end()) {
      SendError(res, 404, "not_found",
                "three.js is not installed on the station (apt install libjs-three)");
      return;
    }
    res.set_header("Cache-Control", "max-age=86400");
    res.set_content(it->second.data(), it->second.size(), "text/javascript; charset=utf-8");
  });
}

void WebServer::Impl::RouteApi() {
  server_.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
    const std::uint64_t event_id = hub_.last_id();
    Answer(res, control_.status, [&](const nlohmann::json& status) {
      res.set_header("Cache-Control", "no-store");
      SendJson(res, 200, StatusBody(status, event_id));
    });
  });
  server_.Post("/api/scans", [this](const httplib::Request& req, httplib::Response& res) {
    nlohmann::json body = req.body.empty() ? nlohmann::json::object()
                                           : nlohmann::json::parse(req.body, nullptr, false);
    if (body.is_discarded() || !body.is_object()) {
      SendError(res, 400, "bad_input",
                "the body must be a JSON object: {}, {\"recipe\": \"quick\"} or "
                "{\"resume\": \"<scan id>\"}");
      return;
    }
    for (const auto& [key, value] : body.items()) {
      if (key != "recipe" && key != "resume") {
        SendError(res, 400, "bad_input",
                  fmt::format("unknown field \"{}\" (recipe, resume)", key.substr(0, 64)));
        return;
      }
    }
    body["cmd"] = "start";
    Expected<Request> request = ParseRequest(body.dump(), nullptr);
    if (!request) {
      SendError(res, request.error());
      return;
    }
    std::function<Expected<nlohmann::json>()> start;
    if (control_.start) start = [&] { return control_.start(request->recipe, request->resume); };
    Answer(res, start, [&](const nlohmann::json& scan) {
      SendJson(res, 202,
               {{"scan", scan.value("id", std::string())},
                {"recipe", scan.value("recipe", std::string())},
                {"resumed", scan.value("resumed", false)},
                {"dir", scan.value("dir", std::string())}});
    });
  });
  server_.Post("/api/abort", [this](const httplib::Request&, httplib::Response& res) {
    Answer(res, control_.abort, [&](const nlohmann::json& aborted) {
      SendJson(res, 200, {{"scan", aborted.value("scan_id", std::string())}});
    });
  });
  server_.Get("/api/scans", [this](const httplib::Request&, httplib::Response& res) {
    Answer(res, control_.list, [&](nlohmann::json scans) {
      for (nlohmann::json& s : scans) {
        s["stops"] = s.value("stops_planned", 0);
        if (!s.contains("model")) s["model"] = nlohmann::json::array();
        std::error_code ec;
        s["contact_sheet"] =
            fs::exists(scans_dir_ / s.value("id", std::string()) / "contact_sheet.png", ec);
      }
      res.set_header("Cache-Control", "no-store");
      SendJson(res, 200, {{"scans", scans}});
    });
  });
  server_.Post("/api/login", [this](const httplib::Request& req, httplib::Response& res) {
    const nlohmann::json body = nlohmann::json::parse(req.body, nullptr, false);
    const std::string given = body.is_object() ? body.value("token", std::string()) : "";
    if (token_.empty()) {
      SendJson(res, 200, {{"token", false}});
      return;
    }
    if (!SameToken(given, token_)) {
      SendError(res, 401, "unauthorized", "wrong token");
      return;
    }
    res.set_header("Set-Cookie",
                   fmt::format("{}={}; Path=/; HttpOnly; SameSite=Strict", kCookieName, token_));
    SendJson(res, 200, {{"token", true}});
  });
  server_.Post("/api/logout", [](const httplib::Request&, httplib::Response& res) {
    res.set_header("Set-Cookie",
                   fmt::format("{}=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0", kCookieName));
    SendJson(res, 200, nlohmann::json::object());
  });
}

void WebServer::Impl::RouteScanFiles() {
  server_.Get("/api/scans/([^/]+)", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string id = req.matches[1].str();
    auto manifest = ResolveScanFile(scans_dir_, id, "manifest.json");
    if (!manifest) {
      SendError(res, manifest.error().code == ErrorCode::kBadInput ? 400 : 404,
                ToString(manifest.error().code),
                manifest.error().code == ErrorCode::kBadInput ? manifest.error().message
                                                              : fmt::format("no scan \"{}\"", id));
      return;
    }
    nlohmann::json body = {{"id", id}, {"report", nullptr}};
    body["manifest"] = nlohmann::json::parse(ReadWholeFile(*manifest).value_or(""), nullptr, false);
    if (body["manifest"].is_discarded()) body["manifest"] = nullptr;
    if (auto report = ResolveScanFile(scans_dir_, id, "report.json")) {
      body["report"] = nlohmann::json::parse(ReadWholeFile(*report).value_or(""), nullptr, false);
      if (body["report"].is_discarded()) body["report"] = nullptr;
    }
    res.set_header("Cache-Control", "no-store");
    SendJson(res, 200, body);
  });
  server_.Get("/api/scans/([^/]+)/files/(.*)", [this](const httplib::Request& req,
                                                      httplib::Response& res) {
    auto file = ResolveScanFile(scans_dir_, req.matches[1].str(), req.matches[2].str());
    if (!file) {
      SendError(res, file.error());
      return;
    }
    auto fd = std::make_shared<UniqueFd>(::open(file->c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW));
    struct stat st {};
    if (!fd->valid() || ::fstat(fd->get(), &st) != 0 || !S_ISREG(st.st_mode)) {
      SendError(res, 404, "not_found", "no such file in the scan");
      return;
    }
    if (req.has_param("download")) {
      res.set_header("Content-Disposition",
                     fmt::format("attachment; filename=\"{}-{}\"", req.matches[1].str(),
                                 file->filename().string()));
    }
    res.set_header("Cache-Control", "no-cache");
    res.set_content_provider(
        static_cast<std::size_t>(st.st_size), std::string(ContentTypeFor(*file)),
        [fd](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
          char buf[65536];
          const ssize_t n =
              ::pread(fd->get(), buf, std::min(length, sizeof(buf)), static_cast<off_t>(offset));
          if (n <= 0) return false;
          return sink.write(buf, static_cast<std::size_t>(n));
        });
  });
}

void WebServer::Impl::RouteEvents() {
  server_.Get("/api/events", [this](const httplib::Request& req, httplib::Response& res) {
    struct Stream {
      std::uint64_t after = 0;
      bool snapshot = true;  // send the status first
      Clock::time_point last_write = Clock::now();
    };
    auto stream = std::make_shared<Stream>();
    std::string last = req.get_header_value("Last-Event-ID");
    if (last.empty() && req.has_param("last_event_id")) last = req.get_param_value("last_event_id");
    if (!last.empty()) {
      char* end = nullptr;
      const unsigned long long id = std::strtoull(last.c_str(), &end, 10);
      // An id from before a restart (past the last one) gets a fresh status.
      if (end != nullptr && *end == '\0' && id <= hub_.last_id()) {
        stream->after = id;
        stream->snapshot = false;
      }
    }
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Accel-Buffering", "no");
    res.set_chunked_content_provider(
        "text/event-stream", [this, stream](std::size_t, httplib::DataSink& sink) {
          if (stopping_.load()) {
            sink.done();
            return true;
          }
          std::string out;
          auto snapshot = [&] {
            // The id before the status: events after it may repeat what the status shows.
            stream->after = hub_.last_id();
            nlohmann::json status = nlohmann::json::object();
            if (control_.status) {
              if (auto s = control_.status()) status = std::move(*s);
            }
            out += fmt::format("id: {}\nevent: status\ndata: {}\n\n", stream->after,
                               StatusBody(std::move(status), stream->after)
                                   .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
          };
          if (stream->snapshot) {
            stream->snapshot = false;
            out += "retry: 2000\n";
            snapshot();
          } else {
            const EventHub::Batch batch = hub_.Wait(stream->after, kStreamWait);
            if (batch.closed) {
              sink.done();
              return true;
            }
            if (batch.gap) snapshot();
            for (const HubEvent& e : batch.events) {
              if (e.id <= stream->after) continue;
              out += fmt::format(
                  "id: {}\nevent: scan\ndata: {}\n\n", e.id,
                  e.event.ToJson().dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
              stream->after = e.id;
            }
          }
          if (out.empty()) {
            if (Clock::now() - stream->last_write < kKeepAliveEvery) return true;
            out = ": keep-alive\n\n";
          }
          stream->last_write = Clock::now();
          return sink.write(out.data(), out.size());
        });
  });
}

void WebServer::Impl::RouteLive() {
  auto send = [](httplib::Response& res, const std::optional<LiveBlob>& blob, const char* type,
                 const char* what) {
    if (!blob) {
      SendError(res, 404, "not_found", what);
      return;
    }
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Revolve-Scan", blob->scan_id);
    res.set_header("X-Revolve-Stop", std::to_string(blob->stop));
    res.set_header("X-Revolve-Stops-In", std::to_string(blob->stops_in));
    res.set_content(blob->bytes, type);
  };
  server_.Get("/api/live/frame.jpg", [this, send](const httplib::Request&, httplib::Response& res) {
    send(res, live_ ? live_->FrameJpeg() : std::nullopt, "image/jpeg",
         "no frame yet: start a scan");
  });
  server_.Get("/api/live/hull.glb", [this, send](const httplib::Request&, httplib::Response& res) {
    send(res, live_ ? live_->HullGlb() : std::nullopt, "model/gltf-binary",
         "no hull yet: it is built from the second stop on (not in thesis mode, whose views "
         "need every silhouette)");
  });
}

WebServer::WebServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
WebServer::~WebServer() { Stop(); }

Expected<std::unique_ptr<WebServer>> WebServer::Start(const WebOptions& options, std::string token,
                                                      fs::path scans_dir, StationControl control,
                                                      const EventHub& hub, LiveView* live) {
  auto impl = std::make_unique<Impl>(options, std::move(token), std::move(scans_dir),
                                     std::move(control), hub, live);
  if (auto bound = impl->Bind(); !bound) return std::unexpected(bound.error());
  return std::unique_ptr<WebServer>(new WebServer(std::move(impl)));
}

void WebServer::Stop() {
  if (impl_) impl_->Stop();
}
int WebServer::port() const { return impl_->port(); }
std::string WebServer::url() const { return impl_->url(); }

}  // namespace revolve::station
