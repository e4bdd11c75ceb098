// The replay camera: a folder of images served as a camera, so a scan can be rerun from saved
// frames or from a published turntable sequence.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"
#include "base/image_files.h"  // NaturalLess, the order of a folder's images
#include "base/sim_plate.h"
#include "capture/camera.h"

namespace revolve::capture {

// Checks a [camera.replay] pattern: "" or a file name with at most one of each placeholder
// {angle}, {index}, optionally zero-padded ({angle:03}), and no other braces.
// Errors: bad_input saying what is wrong.
Expected<void> CheckReplayPattern(std::string_view pattern);

// The file name for a stop: {angle} becomes angle_deg, {index} becomes index (zero-padded to
// the given width). Contract: CheckReplayPattern(pattern) passed.
std::string ExpandReplayPattern(std::string_view pattern, int angle_deg, int index);

// The image files (png, jpg, jpeg, tif, tiff, bmp, pgm, ppm; any case) of a folder in natural
// order. Errors: not_found (no folder), bad_input (no images).
Expected<std::vector<std::filesystem::path>> ListImages(const std::filesystem::path& dir);

class ReplayCamera final : public Camera {
 public:
  // Checks that the folder holds the first image (it fixes the frame size). `plate` may be
  // null: the images are then served in sequence. Errors: not_found, bad_input.
  static Expected<std::unique_ptr<ReplayCamera>> Create(
      const ReplayOptions& options, std::shared_ptr<const SimulatedPlate> plate);

  // {width, height, "BGR3"} of the first image.
  Expected<FrameFormat> Start() override;

  // Waits until not_before (timeout at once when it lies beyond now + timeout; aborted on
  // Stop), then loads the image for the plate's angle (order = "angle": stop k = round(angle /
  // step_deg) modulo the images of a turn) or the next one (order = "sequence", or no plate).
  // Grey images are served as BGR. Errors: not_found (a missing image; the last image of a
  // sequence already served), bad_input (unreadable), internal (not started).
  Expected<Frame> Capture(Clock::time_point not_before, Clock::duration timeout) override;

  // The configured background image. Errors: unsupported when none is configured; not_found,
  // bad_input (its size differs from the frames').
  Expected<Frame> CaptureBackground(Clock::time_point not_before, Clock::duration timeout) override;

  void Stop() noexcept override;

  // The configured geometry (hfov_deg > 0), for the first image's size.
  std::optional<Rig> KnownRig() const override;
  std::string Describe() const override;

  // The file served for stop `index` (pure; for tests and messages).
  std::filesystem::path PathForStop(int index) const;
  // The stop index served for a plate angle.
  int StopForAngle(double angle_deg) const;

 private:
  ReplayCamera(const ReplayOptions& options, std::shared_ptr<const SimulatedPlate> plate,
               std::vector<std::filesystem::path> files, cv::Size size);
  Expected<void> WaitUntil(Clock::time_point not_before, Clock::duration timeout);
  Expected<cv::Mat> Load(const std::filesystem::path& path) const;

  ReplayOptions options_;
  std::shared_ptr<const SimulatedPlate> plate_;
  std::vector<std::filesystem::path> files_;  // natural order when there is no pattern
  cv::Size size_;
  int stops_per_turn_;

  std::mutex mutex_;
  std::condition_variable wake_;
  bool started_ = false;  // guarded by mutex_
  std::uint64_t next_sequence_ = 0;
};

}  // namespace revolve::capture
