// Point-to-point motion planning for a rotary axis: pure maths, no clock, no device.
//
// A move starts and ends at rest. The velocity ramps up at a constant acceleration, cruises at
// the speed limit, and ramps down at the same rate (a trapezoid). When the move is too short to
// reach the speed limit (distance < speed^2 / acceleration) the cruise phase vanishes and the
// velocity peaks halfway (a triangle). Times are in the drive's own seconds (the mock turntable
// maps them to the wall clock with its time_scale).
#pragma once

namespace revolve::turntable {

// Limits of a move. Contract: both finite and > 0.
struct MotionLimits {
  double speed_deg_per_s = 120.0;
  double acceleration_deg_per_s2 = 720.0;  // also the deceleration
};

// Duration of a rest-to-rest move over `distance_deg` (>= 0; the sign is ignored):
//   trapezoid (distance >= v^2 / a): distance / v + v / a
//   triangle  (distance <  v^2 / a): 2 * sqrt(distance / a)
// Both agree at the boundary, so the duration is continuous in the distance.
double MoveDurationS(double distance_deg, const MotionLimits& limits);

// One planned move from `start_deg` to `target_deg` (absolute angles, any real numbers: a move
// from 350 to 360 turns 10 deg forward, one from 350 to 0 turns 350 deg back).
class MotionProfile {
 public:
  // A move of zero length at 0 deg.
  MotionProfile() = default;

  // Contract: start_deg and target_deg finite; limits as documented on MotionLimits.
  MotionProfile(double start_deg, double target_deg, const MotionLimits& limits);

  double start_deg() const { return start_deg_; }
  double target_deg() const { return target_deg_; }
  double distance_deg() const { return distance_deg_; }  // |target - start|
  double duration_s() const { return duration_s_; }
  double accel_time_s() const { return accel_time_s_; }    // ramp up (= ramp down) time
  double cruise_time_s() const { return cruise_time_s_; }  // 0 for a triangle
  double peak_speed_deg_per_s() const { return peak_speed_deg_per_s_; }
  bool triangular() const { return cruise_time_s_ == 0.0; }

  // The angle `t_s` seconds after the move started: start_deg for t_s <= 0, exactly target_deg
  // for t_s >= duration_s(). Continuous and monotone (toward the target) in t_s.
  double PositionAt(double t_s) const;

  // The signed angular velocity at `t_s` (0 before the start and after the end). Continuous.
  double VelocityAt(double t_s) const;

 private:
  // Distance travelled along the move (0 .. distance_deg_) at `t_s`.
  double TravelAt(double t_s) const;

  double start_deg_ = 0.0;
  double target_deg_ = 0.0;
  double direction_ = 1.0;  // +1 or -1
  double distance_deg_ = 0.0;
  double acceleration_deg_per_s2_ = 1.0;
  double peak_speed_deg_per_s_ = 0.0;
  double accel_time_s_ = 0.0;
  double cruise_time_s_ = 0.0;
  double duration_s_ = 0.0;
};

}  // namespace revolve::turntable
