// The option keys every real motor drive shares ([turntable.modbus], [turntable.gpio]).
#pragma once

#include <string>

#include "config/reader.h"

namespace revolve::turntable {

// Reads gear_ratio (0, 1000], direction ("forward" | "reverse", into `reverse`),
// speed_deg_per_s (0, 3600] and acceleration_deg_per_s2 (0, 100000] into `o`, in that order.
template <class DriveOptions>
void ReadDriveMotion(config::Reader& r, DriveOptions& o) {
  r.NumberAbove("gear_ratio", o.gear_ratio, 0.0, 1000.0);
  std::string direction = "forward";
  r.String("direction", direction, {"forward", "reverse"});
  o.reverse = direction == "reverse";
  r.NumberAbove("speed_deg_per_s", o.speed_deg_per_s, 0.0, 3600.0);
  r.NumberAbove("acceleration_deg_per_s2", o.acceleration_deg_per_s2, 0.0, 100000.0);
}

}  // namespace revolve::turntable
