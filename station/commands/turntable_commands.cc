#include "station/commands/turntable_commands.h"

#include <chrono>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ostream.h>

#include "base/log.h"
#include "station/commands/scan_command.h"
#include "station/station_config.h"
#include "turntable/modbus/profile.h"
#include "turntable/modbus/profile_library.h"
#include "turntable/modbus/sim_drive.h"
#include "turntable/modbus/sim_server.h"
#include "turntable/turntable.h"

namespace revolve::station {
namespace {

using turntable::modbus::SimDriveOptions;
using turntable::modbus::SimServerOptions;

std::string StateLine(const turntable::TurntableState& s) {
  std::string line = fmt::format(
      "angle {:.3f} deg{}, {}, {}, {}, {}", s.angle_deg,
      s.open_loop ? " (counted steps, open loop)" : " (read back)", s.moving ? "moving" : "stopped",
      s.in_position ? "in position" : "not in position", s.enabled ? "enabled" : "disabled",
      s.homed ? "homed" : "not homed");
  if (s.alarm_code || !s.alarm_text.empty()) {
    line += fmt::format(", ALARM{}: {}", s.alarm_code ? fmt::format(" 0x{:X}", *s.alarm_code) : "",
                        s.alarm_text);
  }
  return line;
}

class Commands final : public TurntableCommands {
 public:
  explicit Commands(CLI::App& app) {
    // --- simulate-drive ---
    sim_ = app.add_subcommand("simulate-drive",
                              "Simulate a Modbus motor drive (any profile) on TCP or a serial "
                              "line, for tests and for trying a config without hardware");
    sim_->add_option("--profile", profile_, "Drive profile: a name (see --list) or a file")
        ->required();
    auto* tcp = sim_->add_option("--tcp", tcp_, "Serve Modbus TCP on HOST:PORT (port 0: any)");
    auto* rtu = sim_->add_option("--rtu", rtu_, "Serve Modbus RTU on this serial device / pty");
    tcp->excludes(rtu);
    rtu->excludes(tcp);
    sim_->add_option("--baud", server_.baud, "RTU baud rate")->capture_default_str();
    sim_->add_option("--parity", parity_, "RTU parity: none, even, odd")
        ->check(CLI::IsMember({"none", "even", "odd"}))
        ->capture_default_str();
    sim_->add_option("--data-bits", server_.data_bits, "RTU data bits")->capture_default_str();
    sim_->add_option("--stop-bits", server_.stop_bits, "RTU stop bits")->capture_default_str();
    sim_->add_option("--slave-id", server_.slave_id, "RTU slave id to answer")
        ->capture_default_str();
    sim_->add_option("--steps-per-rev", drive_.steps_per_rev,
                     "Counts per motor revolution (default: the profile's)");
    sim_->add_option("--speed-hz", drive_.default_speed_hz,
                     "Speed when the move command gives none, counts/s (default 1 rev/s)");
    sim_->add_option("--accel-hz-s", drive_.default_accel_hz_s,
                     "Acceleration when the move gives none, counts/s^2");
    sim_->add_option("--settle-ms", drive_.settle_ms, "Settling after each move")
        ->capture_default_str();
    sim_->add_option("--watchdog-ms", drive_.watchdog_ms,
                     "Stop a moving motor after this long without a request (0: off)")
        ->capture_default_str();
    sim_->add_option("--alarm-code", drive_.alarm_code, "Code of injected alarms")
        ->capture_default_str();
    sim_->add_option("--fault", faults_,
                     "Inject a fault: KIND@MOVE[:ARG], KIND = alarm | stall | link-drop | "
                     "no-reply | corrupt | exception (repeatable)");
    sim_->add_option("--port-file", server_.port_file,
                     "Write the TCP port actually bound to this file");

    // --- turntable ---
    table_ = app.add_subcommand("turntable", "Drive the configured turntable (rig bring-up)");
    table_->add_option("--config", config_, "Config file (TOML); default: the simulated rig");
    table_->add_option("--timeout-s", timeout_s_,
                       "Deadline of home/move (default: scan.move_timeout_s)");
    table_->require_subcommand(1);
    home_ = table_->add_subcommand("home", "Home the table (resets a latched alarm)");
    move_ = table_->add_subcommand("move", "Move to an absolute plate angle");
    move_->add_option("DEG", move_deg_, "Target angle, degrees (multi-turn, not wrapped)")
        ->required();
    status_ = table_->add_subcommand("status", "Print the drive's state");
    list_ = table_->add_subcommand("profiles", "List the drive profiles found, and where");
  }

  std::optional<int> Run(std::stop_token stop, std::ostream& out, std::ostream& err) override {
    if (sim_->parsed()) return RunSimulator(stop, out, err);
    if (table_->parsed()) return RunTurntable(stop, out, err);
    return std::nullopt;
  }

