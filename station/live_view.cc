#include "station/live_view.h"

#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "base/atomic_file.h"
#include "base/image_codecs.h"
#include "base/log.h"
#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/io/mesh_io.h"

namespace revolve::station {

struct LiveView::HullState {
  std::string scan_id;
  std::unique_ptr<reconstruct::VisualHull> hull;
  int stops_in = 0;
  int last_stop = -1;
};

namespace {

// `view` for a mask scaled by (sx, sy): pixel centres map as x' = sx x + (sx - 1) / 2.
View ScaledView(const View& view, int width_px, int height_px) {
  const double sx = static_cast<double>(width_px) / view.width_px;
  const double sy = static_cast<double>(height_px) / view.height_px;
  Eigen::Matrix3d a;
  a << sx, 0, (sx - 1) / 2, 0, sy, (sy - 1) / 2, 0, 0, 1;
  View scaled = view;
  scaled.pixel_from_object = a * view.pixel_from_object;
  scaled.width_px = width_px;
  scaled.height_px = height_px;
  return scaled;
}

double ScaleToFit(const cv::Mat& image, int max_side_px) {
  const int side = std::max(image.cols, image.rows);
  return side > max_side_px ? static_cast<double>(max_side_px) / side : 1.0;
}

}  // namespace

Expected<std::unique_ptr<LiveView>> LiveView::Create(LiveViewOptions options) {
  std::error_code ec;
  std::string pattern =
      (std::filesystem::temp_directory_path(ec) / "revolved-live-XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) {
    return MakeError(ErrorCode::kIo,
                     fmt::format("cannot create a folder for the live hull ({}): {}", pattern,
                                 std::strerror(errno)));
  }
  return std::unique_ptr<LiveView>(new LiveView(options, pattern));
}

LiveView::LiveView(LiveViewOptions options, std::filesystem::path work_dir)
    : options_(options), work_dir_(std::move(work_dir)) {
  worker_ = std::thread([this] { Work(); });
}

LiveView::~LiveView() {
  {
    std::lock_guard lock(hull_mutex_);
    stopping_ = true;
  }
  hull_cv_.notify_all();
  worker_.join();
  std::error_code ec;
  std::filesystem::remove_all(work_dir_, ec);
}

void LiveView::AddStop(const LiveStop& stop) {
  {
    std::lock_guard lock(frame_mutex_);
    latest_ = stop;
    latest_.view.reset();
    have_latest_ = true;
    ++frame_version_;
  }
  if (!stop.view || stop.mask.empty()) return;
  {
    std::lock_guard lock(hull_mutex_);
    jobs_.push_back(HullJob{stop.scan_id, stop.index, stop.mask, *stop.view, stop.bbox_min_mm,
                            stop.bbox_max_mm});
  }
  hull_cv_.notify_all();
}

std::optional<LiveBlob> LiveView::FrameJpeg() {
  LiveStop stop;
  std::uint64_t version = 0;
  {
    std::lock_guard lock(frame_mutex_);
    if (!have_latest_) return std::nullopt;
    if (frame_jpeg_ && frame_jpeg_->version == frame_version_) return frame_jpeg_;
    stop = latest_;
    version = frame_version_;
  }
  // Encoded outside the lock: the scanning thread never waits for it.
  const double scale = ScaleToFit(stop.frame, options_.frame_max_side_px);
  cv::Mat image;
  if (stop.frame.channels() == 1) {
    cv::cvtColor(stop.frame, image, cv::COLOR_GRAY2BGR);
  } else {
    image = stop.frame.clone();
  }
  if (scale < 1.0) cv::resize(image, image, cv::Size(), scale, scale, cv::INTER_AREA);
  if (!stop.mask.empty()) {
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(stop.mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
    for (auto& contour : contours) {
      for (cv::Point& p : contour) {
        p = cv::Point(static_cast<int>(std::lround((p.x + 0.5) * scale - 0.5)),
                      static_cast<int>(std::lround((p.y + 0.5) * scale - 0.5)));
      }
    }
    const int thickness =
        std::max(1, static_cast<int>(std::lround(std::max(image.cols, image.rows) / 300.0)));
    cv::polylines(image, contours, true, cv::Scalar(0, 255, 0), thickness, cv::LINE_AA);
  }
  // An image that cannot be encoded (or no codecs) shows no picture; the stop goes on.
  const Expected<std::vector<std::uint8_t>> jpeg =
      EncodeImage(".jpg", image, {cv::IMWRITE_JPEG_QUALITY, options_.jpeg_quality});
  LiveBlob blob{jpeg ? std::string(jpeg->begin(), jpeg->end()) : std::string(), stop.scan_id,
                stop.index, 0, version};
  std::lock_guard lock(frame_mutex_);
  if (!frame_jpeg_ || frame_jpeg_->version < version) frame_jpeg_ = blob;
  return blob;
}

std::optional<LiveBlob> LiveView::HullGlb() const {
  std::lock_guard lock(hull_mutex_);
  return hull_glb_;
}

void LiveView::Flush() {
  std::unique_lock lock(hull_mutex_);
  hull_cv_.wait(lock, [this] { return stopping_ || (jobs_.empty() && !busy_); });
}

void LiveView::Work() {
  hull_ = std::make_unique<HullState>();
  for (;;) {
    HullJob job;
    {
      std::unique_lock lock(hull_mutex_);
      hull_cv_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
      if (stopping_) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
      busy_ = true;
    }
    Carve(std::move(job));
    bool more = false;
    {
      std::lock_guard lock(hull_mutex_);
      more = !jobs_.empty();
    }
    // Stops that came in meanwhile are carved first: one mesh for all of them.
    if (!more) PublishHull();
    {
      std::lock_guard lock(hull_mutex_);
      busy_ = false;
    }
    hull_cv_.notify_all();
  }
}

void LiveView::Carve(HullJob job) {
  HullState& h = *hull_;
  if (!h.hull || h.scan_id != job.scan_id) {
    auto grid =
        reconstruct::VoxelGrid::FromBox(job.bbox_min_mm, job.bbox_max_mm, options_.hull_resolution);
    if (!grid) {
      Logger("station")->warn("live hull: {}", grid.error().message);
      return;
    }
    h = HullState{job.scan_id, std::make_unique<reconstruct::VisualHull>(*grid), 0, -1};
    std::lock_guard lock(hull_mutex_);
    hull_glb_.reset();
  }
  const double scale = ScaleToFit(job.mask, options_.mask_max_side_px);
  cv::Mat mask = job.mask;
  View view = job.view;
  if (scale < 1.0) {
    const int w = std::max(1, static_cast<int>(std::lround(job.mask.cols * scale)));
    const int hgt = std::max(1, static_cast<int>(std::lround(job.mask.rows * scale)));
    cv::resize(job.mask, mask, cv::Size(w, hgt), 0, 0, cv::INTER_AREA);
    cv::threshold(mask, mask, 127, 255, cv::THRESH_BINARY);
    view = ScaledView(job.view, w, hgt);
  }
  if (auto carved = h.hull->Integrate(mask, view); !carved) {
    Logger("station")->warn("live hull: stop {}: {}", job.index, carved.error().message);
    return;
  }
  ++h.stops_in;
  h.last_stop = job.index;
}

void LiveView::PublishHull() {
  const HullState& h = *hull_;
  if (!h.hull || h.stops_in == 0) return;
  reconstruct::HullSurfaceOptions surface;
  surface.sub_voxel = false;
  const reconstruct::Mesh mesh = h.hull->ExtractSurface(surface);
  if (mesh.faces.empty()) return;
  const std::filesystem::path file = work_dir_ / "hull.glb";
  if (auto written = reconstruct::WriteGlb(mesh, file); !written) {
    Logger("station")->warn("live hull: {}", written.error().message);
    return;
  }
  Expected<std::string> bytes = ReadWholeFile(file);
  if (!bytes) return;
  std::lock_guard lock(hull_mutex_);
  const std::uint64_t version = hull_glb_ ? hull_glb_->version + 1 : 1;
  hull_glb_ = LiveBlob{std::move(*bytes), h.scan_id, h.last_stop, h.stops_in, version};
}

}  // namespace revolve::station
