#include "station/station_config.h"

#include <algorithm>
#include <sstream>

#include <fmt/format.h>

#include "calibrate/calibration.h"
#include "capture/synthetic/synthetic_camera.h"
#include "config/reader.h"
#include "turntable/mock/mock_turntable.h"

namespace revolve::station {
namespace {

// A GPIO line: an integer offset or a line name; `<key>_active_low` next to it.
void ReadLine(config::Reader& r, std::string_view key, PanelLine& out, bool default_active_low) {
  if (!r.ok()) return;
  const config::Section& section = r.section();
  out.active_low = default_active_low;
  r.Boolean(fmt::format("{}_active_low", key), out.active_low);
  if (!r.ok() || !section.Has(key)) {
    (void)section.String(key, "");  // known, even when absent
    return;
  }
  if (Expected<std::int64_t> offset = section.Integer(key, -1, 0, 1023); offset) {
    out.offset = static_cast<int>(*offset);
    return;
  }
  Expected<std::string> name = section.String(key, "");
  if (!name || name->empty()) {
    r.Fail(section.BadValue(key, "expected a line offset 0..1023 or a line name (\"GPIO17\")"));
    return;
  }
  out.name = *name;
}

Expected<ScanOptions> ParseScanOptions(const config::Section& s) {
  ScanOptions o;
  config::Reader r(s);
  r.Integer("stops", o.stops, 1, 3600);
  r.Number("step_deg", o.step_deg, 0.01, 360.0);
  r.Number("settle_ms", o.settle_ms, 0.0, 60000.0);
  r.Number("move_timeout_s", o.move_timeout_s, 0.1, 3600.0);
  r.Number("capture_timeout_s", o.capture_timeout_s, 0.1, 600.0);
  if (r.ok() && o.stops * o.step_deg > 360.0 + 1e-9) {
    r.Fail(s.BadValue("stops",
                      "stops * step_deg exceeds one revolution (360 deg); lower one of them"));
  }
  if (auto done = r.Finish(); !done) return std::unexpected(done.error());
  return o;
}

Expected<SimulateOptions> ParseSimulateOptions(const config::Section& s) {
  SimulateOptions o;
  config::Reader r(s);
  r.String("drive_fault", o.drive_fault, {"none", "stall", "alarm", "link_down"});
  r.Integer("drive_fault_move", o.drive_fault_move, 0, 1000000);
  r.Integer("drive_fault_count", o.drive_fault_count, 1, 1000000);
  r.Number("drive_fault_at", o.drive_fault_at, 0.0, 1.0);
  r.Integer("drive_alarm_code", o.drive_alarm_code, 0, 65535);
  r.Integer("camera_fail_after", o.camera_fail_after, -1, 1000000000);
  r.Integer("camera_fail_count", o.camera_fail_count, 1, 1000000000);
  r.String("camera_glitch", o.camera_glitch, {"none", "blank", "overexposed", "blurred"});
  r.Integer("camera_glitch_after", o.camera_glitch_after, 0, 1000000000);
  r.Integer("camera_glitch_count", o.camera_glitch_count, 1, 1000000000);
  r.Integer("disk_limit_bytes", o.disk_limit_bytes, 0, 1'000'000'000'000);
  if (auto done = r.Finish(); !done) return std::unexpected(done.error());
  return o;
}

Expected<StationOptions> ParseStationOptions(const config::Section& s) {
  StationOptions o;
  config::Reader r(s);
  r.String("recipe", o.recipe);
  r.String("scans_dir", o.scans_dir);
  if (r.ok() && o.scans_dir.empty()) r.Fail(s.BadValue("scans_dir", "must not be empty"));
  r.Integer("camera_retries", o.camera_retries, 0, 20);
  r.Number("camera_retry_delay_ms", o.camera_retry_delay_ms, 0.0, 60000.0);
  r.Number("min_free_mb", o.min_free_mb, 0.0, 1e7);
  if (r.ok()) {
    Expected<config::Section> simulate = s.Child("simulate");
    if (!simulate) return std::unexpected(simulate.error());
    Expected<SimulateOptions> parsed = ParseSimulateOptions(*simulate);
    if (!parsed) return std::unexpected(parsed.error());
    o.simulate = std::move(*parsed);
  }
  if (auto done = r.Finish(); !done) return std::unexpected(done.error());
  return o;
}

Expected<DaemonOptions> ParseDaemonOptions(const config::Section& s) {
  DaemonOptions o;
  config::Reader r(s);
  r.String("socket", o.socket);
  if (r.ok() && o.socket.empty()) r.Fail(s.BadValue("socket", "must not be empty"));
  if (r.ok() && o.socket.size() >= 108) {
    r.Fail(s.BadValue("socket", "is longer than a Unix socket path may be (107 bytes)"));
  }
  if (r.ok() && s.Has("socket_mode")) {
    // "0660" (a string, octal) or 0o660 (a TOML octal integer).
    if (Expected<std::int64_t> mode = s.Integer("socket_mode", o.socket_mode, 0, 0777); mode) {
      o.socket_mode = static_cast<int>(*mode);
    } else {
      std::string text;
      r.String("socket_mode", text);
      if (r.ok()) {
        const bool octal =
            !text.empty() && text.size() <= 4 &&
            std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '7'; });
        if (!octal) {
          r.Fail(s.BadValue("socket_mode", "expected an octal mode such as \"0660\""));
        } else {
          o.socket_mode = static_cast<int>(std::stoi(text, nullptr, 8));
        }
      }
    }
  }
  r.String("socket_group", o.socket_group);
  r.Integer("max_clients", o.max_clients, 1, 1024);
  r.Integer("max_request_bytes", o.max_request_bytes, 64, 1 << 20);
  r.Number("idle_timeout_s", o.idle_timeout_s, 1.0, 86400.0);
  if (auto done = r.Finish(); !done) return std::unexpected(done.error());
  return o;
}