 private:
  int RunSimulator(std::stop_token stop, std::ostream& out, std::ostream& err) {
    if (tcp_.empty() == rtu_.empty()) {
      err << "revolve simulate-drive: give exactly one of --tcp HOST:PORT and --rtu DEVICE\n";
      return kExitUsage;
    }
    Expected<std::filesystem::path> path =
        turntable::modbus::FindProfile(profile_, std::filesystem::current_path());
    if (!path) {
      err << "revolve simulate-drive: " << path.error().message << "\n";
      return kExitConfig;
    }
    Expected<turntable::modbus::DriveProfile> profile = turntable::modbus::LoadProfileFile(*path);
    if (!profile) {
      err << "revolve simulate-drive: " << profile.error().message << "\n";
      return kExitConfig;
    }
    for (const std::string& spec : faults_) {
      Expected<turntable::modbus::SimFault> fault = turntable::modbus::ParseSimFault(spec);
      if (!fault) {
        err << "revolve simulate-drive: " << fault.error().message << "\n";
        return kExitUsage;
      }
      if (fault->kind == turntable::modbus::SimFault::Kind::kAlarm &&
          spec.find(':') == std::string::npos) {
        fault->code = drive_.alarm_code;
      }
      drive_.faults.push_back(*fault);
    }
    if (!tcp_.empty()) {
      const std::size_t colon = tcp_.rfind(':');
      if (colon == std::string::npos) {
        err << "revolve simulate-drive: --tcp wants HOST:PORT\n";
        return kExitUsage;
      }
      server_.transport = SimServerOptions::Transport::kTcp;
      server_.host = tcp_.substr(0, colon);
      try {
        server_.port = std::stoi(tcp_.substr(colon + 1));
      } catch (const std::exception&) {
        err << "revolve simulate-drive: bad port in --tcp " << tcp_ << "\n";
        return kExitUsage;
      }
    } else {
      server_.transport = SimServerOptions::Transport::kRtu;
      server_.device = rtu_;
      server_.parity = parity_ == "even" ? 'E' : parity_ == "odd" ? 'O' : 'N';
    }
    Expected<std::unique_ptr<turntable::modbus::SimulatedDrive>> drive =
        turntable::modbus::SimulatedDrive::Create(std::move(*profile), drive_);
    if (!drive) {
      err << "revolve simulate-drive: " << drive.error().message << "\n";
      return kExitConfig;
    }
    const std::string profile_name = (*drive)->profile().name;
    Expected<void> served =
        turntable::modbus::RunSimServer(**drive, server_, stop, [&](const std::string& ready) {
          out << fmt::format("simulate-drive: profile {} ({}), {}", profile_name, path->string(),
                             ready)
              << std::endl;
        });
    if (!served) {
      err << "revolve simulate-drive: " << served.error().message << "\n";
      return kExitFailed;
    }
    return kExitOk;
  }

  int RunTurntable(std::stop_token stop, std::ostream& out, std::ostream& err) {
    if (list_->parsed()) {
      for (const auto& dir : turntable::modbus::ProfileSearchPath()) {
        out << "search: " << dir.string() << "\n";
      }
      for (const std::string& name : turntable::modbus::ListProfiles()) {
        Expected<std::filesystem::path> path = turntable::modbus::FindProfile(name, {});
        out << name << "  " << (path ? path->string() : "") << "\n";
      }
      return kExitOk;
    }
    std::optional<std::filesystem::path> config_path;
    if (!config_.empty()) config_path = config_;
    Expected<StationConfig> config = LoadStationConfig(config_path);
    if (!config) {
      err << "revolve turntable: " << config.error().message << "\n";
      return kExitConfig;
    }
    Expected<std::unique_ptr<turntable::Turntable>> table =
        turntable::Create(config->turntable, nullptr);
    if (!table) {
      err << "revolve turntable: " << config->turntable.backend << ": " << table.error().message
          << "\n";
      return table.error().code == ErrorCode::kBadInput ||
                     table.error().code == ErrorCode::kUnsupported
                 ? kExitConfig
                 : kExitFailed;
    }
    turntable::Turntable& t = **table;
    out << t.Describe() << "\n";
    std::stop_callback stop_motor(stop, [&t] { t.Stop(); });
    const double timeout_s = timeout_s_ > 0 ? timeout_s_ : config->scan.move_timeout_s;
    const auto deadline =
        turntable::Clock::now() + std::chrono::duration_cast<turntable::Clock::duration>(
                                      std::chrono::duration<double>(timeout_s));
    Expected<void> done;
    if (home_->parsed()) {
      done = t.Home(deadline);
    } else if (move_->parsed()) {
      done = t.MoveTo(move_deg_, deadline);
    }
    Expected<turntable::TurntableState> state = t.State();
    if (state) out << StateLine(*state) << "\n";
    if (!done) {
      err << "revolve turntable: " << ToString(done.error().code) << ": " << done.error().message
          << "\n";
      return done.error().code == ErrorCode::kAborted ? kExitAborted : kExitFailed;
    }
    if (!state) {
      err << "revolve turntable: " << state.error().ToString() << "\n";
      return kExitFailed;
    }
    return kExitOk;
  }

  CLI::App* sim_ = nullptr;
  std::string profile_;
  std::string tcp_;
  std::string rtu_;
  std::string parity_ = "none";
  std::vector<std::string> faults_;
  SimDriveOptions drive_;
  SimServerOptions server_;

  CLI::App* table_ = nullptr;
  CLI::App* home_ = nullptr;
  CLI::App* move_ = nullptr;
  CLI::App* status_ = nullptr;
  CLI::App* list_ = nullptr;
  std::string config_;
  double timeout_s_ = 0.0;
  double move_deg_ = 0.0;
};

}  // namespace

std::unique_ptr<TurntableCommands> AddTurntableCommands(CLI::App& app) {
  return std::make_unique<Commands>(app);
}

}  // namespace revolve::station
