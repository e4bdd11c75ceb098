// Degree/radian conversions and angle wrapping.
#pragma once

#include <cmath>
#include <numbers>

namespace revolve {

inline double Radians(double deg) { return deg * std::numbers::pi / 180.0; }
inline double Degrees(double rad) { return rad * 180.0 / std::numbers::pi; }

// An angle difference wrapped to (-180, 180].
inline double WrapDeg(double deg) {
  double w = std::fmod(deg, 360.0);
  if (w <= -180.0) w += 360.0;
  if (w > 180.0) w -= 360.0;
  return w;
}

}  // namespace revolve
