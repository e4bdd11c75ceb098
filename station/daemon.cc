#include "station/daemon.h"

#include <fcntl.h>
#include <grp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <list>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "base/log.h"
#include "base/unique_fd.h"
#include "station/control_socket.h"
#include "station/devices.h"
#include "station/event_hub.h"
#include "station/live_view.h"
#include "station/loop_calls.h"
#include "station/notify.h"
#include "station/protocol.h"
#include "station/scan_folder.h"
#include "station/scan_session.h"
#include "station/web_server.h"

#ifndef REVOLVE_VERSION
#define REVOLVE_VERSION "unknown"
#endif

namespace revolve::station {
namespace {

using Clock = std::chrono::steady_clock;

// A watcher that lets this much output pile up is too slow and is dropped.
constexpr std::size_t kMaxClientOutBytes = 4u << 20;
// `list` returns at most this many scans (the newest).
constexpr std::size_t kMaxListedScans = 1000;
// The main loop wakes at least this often.
constexpr auto kMaxPollWait = std::chrono::milliseconds(1000);
// A web request waits this long for the main loop.
constexpr auto kWebCallTimeout = std::chrono::milliseconds(5000);
// A silent client is never evicted for a newcomer before it has been idle this long.
constexpr auto kMinIdleToEvict = std::chrono::milliseconds(500);

Error Errno(ErrorCode code, std::string what, int err) {
  return Error{code, fmt::format("{}: {}", what, std::strerror(err))};
}

struct Client {
  Client(UniqueFd f, std::size_t max_line) : fd(std::move(f)), in(max_line) {}
  UniqueFd fd;
  LineSplitter in;
  std::string out;
  bool watching = false;
  bool closed = false;
  // When it last sent a byte: a client that neither sends nor watches holds a control slot.
  std::chrono::steady_clock::time_point last_active = std::chrono::steady_clock::now();
};

struct ScanJob {
  std::string id;
  std::filesystem::path dir;
  bool resumed = false;
  StationConfig config;
  std::optional<ScanFolder> folder;
  std::unique_ptr<ScanSession> session;
  std::stop_source stop;
  std::jthread thread;
};

}  // namespace

std::filesystem::path ResolveScansDir(const StationOptions& options) {
  std::filesystem::path dir(options.scans_dir);
  if (dir.is_absolute()) return dir;
  if (const char* state = std::getenv("STATE_DIRECTORY"); state != nullptr && *state != '\0') {
    std::string first(state);
    first = first.substr(0, first.find(':'));
    return std::filesystem::path(first) / dir;
  }
  std::error_code ec;
  return std::filesystem::current_path(ec) / dir;
}

class Daemon::Impl {
 public:
  Impl(StationConfig config, DaemonHooks hooks)
      : config_(std::move(config)), hooks_(std::move(hooks)), log_(Logger("station")) {}

  ~Impl() {
    loop_calls_.Close();
    if (web_) web_->Stop();
    if (job_) {
      job_->stop.request_stop();
      if (job_->thread.joinable()) job_->thread.join();
    }
    if (listen_fd_.valid()) ::unlink(socket_path_.c_str());
  }

