#include "turntable/motion_profile.h"

#include <cmath>

namespace revolve::turntable {

double MoveDurationS(double distance_deg, const MotionLimits& limits) {
  const double d = std::abs(distance_deg);
  const double v = limits.speed_deg_per_s;
  const double a = limits.acceleration_deg_per_s2;
  if (d >= v * v / a) return d / v + v / a;
  return 2.0 * std::sqrt(d / a);
}

MotionProfile::MotionProfile(double start_deg, double target_deg, const MotionLimits& limits)
    : start_deg_(start_deg),
      target_deg_(target_deg),
      direction_(target_deg >= start_deg ? 1.0 : -1.0),
      distance_deg_(std::abs(target_deg - start_deg)),
      acceleration_deg_per_s2_(limits.acceleration_deg_per_s2) {
  const double v = limits.speed_deg_per_s;
  const double a = limits.acceleration_deg_per_s2;
  if (distance_deg_ >= v * v / a) {
    peak_speed_deg_per_s_ = v;
    accel_time_s_ = v / a;
    cruise_time_s_ = (distance_deg_ - v * v / a) / v;
  } else {
    accel_time_s_ = std::sqrt(distance_deg_ / a);
    peak_speed_deg_per_s_ = a * accel_time_s_;
    cruise_time_s_ = 0.0;
  }
  duration_s_ = 2.0 * accel_time_s_ + cruise_time_s_;
}

double MotionProfile::TravelAt(double t_s) const {
  const double a = acceleration_deg_per_s2_;
  if (t_s <= 0.0) return 0.0;
  if (t_s >= duration_s_) return distance_deg_;
  if (t_s < accel_time_s_) return 0.5 * a * t_s * t_s;
  if (t_s < accel_time_s_ + cruise_time_s_) {
    return 0.5 * a * accel_time_s_ * accel_time_s_ + peak_speed_deg_per_s_ * (t_s - accel_time_s_);
  }
  // Ramp down, written from the end so that it lands on distance_deg_ without rounding drift.
  const double remaining_s = duration_s_ - t_s;
  return distance_deg_ - 0.5 * a * remaining_s * remaining_s;
}

double MotionProfile::PositionAt(double t_s) const {
  if (t_s >= duration_s_) return target_deg_;
  return start_deg_ + direction_ * TravelAt(t_s);
}

double MotionProfile::VelocityAt(double t_s) const {
  if (t_s <= 0.0 || t_s >= duration_s_) return 0.0;
  const double a = acceleration_deg_per_s2_;
  double speed = peak_speed_deg_per_s_;
  if (t_s < accel_time_s_) {
    speed = a * t_s;
  } else if (t_s >= accel_time_s_ + cruise_time_s_) {
    speed = a * (duration_s_ - t_s);
  }
  return direction_ * speed;
}

}  // namespace revolve::turntable
