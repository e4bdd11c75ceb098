// revolved: the station daemon (systemd runs it). Thin: parses arguments, loads the config and
// runs station::Daemon.
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <optional>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "station/apps/guarded_main.h"
#include "station/daemon.h"
#include "station/exit_codes.h"
#include "station/station_config.h"

namespace {

int Main(int argc, char** argv) {
  namespace station = revolve::station;
  CLI::App app{"revolved: the revolve turntable capture station daemon"};
  std::optional<std::filesystem::path> config_path;
  app.add_option("--config", config_path,
                 "Config file (TOML); default: the embedded simulated rig");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : station::kExitUsage;
  }

  // Signals are taken by the daemon's signalfd: block them before any thread starts.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  // A configuration error exits with EX_CONFIG (78): the unit's RestartPreventExitStatus=78
  // keeps systemd from restarting into the same error.
  auto config = station::LoadStationConfig(config_path);
  if (!config) {
    fmt::print(stderr, "revolved: {}\n", config.error().message);
    return station::kExitConfig;
  }
  for (const std::string& recipe : station::RecipeNames(*config)) {
    if (auto applied = station::ApplyRecipe(*config, recipe); !applied) {
      fmt::print(stderr, "revolved: {}\n", applied.error().message);
      return station::kExitConfig;
    }
  }
  station::DaemonHooks hooks;
  hooks.handle_signals = true;
  auto daemon = station::Daemon::Create(std::move(*config), std::move(hooks));
  if (!daemon) {
    fmt::print(stderr, "revolved: {}\n", daemon.error().message);
    return daemon.error().code == revolve::ErrorCode::kBadInput ? station::kExitConfig
                                                                : station::kExitFailed;
  }
  return (*daemon)->Run();
}

}  // namespace

int main(int argc, char** argv) {
  return revolve::station::GuardedMain("revolved", Main, argc, argv);
}
