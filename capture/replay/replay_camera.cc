#include "capture/replay/replay_camera.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/image_files.h"
#include "base/image_read.h"
#include "base/log.h"

namespace revolve::capture {
namespace {

struct Placeholder {
  std::size_t begin = 0, end = 0;  // [begin, end) of "{...}"
  bool angle = false;
  int width = 0;
};

// Parses the placeholders of a pattern.
Expected<std::vector<Placeholder>> Placeholders(std::string_view pattern) {
  std::vector<Placeholder> out;
  bool seen_angle = false, seen_index = false;
  for (std::size_t i = 0; i < pattern.size(); ++i) {
    if (pattern[i] == '}') {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("pattern \"{}\": a '}}' without '{{'", pattern));
    }
    if (pattern[i] != '{') continue;
    const std::size_t close = pattern.find('}', i);
    if (close == std::string_view::npos) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("pattern \"{}\": a '{{' without '}}'", pattern));
    }
    const std::string_view inside = pattern.substr(i + 1, close - i - 1);
    const std::string_view name = inside.substr(0, inside.find(':'));
    Placeholder p{i, close + 1, name == "angle", 0};
    if (name != "angle" && name != "index") {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("pattern \"{}\": unknown placeholder {{{}}} (use {{angle}} or "
                                   "{{index}}, optionally zero-padded like {{angle:03}})",
                                   pattern, inside));
    }
    if (inside.size() > name.size()) {
      const std::string_view spec = inside.substr(name.size() + 1);
      if (spec.size() < 2 || spec.size() > 3 || spec[0] != '0' ||
          !std::all_of(spec.begin(), spec.end(), [](char c) { return std::isdigit(c); })) {
        return MakeError(
            ErrorCode::kBadInput,
            fmt::format("pattern \"{}\": {{{}}}: the width must look like :03", pattern, inside));
      }
      p.width = std::stoi(std::string(spec.substr(1)));
    }
    bool& seen = p.angle ? seen_angle : seen_index;
    if (seen) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("pattern \"{}\": {{{}}} appears twice", pattern, name));
    }
    seen = true;
    out.push_back(p);
    i = close;
  }
  if (!pattern.empty() && out.empty()) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("pattern \"{}\" has neither {{angle}} nor {{index}}", pattern));
  }
  return out;
}

}  // namespace

Expected<void> CheckReplayPattern(std::string_view pattern) {
  auto placeholders = Placeholders(pattern);
  if (!placeholders) return std::unexpected(placeholders.error());
  return {};
}

std::string ExpandReplayPattern(std::string_view pattern, int angle_deg, int index) {
  auto placeholders = Placeholders(pattern);
  if (!placeholders) return std::string(pattern);
  std::string out;
  std::size_t at = 0;
  for (const Placeholder& p : *placeholders) {
    out += pattern.substr(at, p.begin - at);
    out += fmt::format("{:0{}d}", p.angle ? angle_deg : index, p.width);
    at = p.end;
  }
  out += pattern.substr(at);
  return out;
}

Expected<std::vector<std::filesystem::path>> ListImages(const std::filesystem::path& dir) {
  auto files = ListImageFiles(dir);
  if (!files) return std::unexpected(WithContext(files.error(), "replay"));
  if (files->empty()) {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("replay: {} holds no images (png, jpg, tif, bmp, pgm, ppm)", dir.string()));
  }
  return files;
}

Expected<std::unique_ptr<ReplayCamera>> ReplayCamera::Create(
    const ReplayOptions& options, std::shared_ptr<const SimulatedPlate> plate) {
  if (options.dir.empty()) {
    return MakeError(ErrorCode::kBadInput, "[camera.replay] dir: the folder of images is not set");
  }
  if (auto ok = CheckReplayPattern(options.pattern); !ok) {
    return std::unexpected(WithContext(ok.error(), "[camera.replay]"));
  }
  if (!(options.step_deg > 0.0)) {
    return MakeError(ErrorCode::kBadInput, "[camera.replay] step_deg must be positive");
  }
  std::vector<std::filesystem::path> files;
  std::filesystem::path first;
  if (options.pattern.empty()) {
    auto listed = ListImages(options.dir);
    if (!listed) return std::unexpected(listed.error());
    files = std::move(*listed);
    first = files.front();
  } else {
    first = std::filesystem::path(options.dir) / ExpandReplayPattern(options.pattern, 0, 0);
  }
  const Expected<cv::Mat> image = ReadImageFile(first);
  if (!image) {
    return MakeError(image.error().code,
                     fmt::format("replay: cannot read the first image: {}", image.error().message));
  }
  return std::unique_ptr<ReplayCamera>(
      new ReplayCamera(options, std::move(plate), std::move(files), image->size()));
}

ReplayCamera::ReplayCamera(const ReplayOptions& options,
                           std::shared_ptr<const SimulatedPlate> plate,
                           std::vector<std::filesystem::path> files, cv::Size size)
    : options_(options), plate_(std::move(plate)), files_(std::move(files)), size_(size) {
  stops_per_turn_ = std::max(1, static_cast<int>(std::lround(360.0 / options_.step_deg)));
}