Expected<WebOptions> ParseWebOptions(const config::Section& s) {
  WebOptions o;
  config::Reader r(s);
  r.String("listen", o.listen);
  r.Path("token_file", o.token_file);
  r.Integer("max_connections", o.max_connections, 1, 1024);
  r.Integer("max_request_bytes", o.max_request_bytes, 1024, 16 << 20);
  r.Number("timeout_s", o.timeout_s, 0.5, 300.0);
  if (r.ok() && !o.listen.empty()) {
    auto address = ParseListenAddress(o.listen);
    if (!address) {
      r.Fail(s.BadValue("listen", address.error().message));
    } else if (!address->loopback && o.token_file.empty()) {
      r.Fail(s.BadValue(
          "listen", fmt::format("\"{}\" is reachable from other machines, so the console needs a "
                                "token: set web.token_file (a file holding one line, e.g. from "
                                "`head -c 24 /dev/urandom | base64`), or listen on 127.0.0.1",
                                o.listen)));
    }
  }
  if (auto done = r.Finish(); !done) return std::unexpected(done.error());
  return o;
}

Expected<OperatorOptions> ParseOperatorOptions(const config::Section& s) {
  OperatorOptions o;
  config::Reader r(s);
  r.String("chip", o.chip);
  ReadLine(r, "start_button", o.start_button, true);
  ReadLine(r, "abort_button", o.abort_button, true);
  ReadLine(r, "led", o.led, false);
  ReadLine(r, "lamp", o.lamp, false);
  r.String("bias", o.bias, {"pull_up", "pull_down", "disable", "as_is"});
  r.Number("debounce_ms", o.debounce_ms, 0.0, 1000.0);
  if (auto done = r.Finish(); !done) return std::unexpected(done.error());
  return o;
}

