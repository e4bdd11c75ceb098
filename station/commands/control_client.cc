#include "station/commands/control_client.h"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include <fmt/format.h>

namespace revolve::station {

std::filesystem::path DefaultControlSocket() {
  if (const char* env = std::getenv("REVOLVE_SOCKET"); env != nullptr && *env != '\0') return env;
  return "/run/revolve/control.sock";
}

Expected<ControlClient> ControlClient::Connect(const std::filesystem::path& socket) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string p = socket.string();
  if (p.size() >= sizeof(addr.sun_path)) {
    return MakeError(ErrorCode::kBadInput, fmt::format("{}: socket path too long", p));
  }
  std::memcpy(addr.sun_path, p.c_str(), p.size() + 1);
  UniqueFd fd(::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0));
  if (!fd.valid()) {
    return MakeError(ErrorCode::kIo, fmt::format("socket: {}", std::strerror(errno)));
  }
  if (::connect(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    const int err = errno;
    std::string hint = " (is revolved running? `systemctl status revolved`)";
    if (err == EACCES) hint = " (permission: join the socket's group, see [daemon] socket_group)";
    return MakeError(ErrorCode::kLinkDown, fmt::format("cannot connect to revolved at {}: {}{}", p,
                                                       std::strerror(err), hint));
  }
  return ControlClient(std::move(fd));
}

Expected<void> ControlClient::SendRaw(std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::send(fd_.get(), bytes.data(), bytes.size(), MSG_NOSIGNAL);
    if (n < 0) {
      if (errno == EINTR) continue;
      return MakeError(ErrorCode::kLinkDown,
                       fmt::format("sending to revolved: {}", std::strerror(errno)));
    }
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
  return {};
}

Expected<void> ControlClient::Send(const nlohmann::json& request) {
  return SendRaw(request.dump() + "\n");
}

Expected<nlohmann::json> ControlClient::Receive(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    if (const std::size_t nl = buffer_.find('\n'); nl != std::string::npos) {
      const std::string line = buffer_.substr(0, nl);
      buffer_.erase(0, nl + 1);
      nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
      if (j.is_discarded()) {
        return MakeError(ErrorCode::kProtocol, "revolved sent a line that is not JSON");
      }
      return j;
    }
    const auto left =
        std::chrono::ceil<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      return MakeError(ErrorCode::kTimeout,
                       fmt::format("no answer from revolved within {} ms", timeout.count()));
    }
    pollfd p{fd_.get(), POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(left.count()));
    if (ready < 0 && errno != EINTR) {
      return MakeError(ErrorCode::kIo, fmt::format("poll: {}", std::strerror(errno)));
    }
    if (ready <= 0) continue;
    char buf[8192];
    const ssize_t n = ::recv(fd_.get(), buf, sizeof(buf), 0);
    if (n == 0) return MakeError(ErrorCode::kLinkDown, "revolved closed the connection");
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      return MakeError(ErrorCode::kLinkDown,
                       fmt::format("reading from revolved: {}", std::strerror(errno)));
    }
    buffer_.append(buf, static_cast<std::size_t>(n));
  }
}

Expected<nlohmann::json> ControlClient::Call(const nlohmann::json& request,
                                             std::chrono::milliseconds timeout) {
  if (auto sent = Send(request); !sent) return std::unexpected(sent.error());
  return Receive(timeout);
}

std::string ProgressBar(double progress, int width) {
  if (!(progress >= 0.0)) progress = 0.0;
  progress = std::min(progress, 1.0);
  const int filled = static_cast<int>(std::lround(progress * width));
  return "[" + std::string(static_cast<std::size_t>(filled), '#') +
         std::string(static_cast<std::size_t>(width - filled), '-') + "]";
}

std::string FormatEta(double seconds) {
  if (!(seconds >= 0.0) || !std::isfinite(seconds)) return "--";
  const long s = std::lround(seconds);
  if (s < 60) return fmt::format("{} s", s);
  if (s < 3600) return fmt::format("{}:{:02d}", s / 60, s % 60);
  return fmt::format("{}:{:02d}:{:02d}", s / 3600, (s / 60) % 60, s % 60);
}

namespace {

double Number(const nlohmann::json& j, const char* key, double fallback) {
  auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>() : fallback;
}

std::string Text(const nlohmann::json& j, const char* key) {
  auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}

}  // namespace

