// The libcamera plugin (capture/libcamera/libcamera_plugin.h): built into
// librevolve_libcamera.so, not into revolve.
#include "capture/libcamera/libcamera_plugin.h"

#include <sys/mman.h>

#include <cstdlib>

#include <condition_variable>
#include <deque>
#include <mutex>

#include <fmt/format.h>
#include <libcamera/libcamera.h>

#include "capture/v4l2/pixel_convert.h"  // the FourCC constants (header only)

namespace revolve::capture {
namespace {

namespace lc = libcamera;

// libcamera's RGB888 is B, G, R in memory (DRM naming), OpenCV's order.
constexpr std::uint32_t kDrmRgb888 = FourCc('R', 'G', '2', '4');
constexpr std::uint32_t kDrmBgr888 = FourCc('B', 'G', '2', '4');

class LibcameraCamera final : public Camera {
 public:
  LibcameraCamera(const LibcameraOptions& options, libcamera_plugin::ConvertFn convert)
      : options_(options), convert_(convert) {}
  ~LibcameraCamera() override { Stop(); }

  Expected<FrameFormat> Start() override {
    std::lock_guard lock(mutex_);
    manager_ = std::make_unique<lc::CameraManager>();
    if (int r = manager_->start(); r < 0) {
      return MakeError(ErrorCode::kIo, fmt::format("libcamera: CameraManager::start: {}", r));
    }
    const auto cameras = manager_->cameras();
    if (cameras.empty()) {
      return MakeError(ErrorCode::kNoDevice,
                       options_.camera.empty()
                           ? std::string("libcamera: no cameras")
                           : fmt::format("libcamera: no cameras (so no \"{}\")", options_.camera));
    }
    camera_ = options_.camera.empty() ? cameras.front() : manager_->get(options_.camera);
    if (!camera_) {
      return MakeError(ErrorCode::kNoDevice,
                       fmt::format("libcamera: no camera \"{}\"", options_.camera));
    }
    if (camera_->acquire() < 0) {
      camera_.reset();
      return MakeError(ErrorCode::kBusy, "libcamera: the camera is in use");
    }
    acquired_ = true;
    config_ = camera_->generateConfiguration({lc::StreamRole::StillCapture});
    if (!config_ || config_->empty()) {
      return MakeError(ErrorCode::kUnsupported, "libcamera: no still-capture configuration");
    }
    lc::StreamConfiguration& stream_config = config_->at(0);
    stream_config.size = lc::Size(static_cast<unsigned>(options_.width_px),
                                  static_cast<unsigned>(options_.height_px));
    stream_config.pixelFormat = lc::formats::RGB888;
    stream_config.bufferCount = 4;
    if (config_->validate() == lc::CameraConfiguration::Invalid) {
      return MakeError(ErrorCode::kUnsupported, "libcamera: the configuration is invalid");
    }
    if (camera_->configure(config_.get()) < 0) {
      return MakeError(ErrorCode::kIo, "libcamera: configure failed");
    }
    stream_ = stream_config.stream();
    fourcc_ = stream_config.pixelFormat.fourcc();
    width_ = static_cast<int>(stream_config.size.width);
    height_ = static_cast<int>(stream_config.size.height);
    stride_ = static_cast<int>(stream_config.stride);
    allocator_ = std::make_unique<lc::FrameBufferAllocator>(camera_);
    if (allocator_->allocate(stream_) < 0) {
      return MakeError(ErrorCode::kIo, "libcamera: cannot allocate buffers");
    }
    for (const std::unique_ptr<lc::FrameBuffer>& buffer : allocator_->buffers(stream_)) {
      std::unique_ptr<lc::Request> request = camera_->createRequest();
      if (!request || request->addBuffer(stream_, buffer.get()) < 0) {
        return MakeError(ErrorCode::kIo, "libcamera: cannot create a request");
      }
      SetControls(request->controls());
      requests_.push_back(std::move(request));
    }
    camera_->requestCompleted.connect(this, &LibcameraCamera::OnCompleted);
    if (camera_->start() < 0) return MakeError(ErrorCode::kIo, "libcamera: start failed");
    started_ = true;
    for (auto& request : requests_) camera_->queueRequest(request.get());
    return FrameFormat{width_, height_, FourCcToString(fourcc_)};
  }

  Expected<Frame> Capture(Clock::time_point not_before, Clock::duration timeout) override {
    std::unique_lock lock(mutex_);
    if (!started_) return MakeError(ErrorCode::kInternal, "libcamera: not started");
    const auto deadline = Clock::now() + timeout;
    while (true) {
      if (!completed_cv_.wait_until(lock, deadline,
                                    [&] { return !completed_.empty() || !started_; })) {
        return MakeError(ErrorCode::kTimeout, "libcamera: no frame before the deadline");
      }
      if (!started_) return MakeError(ErrorCode::kAborted, "libcamera: stopped");
      lc::Request* request = completed_.front();
      completed_.pop_front();
      Expected<Frame> frame = MakeError(ErrorCode::kInternal, "no frame");
      bool keep = false;
      if (request->status() == lc::Request::RequestComplete) {
        lc::FrameBuffer* buffer = request->buffers().begin()->second;
        const Clock::time_point exposed{std::chrono::duration_cast<Clock::duration>(
            std::chrono::nanoseconds(buffer->metadata().timestamp))};
        if (exposed >= not_before) {
          frame = Convert(*buffer);
          if (frame) {
            frame->exposed = exposed;
            frame->sequence = buffer->metadata().sequence;
            if (options_.exposure_us > 0.0) frame->exposure_us = options_.exposure_us;
            keep = true;
          }
        }
      }
      request->reuse(lc::Request::ReuseBuffers);
      SetControls(request->controls());
      camera_->queueRequest(request);
      if (keep) return frame;
    }
  }