Expected<FrameFormat> ReplayCamera::Start() {
  {
    std::lock_guard lock(mutex_);
    started_ = true;
  }
  Logger("capture")->info("{} started", Describe());
  return FrameFormat{size_.width, size_.height, "BGR3"};
}

void ReplayCamera::Stop() noexcept {
  {
    std::lock_guard lock(mutex_);
    started_ = false;
  }
  wake_.notify_all();
}

Expected<void> ReplayCamera::WaitUntil(Clock::time_point not_before, Clock::duration timeout) {
  std::unique_lock lock(mutex_);
  if (!started_) {
    return MakeError(ErrorCode::kInternal, "replay camera: Capture() called while not started");
  }
  const Clock::time_point now = Clock::now();
  if (not_before > now && not_before - now > timeout) {
    return MakeError(ErrorCode::kTimeout,
                     "replay camera: not_before lies beyond the capture timeout");
  }
  while (started_ && Clock::now() < not_before) wake_.wait_until(lock, not_before);
  if (!started_) return MakeError(ErrorCode::kAborted, "replay camera: stopped while waiting");
  return {};
}

int ReplayCamera::StopForAngle(double angle_deg) const {
  const long k = std::lround(angle_deg / options_.step_deg);
  return static_cast<int>(((k % stops_per_turn_) + stops_per_turn_) % stops_per_turn_);
}

std::filesystem::path ReplayCamera::PathForStop(int index) const {
  if (options_.pattern.empty()) return files_[static_cast<std::size_t>(index) % files_.size()];
  const int angle = static_cast<int>(std::lround(index * options_.step_deg)) % 360;
  return std::filesystem::path(options_.dir) / ExpandReplayPattern(options_.pattern, angle, index);
}

Expected<cv::Mat> ReplayCamera::Load(const std::filesystem::path& path) const {
  ImageReadOptions read_options;
  read_options.imread_flags = cv::IMREAD_COLOR;
  Expected<cv::Mat> read = ReadImageFile(path, read_options);
  if (!read) {
    return MakeError(read.error().code,
                     fmt::format("replay: cannot read: {}", read.error().message));
  }
  cv::Mat image = std::move(*read);
  if (image.size() != size_) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("replay: {} is {}x{}, the first image {}x{}", path.string(),
                                 image.cols, image.rows, size_.width, size_.height));
  }
  return image;
}

Expected<Frame> ReplayCamera::Capture(Clock::time_point not_before, Clock::duration timeout) {
  if (auto ok = WaitUntil(not_before, timeout); !ok) return std::unexpected(ok.error());
  Frame frame;
  frame.exposed = Clock::now();
  int stop = 0;
  {
    std::lock_guard lock(mutex_);
    frame.sequence = next_sequence_++;
    const bool by_angle = options_.order == "angle" && plate_ != nullptr;
    if (by_angle) {
      stop = StopForAngle(plate_->angle_deg.load());
    } else {
      if (options_.pattern.empty() && frame.sequence >= files_.size()) {
        return MakeError(
            ErrorCode::kNotFound,
            fmt::format("replay: all {} images of {} were served", files_.size(), options_.dir));
      }
      stop = static_cast<int>(frame.sequence);
    }
  }
  auto image = Load(PathForStop(stop));
  if (!image) return std::unexpected(image.error());
  frame.image = std::move(*image);
  frame.plate_angle_deg = stop * options_.step_deg;
  return frame;
}

Expected<Frame> ReplayCamera::CaptureBackground(Clock::time_point not_before,
                                                Clock::duration timeout) {
  if (options_.background.empty()) {
    return MakeError(ErrorCode::kUnsupported,
                     "replay: no background image ([camera.replay] background)");
  }
  if (auto ok = WaitUntil(not_before, timeout); !ok) return std::unexpected(ok.error());
  auto image = Load(options_.background);
  if (!image) return std::unexpected(image.error());
  Frame frame;
  frame.exposed = Clock::now();
  frame.image = std::move(*image);
  return frame;
}

std::optional<Rig> ReplayCamera::KnownRig() const {
  if (!(options_.hfov_deg > 0.0)) return std::nullopt;
  Rig rig;
  rig.intrinsics = Intrinsics::FromFieldOfView(size_.width, size_.height, options_.hfov_deg);
  rig.cam_from_table = CamFromTableLookingAtAxis(options_.distance_mm, options_.elevation_deg,
                                                 options_.target_height_mm);
  return rig;
}

std::string ReplayCamera::Describe() const {
  return fmt::format("replay camera {}x{} from {}{}", size_.width, size_.height, options_.dir,
                     options_.pattern.empty() ? fmt::format(" ({} images)", files_.size())
                                              : "/" + options_.pattern);
}

}  // namespace revolve::capture