std::string FormatProgressLine(const nlohmann::json& e) {
  const std::string state = Text(e, "state");
  const int stop = static_cast<int>(Number(e, "stop", -1));
  const int stops = static_cast<int>(Number(e, "stops", 0));
  const int done = static_cast<int>(Number(e, "stops_done", 0));
  std::string where = stop >= 0 ? fmt::format("stop {}/{}", stop + 1, stops)
                                : fmt::format("{}/{} stops", done, stops);
  std::string line =
      fmt::format("{:<11} {:<13} {} {:3.0f}%", state, where,
                  ProgressBar(Number(e, "progress", 0.0), 24), 100.0 * Number(e, "progress", 0.0));
  if (state != "idle" && state != "done" && state != "failed" && state != "aborted") {
    line += "  ETA " + FormatEta(Number(e, "eta_s", -1.0));
  }
  if (const std::string id = Text(e, "scan_id"); !id.empty()) line += "  scan " + id;
  if (const std::string note = Text(e, "note"); !note.empty()) line += "  - " + note;
  if (auto alarm = e.find("alarm"); alarm != e.end() && alarm->is_object()) {
    line += fmt::format("  [drive alarm {}: {}]", alarm->value("code", 0),
                        alarm->value("text", std::string()));
  }
  return line;
}

std::string FormatStatus(const nlohmann::json& s) {
  std::string out;
  const std::string state = Text(s, "state");
  out += fmt::format("state     {}\n", state);
  if (auto scan = s.find("scan"); scan != s.end() && scan->is_object()) {
    out += fmt::format("scan      {} (recipe {}{})\n          {}\n", scan->value("id", ""),
                       scan->value("recipe", ""), scan->value("resumed", false) ? ", resumed" : "",
                       scan->value("dir", ""));
  }
  if (state != "idle") {
    const int stop = static_cast<int>(Number(s, "stop", -1));
    const int stops = static_cast<int>(Number(s, "stops", 0));
    out +=
        fmt::format("progress  {} {:3.0f}%  {}/{} stops saved{}{}\n",
                    ProgressBar(Number(s, "progress", 0.0), 30), 100.0 * Number(s, "progress", 0.0),
                    static_cast<int>(Number(s, "stops_done", 0)), stops,
                    stop >= 0 ? fmt::format(", at stop {}", stop + 1) : "",
                    (state == "done" || state == "failed" || state == "aborted")
                        ? ""
                        : ", ETA " + FormatEta(Number(s, "eta_s", -1.0)));
  }
  if (auto error = s.find("error"); error != s.end() && error->is_object()) {
    out += fmt::format("error     {}: {}\n", error->value("code", ""), error->value("message", ""));
  }
  if (auto alarm = s.find("alarm"); alarm != s.end() && alarm->is_object()) {
    out += fmt::format("alarm     drive alarm {} ({:#x}): {}\n", alarm->value("code", 0),
                       alarm->value("code", 0), alarm->value("text", ""));
  }
  if (auto devices = s.find("devices"); devices != s.end() && devices->is_object()) {
    out += fmt::format("devices   {}{}\n", devices->value("ok", false) ? "ok: " : "NOT UP: ",
                       devices->value("ok", false) ? devices->value("description", "")
                                                   : devices->value("error", ""));
  }
  if (auto led = s.find("led"); led != s.end() && led->is_string()) {
    out += fmt::format("led       {}\n", led->get<std::string>());
  }
  if (auto daemon = s.find("daemon"); daemon != s.end() && daemon->is_object()) {
    out += fmt::format("daemon    pid {}, version {}, up {}, scans in {}\n",
                       daemon->value("pid", 0), daemon->value("version", ""),
                       FormatEta(daemon->value("uptime_s", 0.0)), daemon->value("scans_dir", ""));
    if (auto web = daemon->find("web"); web != daemon->end() && web->is_string()) {
      out += fmt::format("web       {}\n", web->get<std::string>());
    }
  }
  return out;
}

std::string FormatScanList(const nlohmann::json& scans) {
  std::string out = fmt::format("{:<22} {:<12} {:<10} {:>9}  {}\n", "ID", "STATE", "RECIPE",
                                "STOPS", "MODEL / ERROR");
  if (!scans.is_array()) return out;
  for (const nlohmann::json& s : scans) {
    std::string detail;
    if (auto model = s.find("model"); model != s.end() && model->is_array()) {
      for (const auto& f : *model) {
        if (f.is_string()) detail += (detail.empty() ? "" : ", ") + f.get<std::string>();
      }
    }
    if (detail.empty()) detail = s.value("error", "");
    out += fmt::format("{:<22} {:<12} {:<10} {:>4}/{:<4}  {}\n", s.value("id", ""),
                       s.value("state", ""), s.value("recipe", ""), s.value("stops_done", 0),
                       s.value("stops_planned", 0), detail);
  }
  return out;
}

}  // namespace revolve::station