  void Stop() noexcept override {
    bool was_started;
    {
      std::lock_guard lock(mutex_);
      was_started = started_;
      started_ = false;
      completed_.clear();
      completed_cv_.notify_all();
    }
    // Without the lock: stopping completes the queued requests through OnCompleted.
    if (was_started && camera_) camera_->stop();
    std::lock_guard lock(mutex_);
    requests_.clear();
    allocator_.reset();
    if (camera_) {
      if (acquired_) camera_->release();
      acquired_ = false;
      camera_.reset();
    }
    config_.reset();
    if (manager_) manager_->stop();
    manager_.reset();
  }

  std::string Describe() const override {
    return fmt::format("libcamera camera {} {}x{}",
                       options_.camera.empty() ? "(first)" : options_.camera, options_.width_px,
                       options_.height_px);
  }

 private:
  void SetControls(lc::ControlList& controls) const {
    if (options_.exposure_us > 0.0) {
      controls.set(lc::controls::AeEnable, false);
      controls.set(lc::controls::ExposureTime, static_cast<std::int32_t>(options_.exposure_us));
    }
    if (options_.analogue_gain > 0.0) {
      controls.set(lc::controls::AnalogueGain, static_cast<float>(options_.analogue_gain));
    }
    if (options_.colour_gains.size() == 2) {
      controls.set(lc::controls::AwbEnable, false);
      const float gains[2] = {static_cast<float>(options_.colour_gains[0]),
                              static_cast<float>(options_.colour_gains[1])};
      controls.set(lc::controls::ColourGains, lc::Span<const float, 2>(gains));
    }
  }

  // On libcamera's thread.
  void OnCompleted(lc::Request* request) {
    if (request->status() == lc::Request::RequestCancelled) return;
    std::lock_guard lock(mutex_);
    if (!started_) return;
    completed_.push_back(request);
    completed_cv_.notify_all();
  }

  Expected<Frame> Convert(const lc::FrameBuffer& buffer) const {
    const lc::FrameBuffer::Plane& plane = buffer.planes().front();
    const std::size_t length = plane.offset + plane.length;
    void* address = ::mmap(nullptr, length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
    if (address == MAP_FAILED) return MakeError(ErrorCode::kIo, "libcamera: cannot map a buffer");
    const std::span<const std::uint8_t> data(
        static_cast<const std::uint8_t*>(address) + plane.offset,
        buffer.metadata().planes().front().bytesused);
    std::uint32_t fourcc = fourcc_;
    Expected<cv::Mat> image = MakeError(ErrorCode::kInternal, "");
    if (fourcc == kDrmRgb888 || fourcc == kDrmBgr888) {
      image = convert_(data, kDrmRgb888 == fourcc ? kFourCcBgr24 : kFourCcRgb24, width_, height_,
                       stride_);
    } else {
      image = convert_(data, fourcc, width_, height_, stride_);
    }
    ::munmap(address, length);
    if (!image) return std::unexpected(image.error());
    Frame frame;
    frame.image = std::move(*image);
    return frame;
  }

  LibcameraOptions options_;
  libcamera_plugin::ConvertFn convert_;
  std::mutex mutex_;
  std::condition_variable completed_cv_;
  std::unique_ptr<lc::CameraManager> manager_;
  std::shared_ptr<lc::Camera> camera_;
  bool acquired_ = false;
  bool started_ = false;
  std::unique_ptr<lc::CameraConfiguration> config_;
  std::unique_ptr<lc::FrameBufferAllocator> allocator_;
  lc::Stream* stream_ = nullptr;
  std::vector<std::unique_ptr<lc::Request>> requests_;
  std::deque<lc::Request*> completed_;
  std::uint32_t fourcc_ = 0;
  int width_ = 0, height_ = 0, stride_ = 0;
};

Expected<std::unique_ptr<Camera>> Create(const LibcameraOptions& options,
                                         libcamera_plugin::ConvertFn convert) {
  return std::unique_ptr<Camera>(std::make_unique<LibcameraCamera>(options, convert));
}

std::string List() {
  // Keep libcamera's own log (e.g. "No IPA found") off the listing unless asked for.
  ::setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", 0);
  lc::CameraManager manager;
  if (manager.start() < 0) return "libcamera: cannot start the camera manager\n";
  std::string out;
  for (const auto& camera : manager.cameras()) out += "libcamera: " + camera->id() + "\n";
  if (out.empty()) out = "libcamera: no cameras\n";
  manager.stop();
  return out;
}

const libcamera_plugin::Table kTable{libcamera_plugin::kVersion, &Create, &List};

}  // namespace
}  // namespace revolve::capture

// The plugin's one exported name (the rest is hidden).
extern "C" [[gnu::visibility("default")]] const revolve::capture::libcamera_plugin::Table*
revolve_libcamera_plugin_v1() {
  return &revolve::capture::kTable;
}