  Expected<void> Init() {
    socket_path_ = config_.daemon.socket;
    scans_dir_ = ResolveScansDir(config_.station);
    std::error_code ec;
    std::filesystem::create_directories(scans_dir_, ec);
    if (ec) {
      return MakeError(ErrorCode::kIo, fmt::format("station.scans_dir: cannot create {}: {}",
                                                   scans_dir_.string(), ec.message()));
    }
    OpenAllDevices();

    std::unique_ptr<OperatorLines> lines = std::move(hooks_.panel_lines);
    if (!lines) {
      auto opened = OpenPanelLines(config_.panel);
      if (opened) {
        lines = std::move(*opened);
      } else {
        panel_error_ = opened.error().message;
        log_->error("operator panel: {} (the control socket still works)", panel_error_);
      }
    }
    if (lines) panel_ = std::make_unique<OperatorPanel>(std::move(lines), config_.panel);

    wake_fd_ = UniqueFd(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
    if (!wake_fd_.valid()) return std::unexpected(Errno(ErrorCode::kIo, "eventfd", errno));
    if (hooks_.handle_signals) {
      sigset_t set;
      sigemptyset(&set);
      sigaddset(&set, SIGTERM);
      sigaddset(&set, SIGINT);
      sigaddset(&set, SIGHUP);
      signal_fd_ = UniqueFd(::signalfd(-1, &set, SFD_CLOEXEC | SFD_NONBLOCK));
      if (!signal_fd_.valid()) return std::unexpected(Errno(ErrorCode::kIo, "signalfd", errno));
    }
    auto listen = BindControlSocket(socket_path_, config_.daemon);
    if (!listen) return std::unexpected(listen.error());
    listen_fd_ = std::move(*listen);
    // The socket's watchers and the web console's streams read the same events.
    hub_.Subscribe([this](const HubEvent& h) {
      const std::string line = EventLine(h.event);
      for (Client& c : clients_) {
        if (c.watching && !c.closed) Queue(c, line);
      }
    });
    if (auto web = StartWeb(); !web) return std::unexpected(web.error());
    started_ = Clock::now();
    last_event_.time = IsoTimeNow();
    return {};
  }

  int Run() {
    notifier_.Ready(StatusText());
    log_->info("revolved {} ready: socket {}, scans in {}, devices {}{}", REVOLVE_VERSION,
               socket_path_.string(), scans_dir_.string(),
               devices_ok_ ? DevicesText() : "NOT up: " + devices_error_,
               panel_ ? ", panel " + panel_->Describe() : "");
    if (const auto wd = notifier_.watchdog_interval()) next_watchdog_ = Clock::now();
    while (!shutdown_.load()) {
      PollOnce();
    }
    Shutdown();
    return 0;
  }

  void RequestShutdown() {
    {
      std::lock_guard lock(queue_mutex_);
      if (shutdown_reason_.empty()) shutdown_reason_ = "revolved is stopping";
    }
    shutdown_.store(true);
    Wake();
  }

  const std::filesystem::path& socket_path() const { return socket_path_; }
  const std::filesystem::path& scans_dir() const { return scans_dir_; }

 private:
  // ---- Web console (station/web_server.h) -----------------------------------------------------

  Expected<void> StartWeb() {
    if (config_.web.listen.empty()) return {};
    std::string token;
    if (!config_.web.token_file.empty()) {
      auto read = ReadWebToken(config_.web.token_file);
      if (!read) return MakeError(ErrorCode::kBadInput, read.error().message);
      token = std::move(*read);
    }
    if (auto live = LiveView::Create({}); live) {
      live_ = std::move(*live);
    } else {
      log_->warn("web: {} (no live frame or hull)", live.error().message);
    }
    StationControl control;
    control.status = [this] {
      return loop_calls_.Run([this]() -> Expected<nlohmann::json> { return StatusJson(); },
                             kWebCallTimeout);
    };
    control.start = [this](const std::optional<std::string>& recipe,
                           const std::optional<std::string>& resume) {
      return loop_calls_.Run(
          [this, recipe, resume] {
            auto started = Start(recipe, resume, "web");
            if (!started) log_->warn("start refused: {}", started.error().message);
            return started;
          },
          kWebCallTimeout);
    };
    control.abort = [this] {
      return loop_calls_.Run([this] { return Abort("abort requested over the web console"); },
                             kWebCallTimeout);
    };
    control.list = [this] {
      return loop_calls_.Run([this]() -> Expected<nlohmann::json> { return ListScans(); },
                             kWebCallTimeout);
    };
    auto web = WebServer::Start(config_.web, std::move(token), scans_dir_, std::move(control), hub_,
                                live_.get());
    if (!web) return std::unexpected(web.error());
    web_ = std::move(*web);
    log_->info("web console: {}{}", web_->url(),
               config_.web.token_file.empty() ? "" : " (token: web.token_file)");
    return {};
  }

  // ---- Devices -------------------------------------------------------------------------------

  void OpenAllDevices() {
    devices_ok_ = false;
    if (devices_.camera) devices_.camera->Stop();
    devices_ = Devices{};
    auto devices = OpenDevices(config_);
    if (!devices) {
      devices_error_ = devices.error().message;
      log_->error("devices: {}", devices_error_);
      return;
    }
    devices_ = std::move(*devices);
    devices_.captures = captures_;
    if (auto reopened = ReopenCamera(config_, devices_); !reopened) {
      devices_error_ = reopened.error().message;
      log_->error("devices: {}", devices_error_);
      return;
    }
    // Probe the camera: it opens and streams.
    if (auto started = devices_.camera->Start(); !started) {
      devices_error_ = "camera: " + started.error().message;
      log_->error("devices: {}", devices_error_);
      return;
    }
    devices_.camera->Stop();
    devices_ok_ = true;
    devices_error_.clear();
  }

  std::string DevicesText() const {
    if (!devices_.turntable || !devices_.camera) return "none";
    return devices_.turntable->Describe() + " / " + devices_.camera->Describe();
  }

  // ---- Scans ---------------------------------------------------------------------------------

  std::string UniqueScanId() const {
    std::string base = NewScanId();
    std::error_code ec;
    if (!std::filesystem::exists(scans_dir_ / base, ec)) return base;
    for (int n = 2;; ++n) {
      std::string id = fmt::format("{}-{}", base, n);
      if (!std::filesystem::exists(scans_dir_ / id, ec)) return id;
    }
  }

  Expected<void> CheckFreeSpace() const {
    if (config_.station.min_free_mb <= 0.0) return {};
    struct statvfs vfs {};
    if (::statvfs(scans_dir_.c_str(), &vfs) != 0) return {};
    const double free_mb =
        static_cast<double>(vfs.f_bavail) * static_cast<double>(vfs.f_frsize) / (1024.0 * 1024.0);
    if (free_mb < config_.station.min_free_mb) {
      return MakeError(ErrorCode::kIo,
                       fmt::format("only {:.1f} MB free in {} (station.min_free_mb = {}): make "
                                   "room before scanning; earlier scans are kept",
                                   free_mb, scans_dir_.string(), config_.station.min_free_mb));
    }
    return {};
  }

  Expected<nlohmann::json> Start(const std::optional<std::string>& recipe,
                                 const std::optional<std::string>& resume,
                                 std::string_view origin) {
    if (shutdown_.load()) return MakeError(ErrorCode::kBusy, "revolved is stopping");
    if (job_) {
      return MakeError(
          ErrorCode::kBusy,
          fmt::format("scan {} is running ({}{}); one scan at a time: wait, or `revolve abort`",
                      job_->id, ToString(last_event_.state),
                      last_event_.stop >= 0
                          ? fmt::format(", stop {}/{}", last_event_.stop + 1, last_event_.stops)
                          : std::string()));
    }
    if (auto space = CheckFreeSpace(); !space) return std::unexpected(space.error());
    if (!devices_ok_) {
      OpenAllDevices();
      if (!devices_ok_) {
        return MakeError(ErrorCode::kNoDevice,
                         fmt::format("the devices are not up: {}", devices_error_));
      }
    } else if (auto state = devices_.turntable->State(); !state) {
      log_->warn("turntable: {}; reopening it", state.error().message);
      turntable::TurntableOptions table = config_.turntable;
      auto reopened = turntable::Create(table, devices_.plate);
      if (!reopened) {
        return MakeError(ErrorCode::kNoDevice,
                         fmt::format("the turntable is not up: {}", reopened.error().message));
      }
      devices_.turntable = std::move(*reopened);
    }

    auto job = std::make_unique<ScanJob>();
    if (resume) {
      job->resumed = true;
      job->id = *resume;
      job->dir = scans_dir_ / *resume;
      auto cfg = LoadStationConfig(job->dir / "scan.toml");
      if (!cfg) {
        return MakeError(
            cfg.error().code == ErrorCode::kNotFound ? ErrorCode::kNotFound : ErrorCode::kBadInput,
            fmt::format("cannot resume {}: {} (see `revolve list`)", *resume, cfg.error().message));
      }
      job->config = std::move(*cfg);
      auto manifest = ReadManifest(job->dir);
      if (!manifest) return std::unexpected(manifest.error());
      if (manifest->value("state", std::string()) == "complete") {
        return MakeError(ErrorCode::kBadInput,
                         fmt::format("cannot resume {}: the scan is complete, nothing to resume "
                                     "(start a new scan with `revolve start`)",
                                     *resume));
      }
      job->config.recipe = manifest->value("recipe", std::string("default"));
      auto folder = ScanFolder::Open(job->dir);
      if (!folder) return std::unexpected(folder.error());
      job->folder.emplace(std::move(*folder));
    } else {
      auto cfg = ApplyRecipe(config_, recipe.value_or(""));
      if (!cfg) return std::unexpected(cfg.error());
      job->config = std::move(*cfg);
    }
    // The camera and segmenter of this scan's configuration (a recipe may change them), before
    // a new folder is made.
    devices_.captures = captures_;
    // Probed as `revolve scan` does: a camera that cannot stream (unplugged, held) refuses the
    // start before a folder is made (no_device, or busy when another program holds it).
    auto camera = ReopenCamera(job->config, devices_);
    if (camera) {
      if (auto started = devices_.camera->Start(); !started)
        camera = std::unexpected(started.error());
    }
    if (!camera) {
      devices_ok_ = false;
      devices_error_ = fmt::format("camera: {} (check [camera] in {})", camera.error().message,
                                   job->config.origin);
      return MakeError(
          camera.error().code == ErrorCode::kBusy ? ErrorCode::kBusy : ErrorCode::kNoDevice,
          devices_error_);
    }
    devices_.camera->Stop();
    if (!resume) {
      job->id = UniqueScanId();
      job->dir = scans_dir_ / job->id;
      auto folder = ScanFolder::Create(job->dir);
      if (!folder) return std::unexpected(folder.error());
      job->folder.emplace(std::move(*folder));
    }
    ScanFolder& folder = job->folder.value();  // opened or created above
    folder.SetByteLimit(job->config.station.simulate.disk_limit_bytes);
    job->session = std::make_unique<ScanSession>(job->config, devices_, folder, job->id);
    job->session->OnEvent([this](const ScanEvent& event) { Post(event); });
    if (live_) job->session->OnLive([this](const LiveStop& stop) { live_->AddStop(stop); });
    ScanJob* raw = job.get();
    raw->thread = std::jthread([this, raw] {
      Expected<ScanResult> result = raw->resumed ? raw->session->Resume(raw->stop.get_token())
                                                 : raw->session->Run(raw->stop.get_token());
      {
        std::lock_guard lock(queue_mutex_);
        job_finished_ = true;
        job_error_ = result ? std::nullopt : std::optional<Error>(result.error());
      }
      Wake();
    });
    log_->info("start ({}): scan {}{}, recipe \"{}\" -> {}", origin, job->id,
               job->resumed ? " resumed" : "", job->config.recipe, job->dir.string());
    last_scan_ = {{"id", job->id},
                  {"dir", job->dir.string()},
                  {"recipe", job->config.recipe},
                  {"resumed", job->resumed}};
    job_ = std::move(job);
    return last_scan_;
  }

  Expected<nlohmann::json> Abort(std::string reason) {
    if (!job_) return MakeError(ErrorCode::kBadInput, "no scan is running");
    job_->session->SetAbortReason(reason);
    const auto t = Clock::now();
    job_->stop.request_stop();  // runs ScanSession's stop callback here: Turntable::Stop()
    log_->info("abort ({}): scan {}, motor stop requested in {:.1f} ms", reason, job_->id,
               std::chrono::duration<double, std::milli>(Clock::now() - t).count());
    return nlohmann::json{{"scan_id", job_->id}};
  }

  // Scanning thread: queue an event for the main loop.
  void Post(const ScanEvent& event) {
    {
      std::lock_guard lock(queue_mutex_);
      queue_.push_back(event);
    }
    Wake();
  }

  void Wake() {
    const std::uint64_t one = 1;
    if (wake_fd_.valid()) (void)!::write(wake_fd_.get(), &one, sizeof(one));
  }

  // Handles the scanning thread's events. The scan is over (and a new one may start) as soon as
  // its terminal event is handled: the thread is joined right there, before any client is read.
  void DrainQueue() {
    std::deque<ScanEvent> events;
    bool finished = false;
    {
      std::lock_guard lock(queue_mutex_);
      events.swap(queue_);
      finished = job_finished_;
    }
    for (const ScanEvent& e : events) {
      OnEvent(e);
      if (job_ && e.scan_id == job_->id && IsTerminal(e.state)) FinishJob();
    }
    if (finished && job_) FinishJob();  // ended without a terminal event
  }

  void FinishJob() {
    if (job_->thread.joinable()) job_->thread.join();
    std::optional<Error> error;
    {
      std::lock_guard lock(queue_mutex_);
      error = job_error_;
      job_error_.reset();
      job_finished_ = false;
    }
    if (last_event_.scan_id != job_->id || !IsTerminal(last_event_.state)) {
      // The scan ended before its state machine could say so (e.g. a resume that was refused).
      ScanEvent e;
      e.seq = last_event_.seq + 1;
      e.scan_id = job_->id;
      e.stops = job_->config.scan.stops;
      e.state =
          error && error->code == ErrorCode::kAborted ? ScanState::kAborted : ScanState::kFailed;
      e.error = error.value_or(Error{ErrorCode::kInternal, "the scan ended without a result"});
      e.note = e.error->message;
      e.time = IsoTimeNow();
      OnEvent(e);
    }
    job_.reset();
  }

  void OnEvent(const ScanEvent& e) {
    last_event_ = e;
    const std::string where =
        e.stop >= 0 ? fmt::format(" stop {}/{} ({} deg)", e.stop + 1, e.stops, e.angle_deg) : "";
    switch (e.state) {
      case ScanState::kDone:
        log_->info("scan {}: done, {} stops, {:.1f} s", e.scan_id, e.stops_done, e.elapsed_s);
        break;
      case ScanState::kFailed:
        log_->error("scan {}: failed after {} of {} stops: {}{}", e.scan_id, e.stops_done, e.stops,
                    e.error ? e.error->ToString() : e.note,
                    e.alarm_code
                        ? fmt::format(" [drive alarm {:#x}: {}]", *e.alarm_code, e.alarm_text)
                        : std::string());
        break;
      case ScanState::kAborted:
        log_->warn("scan {}: aborted after {} of {} stops: {}", e.scan_id, e.stops_done, e.stops,
                   e.note);
        break;
      default:
        if (!e.note.empty()) {
          log_->warn("scan {}: {}{}: {}", e.scan_id, ToString(e.state), where, e.note);
        } else {
          log_->info("scan {}: {}{}", e.scan_id, ToString(e.state), where);
        }
    }
    notifier_.Status(StatusText());
    hub_.Publish(e);
  }

  std::string StatusText() const {
    const ScanEvent& e = last_event_;
    if (!devices_ok_ && !IsActive(e.state)) return "Devices not up: " + devices_error_;
    switch (e.state) {
      case ScanState::kIdle:
        return "Idle";
      case ScanState::kDone:
        return fmt::format("Idle; scan {} done", e.scan_id);
      case ScanState::kFailed:
        return fmt::format("Fault: scan {} failed: {}", e.scan_id, e.note);
      case ScanState::kAborted:
        return fmt::format("Idle; scan {} aborted", e.scan_id);
      default:
        break;
    }
    return fmt::format("Scanning {}: {}{} ({:.0f}%)", e.scan_id, ToString(e.state),
                       e.stop >= 0 ? fmt::format(" stop {}/{}", e.stop + 1, e.stops) : "",
                       100.0 * e.progress);
  }

  LedPattern Pattern() const { return PatternFor(last_event_.state, devices_ok_); }

  nlohmann::json StatusJson() const {
    nlohmann::json j = last_event_.ToJson();
    j["scan"] = last_scan_;
    j["busy"] = job_ != nullptr;
    j["led"] = ToString(Pattern());
    j["devices"] = {{"ok", devices_ok_}, {"description", DevicesText()}};
    if (!devices_ok_) j["devices"]["error"] = devices_error_;
    if (panel_) {
      j["panel"] = panel_->Describe();
    } else if (!panel_error_.empty()) {
      j["panel"] = "error: " + panel_error_;
    } else {
      j["panel"] = nullptr;
    }
    j["daemon"] = {{"pid", ::getpid()},
                   {"version", REVOLVE_VERSION},
                   {"uptime_s", std::chrono::duration<double>(Clock::now() - started_).count()},
                   {"clients", clients_.size()},
                   {"socket", socket_path_.string()},
                   {"scans_dir", scans_dir_.string()},
                   {"web", web_ ? nlohmann::json(web_->url()) : nlohmann::json(nullptr)},
                   {"recipes", RecipeNames(config_)},
                   {"default_recipe", config_.station.recipe}};
    return j;
  }

  nlohmann::json ListScans() const {
    return ListScanFolders(scans_dir_, job_ ? job_->id : std::string(), kMaxListedScans);
  }

  // ---- Clients -------------------------------------------------------------------------------

  void Queue(Client& c, std::string_view bytes) {
    if (c.out.size() + bytes.size() > kMaxClientOutBytes) {
      log_->warn("dropping a client that does not read its replies ({} bytes pending)",
                 c.out.size());
      c.closed = true;
      return;
    }
    c.out.append(bytes);
  }

  void HandleLine(Client& c, const std::string& line) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) return;  // blank lines
    nlohmann::json id;
    Expected<Request> request = ParseRequest(line, &id);
    if (!request) {
      Queue(c, ErrorLine(id, request.error()));
      return;
    }
    switch (request->kind) {
      case RequestKind::kStatus:
        Queue(c, OkLine(id, {{"status", StatusJson()}}));
        break;
      case RequestKind::kList:
        Queue(c, OkLine(id, {{"scans", ListScans()}}));
        break;
      case RequestKind::kWatch:
        c.watching = true;
        Queue(c, OkLine(id, {{"status", StatusJson()}}));
        break;
      case RequestKind::kStart: {
        auto started = Start(request->recipe, request->resume, "socket");
        Queue(c, started ? OkLine(id, {{"scan", *started}}) : ErrorLine(id, started.error()));
        if (!started) log_->warn("start refused: {}", started.error().message);
        break;
      }
      case RequestKind::kAbort: {
        auto aborted = Abort("abort requested over the socket");
        Queue(c, aborted ? OkLine(id, *aborted) : ErrorLine(id, aborted.error()));
        break;
      }
    }
  }

