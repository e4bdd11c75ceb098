// What the web console shows while a scan runs: the latest frame with its silhouette outlined
// (JPEG) and a coarse visual hull of the stops so far (glTF binary), rebuilt after each stop.
//
// The scanning thread only hands over the stop (AddStop: shares the images, queues the mask);
// the hull is carved and meshed on the view's own worker thread, and the JPEG is encoded by the
// reader that asks for it, so a slow browser never slows a stop. Thread-safe.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "base/error.h"
#include "station/scan_session.h"

namespace revolve::station {

struct LiveViewOptions {
  int hull_resolution = 48;     // voxels along the longest side of the volume
  int mask_max_side_px = 320;   // masks are scaled down to this before carving
  int frame_max_side_px = 800;  // the JPEG's longest side
  int jpeg_quality = 80;
};

// One encoded picture or model, and what it shows.
struct LiveBlob {
  std::string bytes;
  std::string scan_id;
  int stop = -1;     // the latest stop it includes
  int stops_in = 0;  // hull: stops carved into it
  std::uint64_t version = 0;
};

class LiveView {
 public:
  // `work_dir`: a private folder for the hull's temporary file (created; removed with the view).
  static Expected<std::unique_ptr<LiveView>> Create(LiveViewOptions options);
  ~LiveView();
  LiveView(const LiveView&) = delete;
  LiveView& operator=(const LiveView&) = delete;

  // Scanning thread: the stop just saved. Cheap: the images are shared, not copied.
  void AddStop(const LiveStop& stop);

  // The latest frame with the silhouette's outline, as JPEG; nullopt before the first stop.
  std::optional<LiveBlob> FrameJpeg();
  // The hull of the current scan's stops so far, as glTF binary (millimetres in a node scaled to
  // metres, y up: reconstruct/io/mesh_io.h WriteGlb); nullopt before the first one is built or
  // when the scan's views are not known while scanning (thesis mode).
  std::optional<LiveBlob> HullGlb() const;

  // Waits until the worker has meshed every stop handed over so far (tests).
  void Flush();

 private:
  struct HullJob {
    std::string scan_id;
    int index = 0;
    cv::Mat mask;
    View view;
    Eigen::Vector3d bbox_min_mm, bbox_max_mm;
  };
  struct HullState;

  LiveView(LiveViewOptions options, std::filesystem::path work_dir);
  void Work();
  void Carve(HullJob job);
  void PublishHull();

  LiveViewOptions options_;
  std::filesystem::path work_dir_;

  mutable std::mutex frame_mutex_;
  LiveStop latest_;
  bool have_latest_ = false;
  std::uint64_t frame_version_ = 0;
  std::optional<LiveBlob> frame_jpeg_;  // cached for frame_version_

  mutable std::mutex hull_mutex_;
  std::condition_variable hull_cv_;
  std::deque<HullJob> jobs_;
  bool busy_ = false;
  bool stopping_ = false;
  std::optional<LiveBlob> hull_glb_;
  std::unique_ptr<HullState> hull_;  // the worker's
  std::thread worker_;
};

}  // namespace revolve::station
