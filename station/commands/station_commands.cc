#include "station/commands/station_commands.h"

#include <unistd.h>

#include "station/commands/config_reference.h"
#include "station/commands/control_commands.h"
#include "station/commands/reconstruct_command.h"
#include "station/commands/reconstruct_images_command.h"
#include "station/commands/scan_command.h"

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

    reconstruct_ = app.add_subcommand(
        "reconstruct",
        "Rebuild the model of a scan folder from the stops it holds, or make one from a folder "
        "of images (--images)");
    reconstruct_->add_option("SCAN_DIR", recon_.scan_dir, "The scan folder");
    reconstruct_->add_option("--out", out_,
                             "Output folder (default: SCAN_DIR/model; required with --images)");
    reconstruct_->add_option("--method", method_,
                             "hull or meridian (default: the scan's, with --images hull)");
    reconstruct_->add_option("--resolution", resolution_,
                             "Voxels along the longest side, 16..1024 (default: the scan's, else "
                             "192)");
    reconstruct_->add_option("--formats", formats_, "Model formats: ply,obj,stl,glb,wrl")
        ->delimiter(',');
    reconstruct_->add_option("--images", images_.images,
                             "A folder of photos, cut-out photos (PNG with alpha) or silhouettes "
                             "instead of a scan folder");
    reconstruct_->add_option("--pattern", images_.pattern,
                             "With --images: file names with {angle} or {index}, e.g. "
                             "bw_shoe{angle}.tif (default: every image, sorted by name)");
    reconstruct_->add_option("--step-deg", images_.step_deg,
                             "With --images: degrees between views (default 10)");
    reconstruct_->add_option("--cameras", cameras_,
                             "With --images: per-view cameras (Middlebury *_par.txt or 3x4 "
                             "matrices); default: the thesis's calibration-free geometry");
    reconstruct_->add_option("--bbox", bbox_, "With --images: carving volume X0 Y0 Z0 X1 Y1 Z1")
        ->expected(6);
    reconstruct_->add_option("--segment", images_.segment,
                             "With --images: segmentation of photos: auto (default), graphcut, "
                             "background, otsu, fixed, chroma, or threshold (any channel above "
                             "--threshold)");
    reconstruct_->add_option("--config", images_config_,
                             "With --images: a TOML file whose [segment] table configures the "
                             "segmentation (method auto unless it names one)");
    reconstruct_->add_option("--threshold", images_.threshold,
                             "With --images: photos on black: object where any channel exceeds "
                             "this (0..254, default 20; implies --segment threshold)");
    reconstruct_->add_option("--row-step", images_.row_step_px,
                             "With --images, meridian: feature points every k-th row (default 9)");
    reconstruct_->add_flag("--both-sides", images_.both_sides,
                           "With --images, meridian: both sides of the axis (T/2 images)");
    reconstruct_->add_option("--max-image-mp", images_.max_image_mp,
                             "With --images: refuse images over this many megapixels, from "
                             "their headers (default 100)");

    check_ = app.add_subcommand("check-config", "Validate a config and print the effective one");
    check_->add_option("FILE", check_file_, "The config file");
    check_->add_flag("--reference", reference_,
                     "Print the reference of every table and key as Markdown "
                     "(docs/configuration.md) instead");
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
    if (reconstruct_->parsed()) return RunReconstruct(stop, out, err);
    if (check_->parsed()) return RunCheckConfig(out, err);
    return std::nullopt;
  }

 private:
  int RunCheckConfig(std::ostream& out, std::ostream& err) {
    if (reference_ != check_file_.empty()) {
      err << "revolve check-config: give either a config FILE or --reference\n";
      return kExitUsage;
    }
    if (!reference_) return RunCheckConfigCommand(check_file_, out, err);
    Expected<std::string> markdown = ConfigReferenceMarkdown();
    if (!markdown) {
      err << "revolve check-config --reference: " << markdown.error().message << "\n";
      return kExitFailed;
    }
    out << *markdown;
    return 0;
  }

  int RunReconstruct(std::stop_token stop, std::ostream& out, std::ostream& err) {
    if (!images_.images.empty()) {
      if (!recon_.scan_dir.empty()) {
        err << "revolve reconstruct: give either SCAN_DIR or --images DIR, not both\n";
        return kExitUsage;
      }
      if (out_) images_.out = *out_;
      if (method_) images_.method = *method_;
      if (resolution_) images_.resolution = *resolution_;
      if (!formats_.empty()) images_.formats = formats_;
      if (cameras_) images_.cameras = *cameras_;
      if (images_config_) images_.config = *images_config_;
      if (reconstruct_->count("--threshold") > 0 && images_.segment.empty()) {
        images_.segment = "threshold";
      }
      if (bbox_.size() == 6) {
        images_.bbox =
            std::array<double, 6>{bbox_[0], bbox_[1], bbox_[2], bbox_[3], bbox_[4], bbox_[5]};
      }
      return RunReconstructImages(images_, out, err);
    }
    if (recon_.scan_dir.empty()) {
      err << "revolve reconstruct: give the scan folder (SCAN_DIR) or --images DIR\n";
      return kExitUsage;
    }
    for (const char* option :
         {"--pattern", "--step-deg", "--cameras", "--bbox", "--threshold", "--segment", "--config",
          "--row-step", "--both-sides", "--max-image-mp"}) {
      if (reconstruct_->count(option) > 0) {
        err << "revolve reconstruct: " << option << " applies to --images only\n";
        return kExitUsage;
      }
    }
    if (out_) recon_.out = *out_;
    if (method_) recon_.method = *method_;
    if (resolution_) recon_.resolution = *resolution_;
    if (!formats_.empty()) recon_.formats = formats_;
    return RunReconstructCommand(recon_, stop, out, err);
  }

  ClientOptions client_;
  std::optional<std::string> recipe_;
  std::optional<std::string> resume_;
  bool watch_ = false;
  bool follow_ = false;
  ReconstructCommandOptions recon_;
  ReconstructImagesOptions images_;
  std::optional<std::filesystem::path> images_config_;
  std::optional<std::filesystem::path> out_;
  std::optional<std::string> method_;
  std::optional<int> resolution_;
  std::optional<std::filesystem::path> cameras_;
  std::vector<double> bbox_;
  std::vector<std::string> formats_;
  std::filesystem::path check_file_;
  bool reference_ = false;
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