  void ReadClient(Client& c) {
    char buf[16384];
    for (int round = 0; round < 8 && !c.closed; ++round) {
      const ssize_t n = ::recv(c.fd.get(), buf, sizeof(buf), 0);
      if (n > 0) {
        c.last_active = std::chrono::steady_clock::now();
        c.in.Append(std::string_view(buf, static_cast<std::size_t>(n)));
        for (auto item = c.in.Next(); item.has_value(); item = c.in.Next()) {
          if (item->kind == LineSplitter::Kind::kTooLong) {
            Queue(c, ErrorLine(nullptr, Error{ErrorCode::kProtocol,
                                              fmt::format("request longer than {} bytes "
                                                          "(daemon.max_request_bytes); dropped",
                                                          config_.daemon.max_request_bytes)}));
          } else {
            HandleLine(c, item->line);
          }
          if (c.closed) return;
        }
        if (static_cast<std::size_t>(n) < sizeof(buf)) return;
        continue;
      }
      if (n == 0) {
        c.closed = true;
        return;
      }
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) c.closed = true;
      return;
    }
  }

  void WriteClient(Client& c) {
    while (!c.out.empty() && !c.closed) {
      const ssize_t n = ::send(c.fd.get(), c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n > 0) {
        c.out.erase(0, static_cast<std::size_t>(n));
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
      c.closed = true;
    }
  }

  void AcceptClients() {
    for (;;) {
      UniqueFd fd(::accept4(listen_fd_.get(), nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
      if (!fd.valid()) {
        if (errno == EINTR) continue;
        if (errno != EAGAIN && errno != EWOULDBLOCK) {
          log_->warn("accept: {}", std::strerror(errno));
        }
        return;
      }
      if (clients_.size() >= static_cast<std::size_t>(config_.daemon.max_clients)) {
        EvictIdlestClient();
      }
      if (clients_.size() >= static_cast<std::size_t>(config_.daemon.max_clients)) {
        const std::string line = ErrorLine(
            nullptr, Error{ErrorCode::kBusy, fmt::format("too many clients (daemon.max_clients "
                                                         "= {})",
                                                         config_.daemon.max_clients)});
        (void)!::send(fd.get(), line.data(), line.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
        continue;
      }
      clients_.emplace_back(std::move(fd),
                            static_cast<std::size_t>(config_.daemon.max_request_bytes));
    }
  }

  // A client that neither sends nor watches holds a slot for nothing: it is closed after
  // daemon.idle_timeout_s, and sooner (idle kMinIdleToEvict) when a newcomer needs its slot.
  static bool Idle(const Client& c) { return !c.watching && !c.closed && c.out.empty(); }
  void CloseIdle(Client& c, std::string_view why) {
    const std::string line =
        ErrorLine(nullptr, Error{ErrorCode::kTimeout, fmt::format("closed: idle (nothing sent, not "
                                                                  "watching): {}",
                                                                  why)});
    (void)!::send(c.fd.get(), line.data(), line.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    c.closed = true;
  }
  void EvictIdlestClient() {
    const auto idlest = std::ranges::min_element(clients_, {}, [](const Client& c) {
      return Idle(c) ? c.last_active : std::chrono::steady_clock::time_point::max();
    });
    if (idlest == clients_.end() || !Idle(*idlest) ||
        std::chrono::steady_clock::now() - idlest->last_active < kMinIdleToEvict) {
      return;
    }
    CloseIdle(*idlest, "its slot was needed (every daemon.max_clients slot is taken)");
    clients_.erase(idlest);
  }
  void CloseIdleClients() {
    const auto limit = std::chrono::duration<double>(config_.daemon.idle_timeout_s);
    for (Client& c : clients_) {
      if (Idle(c) && std::chrono::steady_clock::now() - c.last_active > limit) {
        CloseIdle(c, "daemon.idle_timeout_s");
      }
    }
  }

  // ---- Main loop -----------------------------------------------------------------------------

  int PollTimeoutMs() const {
    const auto now = Clock::now();
    auto deadline = now + kMaxPollWait;
    if (notifier_.watchdog_interval()) deadline = std::min(deadline, next_watchdog_);
    if (panel_) {
      if (auto next = panel_->NextDeadline(MonoNow())) {
        deadline = std::min(deadline,
                            Clock::time_point(std::chrono::duration_cast<Clock::duration>(*next)));
      }
    }
    const auto wait = std::chrono::ceil<std::chrono::milliseconds>(deadline - now).count();
    return static_cast<int>(std::clamp<long long>(wait, 0, kMaxPollWait.count()));
  }

  void PollOnce() {
    std::vector<pollfd> fds;
    fds.push_back({wake_fd_.get(), POLLIN, 0});
    fds.push_back({signal_fd_.valid() ? signal_fd_.get() : -1, POLLIN, 0});
    fds.push_back({listen_fd_.get(), POLLIN, 0});
    if (panel_) {
      for (int fd : panel_->PollFds()) fds.push_back({fd, POLLIN, 0});
    }
    const std::size_t clients_first = fds.size();
    for (const Client& c : clients_) {
      fds.push_back({c.fd.get(), static_cast<short>(POLLIN | (c.out.empty() ? 0 : POLLOUT)), 0});
    }
    const int ready = ::poll(fds.data(), fds.size(), PollTimeoutMs());
    if (ready < 0 && errno != EINTR) {
      log_->error("poll: {}", std::strerror(errno));
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }

    if (fds[0].revents & POLLIN) {
      std::uint64_t count = 0;
      (void)!::read(wake_fd_.get(), &count, sizeof(count));
    }
    DrainQueue();
    loop_calls_.RunPending();
    if (signal_fd_.valid() && (fds[1].revents & POLLIN)) ReadSignals();
    if (fds[2].revents & POLLIN) AcceptClients();

    // The panel's edges are read on every pass; its fds (panel_first..) only wake the loop.
    if (panel_) {
      for (PanelCommand command : panel_->Service(MonoNow())) {
        if (command == PanelCommand::kStart) {
          if (auto started = Start(std::nullopt, std::nullopt, "button"); !started) {
            log_->warn("start button: {}", started.error().message);
          }
        } else if (auto aborted = Abort("abort button"); !aborted) {
          log_->info("abort button: {}", aborted.error().message);
        }
      }
    }

    std::size_t i = clients_first;
    for (Client& c : clients_) {
      // Clients accepted during this pass have no pollfd yet.
      if (i >= fds.size()) break;
      const short revents = fds[i++].revents;
      if (revents & (POLLERR | POLLNVAL)) c.closed = true;
      if (!c.closed && (revents & (POLLIN | POLLHUP))) ReadClient(c);
      if (!c.closed) WriteClient(c);
    }
    CloseIdleClients();
    clients_.remove_if([](const Client& c) { return c.closed; });

    if (panel_) panel_->Show(Pattern(), LampOn(last_event_.state), MonoNow());
    if (const auto wd = notifier_.watchdog_interval(); wd && Clock::now() >= next_watchdog_) {
      notifier_.Watchdog();
      next_watchdog_ = Clock::now() + *wd / 2;
    }
  }

  void ReadSignals() {
    signalfd_siginfo info{};
    while (::read(signal_fd_.get(), &info, sizeof(info)) == static_cast<ssize_t>(sizeof(info))) {
      const int sig = static_cast<int>(info.ssi_signo);
      if (sig == SIGHUP) {
        log_->warn("SIGHUP: reloading the configuration is not supported; restart revolved");
        continue;
      }
      {
        std::lock_guard lock(queue_mutex_);
        shutdown_reason_ =
            fmt::format("{}: revolved is stopping", sig == SIGTERM ? "SIGTERM" : "SIGINT");
      }
      shutdown_.store(true);
    }
  }

  void Shutdown() {
    std::string reason;
    {
      std::lock_guard lock(queue_mutex_);
      reason = shutdown_reason_.empty() ? "revolved is stopping" : shutdown_reason_;
    }
    notifier_.Stopping(job_ ? "Stopping: aborting the scan" : "Stopping");
    if (job_) {
      const auto t = Clock::now();
      (void)Abort(reason);
      // Power the motor off too, from here, without waiting for the scanning thread.
      if (devices_.turntable) (void)devices_.turntable->Disable();
      log_->info(
          "{}: motor stopped and disabled in {:.1f} ms; waiting for the scan to close its "
          "folder",
          reason, std::chrono::duration<double, std::milli>(Clock::now() - t).count());
      job_->thread.join();
      DrainQueue();
      if (job_) FinishJob();
    } else if (devices_.turntable) {
      devices_.turntable->Stop();
      (void)devices_.turntable->Disable();
    }
    if (panel_) panel_->Show(LedPattern::kOff, false, MonoNow());
    loop_calls_.Close();
    if (web_) web_->Stop();
    for (Client& c : clients_) WriteClient(c);  // best effort: the last events
    clients_.clear();
    listen_fd_.Reset();
    ::unlink(socket_path_.c_str());
    log_->info("revolved stopped ({})", reason);
  }

  StationConfig config_;
  DaemonHooks hooks_;
  std::shared_ptr<spdlog::logger> log_;
  std::filesystem::path socket_path_;
  std::filesystem::path scans_dir_;
  UniqueFd listen_fd_;
  UniqueFd wake_fd_;
  UniqueFd signal_fd_;
  std::list<Client> clients_;
  Devices devices_;
  std::shared_ptr<std::atomic<std::int64_t>> captures_ =
      std::make_shared<std::atomic<std::int64_t>>(0);
  bool devices_ok_ = false;
  std::string devices_error_;
  std::unique_ptr<OperatorPanel> panel_;
  std::string panel_error_;
  Notifier notifier_;
  std::unique_ptr<ScanJob> job_;
  ScanEvent last_event_;
  nlohmann::json last_scan_;  // null before the first scan
  std::mutex queue_mutex_;
  std::deque<ScanEvent> queue_;
  bool job_finished_ = false;
  std::optional<Error> job_error_;
  std::string shutdown_reason_;
  std::atomic<bool> shutdown_{false};
  EventHub hub_;
  LoopCalls loop_calls_{[this] { Wake(); }};
  std::unique_ptr<LiveView> live_;
  std::unique_ptr<WebServer> web_;  // after what it borrows (hub_, live_): stopped first
  Clock::time_point started_;
  Clock::time_point next_watchdog_;
};

Daemon::Daemon(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Daemon::~Daemon() = default;

Expected<std::unique_ptr<Daemon>> Daemon::Create(StationConfig config, DaemonHooks hooks) {
  auto impl = std::make_unique<Impl>(std::move(config), std::move(hooks));
  if (auto ok = impl->Init(); !ok) return std::unexpected(ok.error());
  return std::unique_ptr<Daemon>(new Daemon(std::move(impl)));
}

int Daemon::Run() { return impl_->Run(); }
void Daemon::RequestShutdown() { impl_->RequestShutdown(); }
const std::filesystem::path& Daemon::socket_path() const { return impl_->socket_path(); }
const std::filesystem::path& Daemon::scans_dir() const { return impl_->scans_dir(); }

}  // namespace revolve::station
