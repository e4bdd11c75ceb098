#include "turntable/gpio/step_plan.h"

#include <algorithm>
#include <cmath>

#include "turntable/motion_profile.h"

namespace revolve::turntable::gpio {

StepPlan PlanSteps(std::int64_t steps, double max_rate_hz, double accel_hz_s) {
  StepPlan plan;
  if (steps <= 0) return plan;
  // MotionProfile works in any unit; here one "degree" is one step.
  const double distance = static_cast<double>(steps);
  const MotionProfile profile(0.0, distance, MotionLimits{max_rate_hz, accel_hz_s});
  const double t_accel = profile.accel_time_s();
  const double t_cruise = profile.cruise_time_s();
  const double peak = profile.peak_speed_deg_per_s();
  const double total = profile.duration_s();
  const double s_accel = 0.5 * accel_hz_s * t_accel * t_accel;
  plan.step_ns.reserve(static_cast<std::size_t>(steps));
  std::int64_t previous = -1;
  for (std::int64_t k = 1; k <= steps; ++k) {
    const double s = static_cast<double>(k);
    double t = 0.0;
    if (s <= s_accel) {
      t = std::sqrt(2.0 * s / accel_hz_s);
    } else if (s <= distance - s_accel) {
      t = t_accel + (s - s_accel) / peak;
    } else {
      t = total - std::sqrt(std::max(0.0, 2.0 * (distance - s) / accel_hz_s));
    }
    auto ns = static_cast<std::int64_t>(std::llround(t * 1e9));
    ns = std::max(ns, previous + 1);  // strictly increasing even where rounding ties
    plan.step_ns.push_back(ns);
    previous = ns;
  }
  plan.duration_s = static_cast<double>(plan.step_ns.back()) * 1e-9;
  plan.peak_rate_hz = peak;
  (void)t_cruise;
  return plan;
}

}  // namespace revolve::turntable::gpio
