// Fuzzes the calibration file reader (calibrate::ParseCalibration): no input may crash, throw or
// hang; a calibration that parses has finite intrinsics.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "calibrate/calibration.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto calibration = revolve::calibrate::ParseCalibration(
      std::string(reinterpret_cast<const char*>(data), size), "fuzz/calibration.toml");
  if (calibration) {
    const auto& k = calibration->camera.intrinsics;
    if (!std::isfinite(k.fx_px) || !std::isfinite(k.fy_px) || !std::isfinite(k.cx_px) ||
        !std::isfinite(k.cy_px)) {
      std::abort();
    }
    (void)calibration->ToRig();
    (void)calibration->CheckFrameSize(640, 480);
  }
  return 0;
}