Expected<Recipe> ParseRecipe(const config::Section& s, std::string name) {
  Recipe o;
  o.name = std::move(name);
  config::Reader r(s);
  r.Optional("stops", o.stops, [&](std::string_view k, int& v) { r.Integer(k, v, 1, 3600); });
  r.Optional("step_deg", o.step_deg,
             [&](std::string_view k, double& v) { r.Number(k, v, 0.01, 360.0); });
  r.Optional("settle_ms", o.settle_ms,
             [&](std::string_view k, double& v) { r.Number(k, v, 0.0, 60000.0); });
  r.Optional("exposure_us", o.exposure_us,
             [&](std::string_view k, double& v) { r.Number(k, v, 1.0, 1e7); });
  r.Optional("segment", o.segment, [&](std::string_view k, std::string& v) { r.String(k, v); });
  r.Optional("threshold", o.threshold,
             [&](std::string_view k, int& v) { r.Integer(k, v, 0, 255); });
  r.Optional("method", o.method, [&](std::string_view k, std::string& v) { r.String(k, v); });
  r.Optional("resolution", o.resolution,
             [&](std::string_view k, int& v) { r.Integer(k, v, 16, 1024); });
  r.Optional("formats", o.formats,
             [&](std::string_view k, std::vector<std::string>& v) { r.Strings(k, v); });
  if (auto done = r.Finish(); !done) return std::unexpected(done.error());
  return o;
}

Expected<std::map<std::string, Recipe, std::less<>>> ParseRecipes(const config::Section& s,
                                                                  const config::Document& doc) {
  std::map<std::string, Recipe, std::less<>> recipes;
  const toml::node* node = doc.root.get("recipes");
  if (node == nullptr) return recipes;
  const toml::table* table = node->as_table();
  if (table == nullptr) {
    return std::unexpected(config::Section::Root(doc).BadValue("recipes", "expected a table"));
  }
  for (auto&& [key, value] : *table) {
    const std::string name(key.str());
    Expected<config::Section> child = s.Child(name);
    if (!child) {
      return std::unexpected(s.BadValue(
          name, "expected a table of recipe keys ([recipes." + name + "] with stops = ...)"));
    }
    Expected<Recipe> recipe = ParseRecipe(*child, name);
    if (!recipe) return std::unexpected(recipe.error());
    recipes.emplace(name, std::move(*recipe));
  }
  return recipes;
}

// Checks the [station.simulate] faults against the configured backends.
Expected<void> CheckSimulate(const StationConfig& cfg, const config::Section& root) {
  const SimulateOptions& sim = cfg.station.simulate;
  if (!sim.Any()) return {};
  auto station = root.Child("station");
  auto simulate = station ? station->Child("simulate") : station;
  if (!simulate) return std::unexpected(simulate.error());
  if (sim.drive_fault != "none" && cfg.turntable.backend != "mock") {
    return std::unexpected(simulate->BadValue(
        "drive_fault", "drive faults can only be simulated with [turntable] backend = \"mock\""));
  }
  if (sim.camera_fail_after >= 0 && cfg.camera.backend != "synthetic" &&
      cfg.camera.backend != "replay") {
    return std::unexpected(simulate->BadValue(
        "camera_fail_after",
        "camera loss can only be simulated with the synthetic or replay camera"));
  }
  if (sim.camera_glitch != "none" && cfg.camera.backend != "synthetic" &&
      cfg.camera.backend != "replay") {
    return std::unexpected(simulate->BadValue(
        "camera_glitch", "bad frames can only be simulated with the synthetic or replay camera"));
  }
  return {};
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

// The table at `path` under `root`, created when missing. Error when a key on the way is not a
// table.
toml::table* EnsureTable(toml::table& root, std::initializer_list<std::string_view> path) {
  toml::table* table = &root;
  for (std::string_view key : path) {
    toml::node* node = table->get(key);
    if (node == nullptr) {
      table = table->insert_or_assign(key, toml::table{}).first->second.as_table();
    } else {
      table = node->as_table();
      if (table == nullptr) return nullptr;
    }
  }
  return table;
}

}  // namespace

