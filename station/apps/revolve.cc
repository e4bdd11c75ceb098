// revolve: the command-line front end. Thin: parses arguments and calls the station library.
#include <iostream>

#include <CLI/CLI.hpp>

#include "station/apps/guarded_main.h"
#include "station/commands/calibrate_commands.h"
#include "station/commands/camera_commands.h"
#include "station/commands/export_command.h"
#include "station/commands/scan_command.h"
#include "station/commands/station_commands.h"
#include "station/commands/turntable_commands.h"
#include "station/signal_stop.h"

namespace {

int Main(int argc, char** argv) {
  CLI::App app{"revolve: turntable 3D capture station"};
  app.require_subcommand(1);

  revolve::station::ScanCommandOptions scan_options;
  CLI::App* scan = app.add_subcommand("scan", "Run one scan on the configured rig");
  scan->add_option("--config", scan_options.config,
                   "Config file (TOML); default: the embedded simulated rig");
  scan->add_option("--out", scan_options.out,
                   "Scan folder to create (must not exist or be empty); default: scans/<id>");

  auto turntable_commands = revolve::station::AddTurntableCommands(app);
  auto station_commands = revolve::station::AddStationCommands(app);
  scan->add_option("--recipe", scan_options.recipe,
                   "Recipe of the config (default: [station] recipe)");
  auto camera_commands = revolve::station::AddCameraCommands(app);

  revolve::station::ExportOptions export_options;
  CLI::App* export_command = app.add_subcommand(
      "export", "Write a scan as a COLMAP text workspace or a nerfstudio transforms.json");
  export_command->add_option("SCAN_DIR", export_options.scan_dir, "The scan folder")->required();
  export_command
      ->add_option("--format", export_options.format,
                   "colmap (images/, masks/, sparse/0/*.txt) or nerfstudio (transforms.json)")
      ->capture_default_str();
  export_command->add_option("--out", export_options.out, "The folder to write")->required();
  auto calibrate_commands = revolve::station::AddCalibrateCommands(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : revolve::station::kExitUsage;
  }

  revolve::station::SignalStop signals;
  if (auto code = turntable_commands->Run(signals.token(), std::cout, std::cerr)) return *code;
  if (auto code = station_commands->Run(signals.token(), std::cout, std::cerr)) return *code;
  if (auto code = camera_commands->Run(signals.token(), std::cout, std::cerr)) return *code;
  if (auto code = calibrate_commands->Run(signals.token(), std::cin, std::cout, std::cerr)) {
    return *code;
  }
  if (export_command->parsed()) {
    return revolve::station::RunExportCommand(export_options, std::cout, std::cerr);
  }
  if (scan->parsed()) {
    return revolve::station::RunScanCommand(scan_options, signals.token(), std::cout, std::cerr);
  }
  return revolve::station::kExitUsage;
}

}  // namespace

int main(int argc, char** argv) {
  return revolve::station::GuardedMain("revolve", Main, argc, argv);
}
