// The devices of a rig, brought up from the configuration, and the simulated faults of
// [station.simulate].
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>

#include "base/error.h"
#include "base/sim_plate.h"
#include "capture/camera.h"
#include "capture/segmenter.h"
#include "station/station_config.h"
#include "turntable/turntable.h"

namespace revolve::station {

// The devices of a rig, owned. For the simulated rig the turntable and the camera share `plate`.
struct Devices {
  std::shared_ptr<SimulatedPlate> plate;
  std::unique_ptr<turntable::Turntable> turntable;
  std::unique_ptr<capture::Camera> camera;
  std::unique_ptr<capture::Segmenter> segmenter;
  // Captures made since the devices were opened (counts across camera re-creations), for
  // [station.simulate] camera_fail_after and camera_glitch_after.
  std::shared_ptr<std::atomic<std::int64_t>> captures =
      std::make_shared<std::atomic<std::int64_t>>(0);
};

// Creates the configured devices (nothing moves yet). [station.simulate] faults are applied:
// drive faults to the mock turntable, camera loss by a wrapper around the camera.
Expected<Devices> OpenDevices(const StationConfig& config);

// Re-creates the camera and the segmenter for `config` (a recipe may change the exposure and the
// segmentation), keeping the turntable, the plate and the capture count.
Expected<void> ReopenCamera(const StationConfig& config, Devices& devices);

}  // namespace revolve::station