Expected<StationConfig> ParseStationConfig(const config::Document& document) {
  StationConfig cfg;
  cfg.origin = document.origin;
  cfg.text = document.text;
  const config::Section root = config::Section::Root(document);

  // Parses root.<key> with `parse` into `out`. (g++ 12's std::expected has no and_then.)
  auto section = [&root](std::string_view key, auto parse, auto& out) -> Expected<void> {
    auto child = root.Child(key);
    if (!child) return std::unexpected(child.error());
    auto parsed = parse(*child);
    if (!parsed) return std::unexpected(parsed.error());
    out = std::move(*parsed);
    return {};
  };
  for (auto parsed :
       {section("scan", ParseScanOptions, cfg.scan),
        section("station", ParseStationOptions, cfg.station),
        section("daemon", ParseDaemonOptions, cfg.daemon), section("web", ParseWebOptions, cfg.web),
        section("operator", ParseOperatorOptions, cfg.panel),
        section("turntable", turntable::ParseOptions, cfg.turntable),
        section("camera", capture::ParseOptions, cfg.camera),
        section("segment", capture::ParseSegmentOptions, cfg.segment),
        section("quality", capture::ParseQualityOptions, cfg.quality),
        section("reconstruct", reconstruct::ParseOptions, cfg.reconstruct),
        section("calibration", calibrate::ParseCalibrationOptions, cfg.calibration)}) {
    if (!parsed) return std::unexpected(parsed.error());
  }
  Expected<config::Section> recipes_section = root.Child("recipes");
  if (!recipes_section) return std::unexpected(recipes_section.error());
  auto recipes = ParseRecipes(*recipes_section, document);
  if (!recipes) return std::unexpected(recipes.error());
  cfg.recipes = std::move(*recipes);
  if (cfg.station.recipe != "default" && !cfg.recipes.contains(cfg.station.recipe)) {
    auto station = root.Child("station");
    return std::unexpected(station->BadValue(
        "recipe", fmt::format("names no recipe (known: {})", JoinNames(RecipeNames(cfg)))));
  }
  if (auto sim = CheckSimulate(cfg, root); !sim) return std::unexpected(sim.error());
  if (auto unknown = root.CheckNoUnknownKeys(); !unknown) return std::unexpected(unknown.error());
  return cfg;
}

Expected<ListenAddress> ParseListenAddress(std::string_view listen) {
  ListenAddress a;
  std::string_view host;
  std::string_view port;
  if (!listen.empty() && listen.front() == '[') {
    const auto close = listen.find(']');
    if (close == std::string_view::npos || close + 1 >= listen.size() || listen[close + 1] != ':') {
      return MakeError(ErrorCode::kBadInput, "expected \"[ipv6]:port\"");
    }
    host = listen.substr(1, close - 1);
    port = listen.substr(close + 2);
  } else {
    const auto colon = listen.rfind(':');
    if (colon == std::string_view::npos || listen.find(':') != colon) {
      return MakeError(
          ErrorCode::kBadInput,
          "expected \"host:port\" (\"127.0.0.1:8080\", \"[::1]:8080\"), or \"\" for no server");
    }
    host = listen.substr(0, colon);
    port = listen.substr(colon + 1);
  }
  if (host.empty())
    return MakeError(ErrorCode::kBadInput,
                     "the host is missing (\"0.0.0.0:8080\" for every address)");
  const bool digits =
      !port.empty() && port.size() <= 5 &&
      std::all_of(port.begin(), port.end(), [](char c) { return c >= '0' && c <= '9'; });
  if (!digits || std::stoi(std::string(port)) > 65535) {
    return MakeError(ErrorCode::kBadInput, fmt::format("\"{}\" is not a port (0..65535)", port));
  }
  a.host = std::string(host);
  a.port = std::stoi(std::string(port));
  a.loopback = host == "localhost" || host == "::1" || host.starts_with("127.");
  return a;
}

Expected<StationConfig> LoadStationConfig(const std::optional<std::filesystem::path>& path) {
  auto document = path ? config::LoadFile(*path)
                       : config::Parse(std::string(config::EmbeddedDefault()),
                                       std::string(config::kEmbeddedOrigin));
  if (!document) return std::unexpected(document.error());
  return ParseStationConfig(*document);
}

std::vector<std::string> RecipeNames(const StationConfig& config) {
  std::vector<std::string> names = {"default"};
  for (const auto& [name, recipe] : config.recipes) {
    if (name != "default") names.push_back(name);
  }
  return names;
}

