#include "station/commands/control_commands.h"

#include <ostream>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ostream.h>
#include <fmt/ranges.h>

#include "station/commands/control_client.h"
#include "station/commands/scan_command.h"
#include "station/scan_state.h"
#include "station/station_config.h"

namespace revolve::station {
namespace {

using namespace std::chrono_literals;

constexpr auto kReplyTimeout = 10s;

Expected<std::filesystem::path> SocketPath(const ClientOptions& options) {
  if (options.socket) return *options.socket;
  if (options.config) {
    auto config = LoadStationConfig(*options.config);
    if (!config) return std::unexpected(config.error());
    return std::filesystem::path(config->daemon.socket);
  }
  return DefaultControlSocket();
}

// Connects; prints the reason and returns the exit code on failure.
std::optional<ControlClient> ConnectOrReport(const ClientOptions& options, std::ostream& err,
                                             int* code) {
  auto path = SocketPath(options);
  if (!path) {
    fmt::print(err, "revolve: {}\n", path.error().message);
    *code = kExitConfig;
    return std::nullopt;
  }
  auto client = ControlClient::Connect(*path);
  if (!client) {
    fmt::print(err, "revolve: {}\n", client.error().message);
    *code = kExitUnavailable;
    return std::nullopt;
  }
  return std::move(*client);
}

// Prints an error reply; returns the exit code for it.
int ReportRefusal(const nlohmann::json& reply, std::string_view what, std::ostream& err) {
  const nlohmann::json error = reply.value("error", nlohmann::json::object());
  const std::string code = error.is_object() ? error.value("code", "") : "";
  fmt::print(err, "revolve {}: {} ({})\n", what,
             error.is_object() ? error.value("message", "refused") : "refused", code);
  // A missing device is a configuration error whatever the backend, as for `revolve scan`.
  if (code == "no_device") return kExitConfig;
  return code == "busy" ? kExitBusy : kExitFailed;
}

int ExitCodeForState(const std::string& state) {
  if (state == "failed") return kExitFailed;
  if (state == "aborted") return kExitAborted;
  return kExitOk;
}

bool IsEndState(const std::string& state) {
  return state == "done" || state == "failed" || state == "aborted" || state == "idle";
}

// Follows events on `client` (already watching) until the scan `scan_id` ("" = any) ends.
int Follow(ControlClient& client, const ClientOptions& options, const std::string& scan_id,
           bool follow, std::stop_token stop, std::ostream& out, std::ostream& err) {
  std::string last_line;
  for (;;) {
    if (stop.stop_requested()) {
      if (options.tty) fmt::print(out, "\n");
      return kExitAborted;
    }
    auto line = client.Receive(200ms);
    if (!line) {
      if (line.error().code == ErrorCode::kTimeout) continue;
      if (options.tty) fmt::print(out, "\n");
      fmt::print(err, "revolve watch: {}\n", line.error().message);
      return kExitUnavailable;
    }
    if (!line->contains("event")) continue;  // a reply
    const nlohmann::json& event = (*line)["event"];
    if (options.json) {
      fmt::print(out, "{}\n", line->dump());
    } else {
      const std::string text = FormatProgressLine(event);
      if (options.tty) {
        fmt::print(out, "\r\033[K{}", text);
      } else if (text != last_line) {
        fmt::print(out, "{}\n", text);
      }
      last_line = text;
    }
    out.flush();
    const std::string state = event.value("state", "");
    const std::string id = event.value("scan_id", "");
    if (!follow && (state == "done" || state == "failed" || state == "aborted") &&
        (scan_id.empty() || id == scan_id)) {
      if (options.tty) fmt::print(out, "\n");
      if (state != "done" && !options.json) {
        if (auto e = event.find("error"); e != event.end() && e->is_object()) {
          fmt::print(err, "revolve: scan {} {}: {}\n", id, state, e->value("message", ""));
        }
      }
      return ExitCodeForState(state);
    }
  }
}

}  // namespace

int RunStartCommand(const ClientOptions& options, const std::optional<std::string>& recipe,
                    const std::optional<std::string>& resume, bool watch, std::stop_token stop,
                    std::ostream& out, std::ostream& err) {
  int code = kExitOk;
  auto client = ConnectOrReport(options, err, &code);
  if (!client) return code;
  if (watch) {
    // Watch first, on the same connection: no event of the new scan can be missed.
    auto reply = client->Call({{"cmd", "watch"}}, kReplyTimeout);
    if (!reply) {
      fmt::print(err, "revolve start: {}\n", reply.error().message);
      return kExitUnavailable;
    }
  }
  nlohmann::json request = {{"cmd", "start"}};
  if (recipe) request["recipe"] = *recipe;
  if (resume) request["resume"] = *resume;
  if (auto sent = client->Send(request); !sent) {
    fmt::print(err, "revolve start: {}\n", sent.error().message);
    return kExitUnavailable;
  }
  // The reply is the next line that is not an event.
  for (;;) {
    auto reply = client->Receive(kReplyTimeout);
    if (!reply) {
      fmt::print(err, "revolve start: {}\n", reply.error().message);
      return kExitUnavailable;
    }
    if (reply->contains("event")) continue;
    if (options.json) fmt::print(out, "{}\n", reply->dump());
    if (!reply->value("ok", false)) return ReportRefusal(*reply, "start", err);
    const nlohmann::json scan = reply->value("scan", nlohmann::json::object());
    const std::string id = scan.value("id", "");
    if (!options.json) {
      fmt::print(out, "revolve start: scan {} (recipe {}{}) -> {}\n", id, scan.value("recipe", ""),
                 scan.value("resumed", false) ? ", resumed" : "", scan.value("dir", ""));
    }
    out.flush();
    if (!watch) return kExitOk;
    return Follow(*client, options, id, false, stop, out, err);
  }
}

int RunAbortCommand(const ClientOptions& options, std::ostream& out, std::ostream& err) {
  int code = kExitOk;
  auto client = ConnectOrReport(options, err, &code);
  if (!client) return code;
  auto reply = client->Call({{"cmd", "abort"}}, kReplyTimeout);
  if (!reply) {
    fmt::print(err, "revolve abort: {}\n", reply.error().message);
    return kExitUnavailable;
  }
  if (options.json) fmt::print(out, "{}\n", reply->dump());
  if (!reply->value("ok", false)) return ReportRefusal(*reply, "abort", err);
  if (!options.json)
    fmt::print(out, "revolve abort: scan {} stopped\n", reply->value("scan_id", ""));
  return kExitOk;
}

int RunStatusCommand(const ClientOptions& options, std::ostream& out, std::ostream& err) {
  int code = kExitOk;
  auto client = ConnectOrReport(options, err, &code);
  if (!client) return code;
  auto reply = client->Call({{"cmd", "status"}}, kReplyTimeout);
  if (!reply) {
    fmt::print(err, "revolve status: {}\n", reply.error().message);
    return kExitUnavailable;
  }
  if (!reply->value("ok", false)) return ReportRefusal(*reply, "status", err);
  const nlohmann::json status = reply->value("status", nlohmann::json::object());
  if (options.json) {
    fmt::print(out, "{}\n", status.dump(2));
  } else {
    fmt::print(out, "{}", FormatStatus(status));
  }
  return kExitOk;
}

int RunWatchCommand(const ClientOptions& options, bool follow, std::stop_token stop,
                    std::ostream& out, std::ostream& err) {
  int code = kExitOk;
  auto client = ConnectOrReport(options, err, &code);
  if (!client) return code;
  auto reply = client->Call({{"cmd", "watch"}}, kReplyTimeout);
  if (!reply) {
    fmt::print(err, "revolve watch: {}\n", reply.error().message);
    return kExitUnavailable;
  }
  if (!reply->value("ok", false)) return ReportRefusal(*reply, "watch", err);
  const nlohmann::json status = reply->value("status", nlohmann::json::object());
  const std::string state = status.value("state", "idle");
  if (options.json) {
    fmt::print(out, "{}\n", nlohmann::json{{"event", status}}.dump());
  } else {
    fmt::print(out, "{}{}", FormatProgressLine(status), options.tty ? "" : "\n");
  }
  out.flush();
  if (!follow && IsEndState(state)) {
    if (options.tty) fmt::print(out, "\n");
    return ExitCodeForState(state);
  }
  return Follow(*client, options, status.value("scan_id", ""), follow, stop, out, err);
}

int RunListCommand(const ClientOptions& options, std::ostream& out, std::ostream& err) {
  int code = kExitOk;
  auto client = ConnectOrReport(options, err, &code);
  if (!client) return code;
  auto reply = client->Call({{"cmd", "list"}}, kReplyTimeout);
  if (!reply) {
    fmt::print(err, "revolve list: {}\n", reply.error().message);
    return kExitUnavailable;
  }
  if (!reply->value("ok", false)) return ReportRefusal(*reply, "list", err);
  if (options.json) {
    fmt::print(out, "{}\n", (*reply)["scans"].dump(2));
  } else {
    fmt::print(out, "{}", FormatScanList((*reply)["scans"]));
  }
  return kExitOk;
}

namespace {

// Double-quoted strings, no indentation: reads like the examples.
constexpr toml::format_flags kTomlFlags = toml::toml_formatter::default_flags &
                                          ~toml::format_flags::allow_literal_strings &
                                          ~toml::format_flags::indentation;

toml::array Strings(const std::vector<std::string>& values) {
  toml::array a;
  for (const auto& v : values) a.push_back(v);
  return a;
}

void PutLine(toml::table& t, std::string_view key, const PanelLine& line) {
  if (!line.present()) return;
  if (line.offset >= 0) {
    t.insert_or_assign(key, static_cast<std::int64_t>(line.offset));
  } else {
    t.insert_or_assign(key, line.name);
  }
  t.insert_or_assign(std::string(key) + "_active_low", line.active_low);
}

// The document with station's own sections (and the recipe-related keys of [segment] and
// [reconstruct]) filled in with their effective values.
toml::table EffectiveTable(const StationConfig& c, const toml::table& given) {
  toml::table root = given;
  auto table = [&root](std::string_view key) -> toml::table& {
    if (!root.contains(key) || !root.get(key)->is_table())
      root.insert_or_assign(key, toml::table{});
    return *root.get_as<toml::table>(key);
  };
  toml::table& scan = table("scan");
  scan.insert_or_assign("stops", c.scan.stops);
  scan.insert_or_assign("step_deg", c.scan.step_deg);
  scan.insert_or_assign("settle_ms", c.scan.settle_ms);
  scan.insert_or_assign("move_timeout_s", c.scan.move_timeout_s);
  scan.insert_or_assign("capture_timeout_s", c.scan.capture_timeout_s);
  toml::table& station = table("station");
  station.insert_or_assign("recipe", c.station.recipe);
  station.insert_or_assign("scans_dir", c.station.scans_dir);
  station.insert_or_assign("camera_retries", c.station.camera_retries);
  station.insert_or_assign("camera_retry_delay_ms", c.station.camera_retry_delay_ms);
  station.insert_or_assign("min_free_mb", c.station.min_free_mb);
  toml::table& daemon = table("daemon");
  daemon.insert_or_assign("socket", c.daemon.socket);
  daemon.insert_or_assign("socket_mode", fmt::format("{:04o}", c.daemon.socket_mode));
  daemon.insert_or_assign("socket_group", c.daemon.socket_group);
  daemon.insert_or_assign("max_clients", c.daemon.max_clients);
  daemon.insert_or_assign("max_request_bytes", c.daemon.max_request_bytes);
  daemon.insert_or_assign("idle_timeout_s", c.daemon.idle_timeout_s);
  toml::table& web = table("web");
  web.insert_or_assign("listen", c.web.listen);
  web.insert_or_assign("token_file", c.web.token_file);
  web.insert_or_assign("max_connections", c.web.max_connections);
  web.insert_or_assign("max_request_bytes", c.web.max_request_bytes);
  web.insert_or_assign("timeout_s", c.web.timeout_s);
  toml::table& panel = table("operator");
  panel.insert_or_assign("chip", c.panel.chip);
  PutLine(panel, "start_button", c.panel.start_button);
  PutLine(panel, "abort_button", c.panel.abort_button);
  PutLine(panel, "led", c.panel.led);
  PutLine(panel, "lamp", c.panel.lamp);
  panel.insert_or_assign("bias", c.panel.bias);
  panel.insert_or_assign("debounce_ms", c.panel.debounce_ms);
  table("turntable").insert_or_assign("backend", c.turntable.backend);
  table("camera").insert_or_assign("backend", c.camera.backend);
  toml::table& segment = table("segment");
  segment.insert_or_assign("method", c.segment.method);
  segment.insert_or_assign("threshold", c.segment.threshold);
  toml::table& recon = table("reconstruct");
  recon.insert_or_assign("method", c.reconstruct.method);
  recon.insert_or_assign("resolution", c.reconstruct.resolution);
  recon.insert_or_assign("formats", Strings(c.reconstruct.formats));
  return root;
}

}  // namespace

int RunCheckConfigCommand(const std::filesystem::path& file, std::ostream& out, std::ostream& err) {
  auto document = config::LoadFile(file);
  if (!document) {
    fmt::print(err, "revolve check-config: {}\n", document.error().message);
    return kExitConfig;
  }
  auto config = ParseStationConfig(*document);
  if (!config) {
    fmt::print(err, "revolve check-config: {}\n", config.error().message);
    return kExitConfig;
  }
  std::string recipes;
  for (const std::string& name : RecipeNames(*config)) {
    auto applied = ApplyRecipe(*config, name);
    if (!applied) {
      fmt::print(err, "revolve check-config: {}\n", applied.error().message);
      return kExitConfig;
    }
    if (auto checked = CheckWithoutDevices(*applied); !checked) {
      fmt::print(err, "revolve check-config: {}{}\n", checked.error().message,
                 name == "default" ? "" : fmt::format(" (recipe \"{}\")", name));
      return kExitConfig;
    }
    recipes += fmt::format("#   {:<12} {} stops x {} deg, settle {} ms, {} {} at {}, formats {}\n",
                           name, applied->scan.stops, applied->scan.step_deg,
                           applied->scan.settle_ms, applied->segment.method,
                           applied->reconstruct.method, applied->reconstruct.resolution,
                           fmt::format("{}", fmt::join(applied->reconstruct.formats, ",")));
  }
  std::ostringstream toml_text;
  toml_text << toml::toml_formatter(EffectiveTable(*config, document->root), kTomlFlags);
  fmt::print(out,
             "# {}: valid: every check a scan makes short of opening the devices passed\n"
             "# (every key, range and recipe; the segmenter, the backends' options and the\n"
             "# calibration file). The turntable and camera themselves are not opened.\n"
             "# The effective configuration: every key of [scan], [station], [daemon] and "
             "[operator]\n"
             "# with its value (defaults filled in); the other sections as given (their "
             "defaults: docs/configuration.md).\n"
             "# Recipes (\"default\" is the base configuration):\n{}\n{}\n",
             file.string(), recipes, toml_text.str());
  return kExitOk;
}

}  // namespace revolve::station
