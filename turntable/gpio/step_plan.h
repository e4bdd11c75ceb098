// Step timing for a step/dir stepper driver: pure maths, planned apart from step emission.
#pragma once

#include <cstdint>
#include <vector>

namespace revolve::turntable::gpio {

// When each step of a rest-to-rest move happens. The move follows a trapezoid in step units
// (the same maths as MotionProfile): the k-th step (k = 1..n) is emitted when the planned
// position reaches k steps, so the first comes sqrt(2 / accel) after the start and the last at
// the end of the profile.
struct StepPlan {
  std::vector<std::int64_t> step_ns;  // time of step k+1 after the start, strictly increasing
  double duration_s = 0.0;            // time of the last step (0 for no steps)
  double peak_rate_hz = 0.0;          // highest step rate reached
};

// Plans `steps` (>= 0) steps at most `max_rate_hz` with acceleration and deceleration
// `accel_hz_s`. Contract: both rates finite and > 0.
StepPlan PlanSteps(std::int64_t steps, double max_rate_hz, double accel_hz_s);

}  // namespace revolve::turntable::gpio
