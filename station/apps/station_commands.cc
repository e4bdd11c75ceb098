#include "station/apps/station_commands.h"

#include <unistd.h>

#include "station/control_commands.h"
#include "station/reconstruct_command.h"

namespace revolve::station {
namespace {

class StationCommandsImpl final : public StationCommands {
 public:
  explicit StationCommandsImpl(CLI::App& app) {
    auto client_options = [this](CLI::App* cmd) {
      cmd->add_option("--socket", client_.socket,
                      "revolved's control socket (default: $REVOLVE_SOCKET, else "
                      "/run/revolve/control.sock)");
      cmd->add_option("--config", client_.config, "Take the socket from this revolved config");
      cmd->add_flag("--json", client_.json, "Print the daemon's JSON");
    };
    start_ = app.add_subcommand("start", "Start a scan on revolved");
    client_options(start_);
    start_->add_option("--recipe", recipe_, "Recipe name (default: [station] recipe)");
    start_->add_option("--resume", resume_, "Finish the interrupted scan ID (see `revolve list`)");
    start_->add_flag("--watch,-w", watch_, "Follow the scan to its end; exit code by its result");
    abort_ = app.add_subcommand("abort", "Abort revolved's running scan");
    client_options(abort_);
    status_ = app.add_subcommand("status", "Show revolved's state");
    client_options(status_);
    watch_cmd_ = app.add_subcommand("watch", "Follow revolved's scan: state, stop, progress, ETA");
    client_options(watch_cmd_);
    watch_cmd_->add_flag("--follow,-f", follow_, "Keep watching after the scan ends");
    list_ = app.add_subcommand("list", "List the scans in revolved's scans folder");
    client_options(list_);

    reconstruct_ = app.add_subcommand("reconstruct",
                                      "Rebuild the model of a scan folder from the stops it holds");
    reconstruct_->add_option("SCAN_DIR", recon_.scan_dir, "The scan folder");
    reconstruct_->add_option("--out", recon_.out, "Model folder (default: SCAN_DIR/model)");
    reconstruct_->add_option("--method", recon_.method, "hull (default: the scan's)");
    reconstruct_->add_option("--resolution", recon_.resolution,
                             "Voxels along the longest side, 16..1024 (default: the scan's)");
    reconstruct_->add_option("--formats", formats_, "Model formats, e.g. ply,wrl")->delimiter(',');

    check_ = app.add_subcommand("check-config", "Validate a config and print the effective one");
    check_->add_option("FILE", check_file_, "The config file")->required();
  }

  std::optional<int> Run(std::stop_token stop, std::ostream& out, std::ostream& err) override {
    client_.tty = ::isatty(STDOUT_FILENO) == 1 && !client_.json;
    if (start_->parsed()) {
      return RunStartCommand(client_, recipe_, resume_, watch_, stop, out, err);
    }
    if (abort_->parsed()) return RunAbortCommand(client_, out, err);
    if (status_->parsed()) return RunStatusCommand(client_, out, err);
    if (watch_cmd_->parsed()) return RunWatchCommand(client_, follow_, stop, out, err);
    if (list_->parsed()) return RunListCommand(client_, out, err);
    if (reconstruct_->parsed()) {
      if (recon_.scan_dir.empty()) {
        err << "revolve reconstruct: give the scan folder (SCAN_DIR)\n";
        return 2;
      }
      if (!formats_.empty()) recon_.formats = formats_;
      return RunReconstructCommand(recon_, stop, out, err);
    }
    if (check_->parsed()) return RunCheckConfigCommand(check_file_, out, err);
    return std::nullopt;
  }

 private:
  ClientOptions client_;
  std::optional<std::string> recipe_;
  std::optional<std::string> resume_;
  bool watch_ = false;
  bool follow_ = false;
  ReconstructCommandOptions recon_;
  std::vector<std::string> formats_;
  std::filesystem::path check_file_;
  CLI::App* start_ = nullptr;
  CLI::App* abort_ = nullptr;
  CLI::App* status_ = nullptr;
  CLI::App* watch_cmd_ = nullptr;
  CLI::App* list_ = nullptr;
  CLI::App* reconstruct_ = nullptr;
  CLI::App* check_ = nullptr;
};

}  // namespace

std::unique_ptr<StationCommands> AddStationCommands(CLI::App& app) {
  return std::make_unique<StationCommandsImpl>(app);
}

}  // namespace revolve::station