Expected<StationConfig> ApplyRecipe(const StationConfig& base, std::string_view name) {
  if (name.empty()) name = base.station.recipe;
  if (!base.recipes.contains(name)) {
    if (name == "default") {
      StationConfig cfg = base;
      cfg.recipe = "default";
      return cfg;
    }
    return MakeError(ErrorCode::kNotFound, fmt::format("no recipe \"{}\" in {} (known: {})", name,
                                                       base.origin, JoinNames(RecipeNames(base))));
  }
  // Re-parse the text so that the moved nodes keep their file positions for errors.
  Expected<config::Document> document = config::Parse(base.text, base.origin);
  if (!document) return std::unexpected(document.error());
  toml::table& root = document->root;
  toml::table* recipe = root.get("recipes")->as_table()->get(name)->as_table();
  const std::string& backend = base.camera.backend;
  for (auto&& [key, node] : *recipe) {
    const std::string_view k = key.str();
    toml::table* target = nullptr;
    std::string_view target_key = k;
    if (k == "stops" || k == "step_deg" || k == "settle_ms") {
      target = EnsureTable(root, {"scan"});
    } else if (k == "exposure_us") {
      if (backend != "v4l2" && backend != "libcamera") {
        return std::unexpected(
            config::Section(*document, fmt::format("recipes.{}", name), recipe)
                .BadValue(k, fmt::format("the {} camera has no exposure control (v4l2 and "
                                         "libcamera have)",
                                         backend)));
      }
      target = EnsureTable(root, {"camera", backend});
    } else if (k == "segment" || k == "threshold") {
      target = EnsureTable(root, {"segment"});
      if (k == "segment") target_key = "method";
    } else if (k == "method" || k == "resolution" || k == "formats") {
      target = EnsureTable(root, {"reconstruct"});
    }
    if (target == nullptr) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("{}: recipe \"{}\": cannot apply key \"{}\"", base.origin, name, k));
    }
    target->insert_or_assign(target_key, std::move(node));
  }
  root.erase("recipes");
  if (toml::table* station = root.get_as<toml::table>("station")) station->erase("recipe");

  std::ostringstream text;
  text << "# revolve: the effective configuration of a scan: recipe \"" << name << "\" of "
       << base.origin << "\n"
       << toml::toml_formatter(root, toml::toml_formatter::default_flags &
                                         ~toml::format_flags::allow_literal_strings &
                                         ~toml::format_flags::indentation)
       << "\n";
  // Parse the merged tree itself (with the recipe's positions) to validate it...
  Expected<StationConfig> merged = ParseStationConfig(*document);
  if (!merged) {
    Error e = merged.error();
    e.message += fmt::format(" (with recipe \"{}\")", name);
    return std::unexpected(e);
  }
  // ...and keep the serialized text, which `revolve scan --config scan.toml` reproduces.
  merged->text = text.str();
  merged->recipe = std::string(name);
  merged->recipes = base.recipes;
  merged->station.recipe = base.station.recipe;
  return merged;
}

Expected<void> CheckWithoutDevices(const StationConfig& config) {
  const auto in_config = [&config](const Error& error) {
    return Error{error.code, fmt::format("{}: {}", config.origin, error.message)};
  };
  if (auto segmenter = capture::CreateSegmenter(config.segment); !segmenter) {
    return std::unexpected(in_config(segmenter.error()));
  }
  if (config.turntable.backend == "mock") {
    if (auto valid = turntable::ValidateMockOptions(config.turntable.mock); !valid) {
      return std::unexpected(in_config(valid.error()));
    }
  }
  if (config.camera.backend == "synthetic") {
    if (auto valid = capture::ValidateSyntheticOptions(config.camera.synthetic); !valid) {
      return std::unexpected(in_config(valid.error()));
    }
  }
  if (!config.calibration.file.empty()) {
    auto calibration = calibrate::LoadCalibration(config.calibration.file);
    if (!calibration) return std::unexpected(calibration.error());
    if (auto rig = calibration->ToRig(); !rig) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("{}: {} (calibration.file in {}: a lens-only calibration; run "
                      "`revolve calibrate axis` with the board on the plate)",
                      config.calibration.file.string(), rig.error().message, config.origin));
    }
  }
  return {};
}

}  // namespace revolve::station
