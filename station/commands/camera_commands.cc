#include "station/commands/camera_commands.h"

#include <chrono>
#include <ostream>
#include <string>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/image_codecs.h"
#include "base/sim_plate.h"
#include "capture/camera.h"
#include "capture/segmenter.h"
#include "config/config.h"
#include "station/commands/scan_command.h"

namespace revolve::station {
namespace {

class CameraCommandsImpl final : public CameraCommands {
 public:
  explicit CameraCommandsImpl(CLI::App& app) {
    camera_ = app.add_subcommand("camera", "Camera bring-up: list devices, take a snapshot");
    camera_->require_subcommand(1);
    list_ = camera_->add_subcommand("list", "List the cameras of this machine and their formats");
    snapshot_ = camera_->add_subcommand(
        "snapshot", "Capture one frame from the configured camera and write it (PNG, JPG, ...)");
    snapshot_->add_option("FILE", file_, "Image file to write")->required();
    snapshot_->add_option("--config", config_,
                          "Config file (TOML); default: the embedded simulated rig");
    snapshot_->add_option("--mask", mask_file_,
                          "Also segment the frame with [segment] and write the mask here");
    snapshot_->add_option("--timeout-s", timeout_s_, "Capture timeout in seconds")
        ->check(CLI::Range(0.1, 600.0));
  }

  std::optional<int> Run(std::stop_token /*stop*/, std::ostream& out, std::ostream& err) override {
    if (list_->parsed()) {
      out << capture::ListCameraDevices();
      return kExitOk;
    }
    if (snapshot_->parsed()) return Snapshot(out, err);
    return std::nullopt;
  }

 private:
  int Snapshot(std::ostream& out, std::ostream& err) {
    auto document = config_.empty() ? config::Parse(std::string(config::EmbeddedDefault()),
                                                    std::string(config::kEmbeddedOrigin))
                                    : config::LoadFile(config_);
    if (!document) {
      err << document.error().message << "\n";
      return kExitConfig;
    }
    const config::Section root = config::Section::Root(*document);
    auto camera_section = root.Child("camera");
    if (!camera_section) {
      err << camera_section.error().message << "\n";
      return kExitConfig;
    }
    auto options = capture::ParseOptions(*camera_section);
    if (!options) {
      err << options.error().message << "\n";
      return kExitConfig;
    }
    std::unique_ptr<capture::Segmenter> segmenter;
    if (!mask_file_.empty()) {
      auto segment_section = root.Child("segment");
      if (!segment_section) {
        err << segment_section.error().message << "\n";
        return kExitConfig;
      }
      auto segment = capture::ParseSegmentOptions(*segment_section);
      if (!segment) {
        err << segment.error().message << "\n";
        return kExitConfig;
      }
      auto created = capture::CreateSegmenter(*segment);
      if (!created) {
        err << created.error().message << "\n";
        return kExitConfig;
      }
      segmenter = std::move(*created);
    }
    auto camera = capture::Create(*options, std::make_shared<SimulatedPlate>());
    if (!camera) {
      err << camera.error().ToString() << "\n";
      return kExitFailed;
    }
    auto format = (*camera)->Start();
    if (!format) {
      err << "starting the camera: " << format.error().ToString() << "\n";
      return kExitFailed;
    }
    const auto timeout = std::chrono::duration_cast<capture::Clock::duration>(
        std::chrono::duration<double>(timeout_s_));
    auto frame = (*camera)->Capture(capture::Clock::now(), timeout);
    (*camera)->Stop();
    if (!frame) {
      err << "capturing: " << frame.error().ToString() << "\n";
      return kExitFailed;
    }
    if (Expected<void> written = WriteImageFile(file_, frame->image); !written) {
      err << written.error().message << "\n";
      return kExitFailed;
    }
    out << fmt::format("{}: {}x{} {} frame from {}", file_, format->width_px, format->height_px,
                       format->pixel_format, (*camera)->Describe());
    if (frame->exposure_us > 0.0) out << fmt::format(", exposure {:g} us", frame->exposure_us);
    out << "\n";
    if (segmenter) {
      auto mask = segmenter->Segment(frame->image, cv::Mat());
      if (!mask) {
        err << "segmenting: " << mask.error().ToString() << "\n";
        return kExitFailed;
      }
      if (Expected<void> written = WriteImageFile(mask_file_, *mask); !written) {
        err << written.error().message << "\n";
        return kExitFailed;
      }
      out << fmt::format("{}: silhouette of {} px\n", mask_file_, cv::countNonZero(*mask));
    }
    return kExitOk;
  }

  CLI::App* camera_ = nullptr;
  CLI::App* list_ = nullptr;
  CLI::App* snapshot_ = nullptr;
  std::string file_;
  std::string config_;
  std::string mask_file_;
  double timeout_s_ = 10.0;
};

}  // namespace

std::unique_ptr<CameraCommands> AddCameraCommands(CLI::App& app) {
  return std::make_unique<CameraCommandsImpl>(app);
}

}  // namespace revolve::station
