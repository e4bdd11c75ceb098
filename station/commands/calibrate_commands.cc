#include "station/commands/calibrate_commands.h"

#include <string>

#include "station/commands/calibrate_command.h"

namespace revolve::station {
namespace {

class CalibrateCommandsImpl final : public CalibrateCommands {
 public:
  explicit CalibrateCommandsImpl(CLI::App& app) {
    calibrate_ = app.add_subcommand(
        "calibrate",
        "Calibrate the lens, then the turntable axis (docs/calibration.md); verbs run one step");
    calibrate_->require_subcommand(0, 1);
    AddConfig(calibrate_);
    AddImages(calibrate_);
    AddOut(calibrate_,
           "Calibration file to write (default: [calibration] file, else "
           "./calibration.toml)");
    AddBoard(calibrate_);

    lens_ = calibrate_->add_subcommand("lens", "Calibrate the lens only (no turntable axis)");
    AddConfig(lens_);
    AddImages(lens_);
    AddOut(lens_,
           "Calibration file to write (default: [calibration] file, else "
           "./calibration.toml)");
    AddBoard(lens_);

    axis_ = calibrate_->add_subcommand(
        "axis", "Calibrate the turntable axis with the lens of an existing calibration file");
    AddConfig(axis_);
    axis_->add_option("--calibration", calibration_, "Calibration file holding the lens")
        ->required();
    AddOut(axis_, "Calibration file to write (default: the --calibration file)");
    AddBoard(axis_);

    check_ = calibrate_->add_subcommand(
        "check", "Check that the rig still matches its calibration (exit 0 pass, 1 drifted)");
    AddConfig(check_);
    check_->add_option("--calibration", calibration_,
                       "Calibration file to check (default: [calibration] file)");
    AddBoard(check_);

    board_ = calibrate_->add_subcommand("board", "Write the board to print (300 dpi)");
    AddConfig(board_);
    AddOut(board_, "Image to write (default: ./board.png)");
    AddBoard(board_);
  }

  std::optional<int> Run(std::stop_token stop, std::istream& in, std::ostream& out,
                         std::ostream& err) override {
    if (!calibrate_->parsed()) return std::nullopt;
    options_.step = lens_->parsed()    ? CalibrateStep::kLens
                    : axis_->parsed()  ? CalibrateStep::kAxis
                    : check_->parsed() ? CalibrateStep::kCheck
                    : board_->parsed() ? CalibrateStep::kBoard
                                       : CalibrateStep::kAll;
    if (!calibration_.empty()) options_.calibration = calibration_;
    return RunCalibrateCommand(options_, std::move(stop), in, out, err);
  }

 private:
  void AddConfig(CLI::App* command) {
    command->add_option("--config", options_.config,
                        "Config file (TOML); default: the embedded simulated rig");
  }
  void AddImages(CLI::App* command) {
    command->add_option("--images", options_.images,
                        "Lens: a folder of images of the board instead of captured frames");
  }
  void AddOut(CLI::App* command, const std::string& what) {
    command->add_option("--out", options_.out, what);
  }
  void AddBoard(CLI::App* command) {
    command->add_option("--cols", options_.cols, "Board: inner corners along a row")
        ->check(CLI::Range(3, 100));
    command->add_option("--rows", options_.rows, "Board: inner corners along a column")
        ->check(CLI::Range(3, 100));
    command->add_option("--square-mm", options_.square_mm, "Board: square side, mm (measured)")
        ->check(CLI::Range(0.1, 1000.0));
    command->add_option("--type", options_.type, "Board: chessboard | charuco")
        ->check(CLI::IsMember({"chessboard", "charuco"}));
  }

  CLI::App* calibrate_ = nullptr;
  CLI::App* lens_ = nullptr;
  CLI::App* axis_ = nullptr;
  CLI::App* check_ = nullptr;
  CLI::App* board_ = nullptr;
  CalibrateCommandOptions options_;
  std::string calibration_;
};

}  // namespace

std::unique_ptr<CalibrateCommands> AddCalibrateCommands(CLI::App& app) {
  return std::make_unique<CalibrateCommandsImpl>(app);
}

}  // namespace revolve::station
