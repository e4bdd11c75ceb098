#include "turntable/motion_profile.h"

#include <cmath>
#include <tuple>

#include <gtest/gtest.h>

namespace revolve::turntable {
namespace {

constexpr MotionLimits kLimits{.speed_deg_per_s = 120.0, .acceleration_deg_per_s2 = 720.0};

TEST(MotionProfile, LongMoveIsATrapezoid) {
  // v^2 / a = 20 deg < 90 deg: ramps of v / a = 1/6 s, a cruise of (90 - 20) / 120 s.
  const MotionProfile profile(0.0, 90.0, kLimits);
  EXPECT_FALSE(profile.triangular());
  EXPECT_DOUBLE_EQ(profile.peak_speed_deg_per_s(), 120.0);
  EXPECT_DOUBLE_EQ(profile.accel_time_s(), 120.0 / 720.0);
  EXPECT_DOUBLE_EQ(profile.cruise_time_s(), 70.0 / 120.0);
  EXPECT_DOUBLE_EQ(profile.duration_s(), 90.0 / 120.0 + 120.0 / 720.0);
  // Each ramp covers v^2 / (2a) = 10 deg.
  EXPECT_NEAR(profile.PositionAt(profile.accel_time_s()), 10.0, 1e-12);
  EXPECT_NEAR(profile.PositionAt(profile.duration_s() - profile.accel_time_s()), 80.0, 1e-12);
}

TEST(MotionProfile, ShortMoveIsATriangle) {
  // 10 deg < v^2 / a = 20 deg: the speed limit is never reached.
  const MotionProfile profile(0.0, 10.0, kLimits);
  EXPECT_TRUE(profile.triangular());
  EXPECT_DOUBLE_EQ(profile.cruise_time_s(), 0.0);
  EXPECT_DOUBLE_EQ(profile.accel_time_s(), std::sqrt(10.0 / 720.0));
  EXPECT_DOUBLE_EQ(profile.duration_s(), 2.0 * std::sqrt(10.0 / 720.0));
  EXPECT_NEAR(profile.peak_speed_deg_per_s(), std::sqrt(10.0 * 720.0), 1e-9);
  EXPECT_LT(profile.peak_speed_deg_per_s(), kLimits.speed_deg_per_s);
  EXPECT_NEAR(profile.PositionAt(profile.duration_s() / 2.0), 5.0, 1e-12);
}

TEST(MotionProfile, DurationFormulaAndContinuityAtTheBoundary) {
  EXPECT_DOUBLE_EQ(MoveDurationS(0.0, kLimits), 0.0);
  EXPECT_DOUBLE_EQ(MoveDurationS(90.0, kLimits), 0.75 + 1.0 / 6.0);
  EXPECT_DOUBLE_EQ(MoveDurationS(-90.0, kLimits), 0.75 + 1.0 / 6.0);
  EXPECT_DOUBLE_EQ(MoveDurationS(5.0, kLimits), 2.0 * std::sqrt(5.0 / 720.0));
  const double boundary_deg = 120.0 * 120.0 / 720.0;
  const double expected_s = 2.0 * 120.0 / 720.0;
  EXPECT_NEAR(MoveDurationS(boundary_deg, kLimits), expected_s, 1e-12);
  EXPECT_NEAR(MoveDurationS(boundary_deg * (1 - 1e-9), kLimits), expected_s, 1e-9);
  EXPECT_NEAR(MoveDurationS(boundary_deg * (1 + 1e-9), kLimits), expected_s, 1e-9);
  // Duration grows with distance.
  double previous_s = 0.0;
  for (double d = 0.5; d < 400.0; d += 0.5) {
    const double duration_s = MoveDurationS(d, kLimits);
    EXPECT_GT(duration_s, previous_s) << d;
    previous_s = duration_s;
  }
}

TEST(MotionProfile, ZeroLengthMove) {
  const MotionProfile profile(42.0, 42.0, kLimits);
  EXPECT_DOUBLE_EQ(profile.duration_s(), 0.0);
  EXPECT_EQ(profile.PositionAt(0.0), 42.0);
  EXPECT_EQ(profile.PositionAt(1.0), 42.0);
  EXPECT_EQ(profile.VelocityAt(0.0), 0.0);
  const MotionProfile empty;
  EXPECT_EQ(empty.PositionAt(3.0), 0.0);
}

TEST(MotionProfile, EndsExactlyOnTheTargetAndStartsOnTheStart) {
  for (const auto& [start, target] :
       {std::pair{0.0, 10.0}, std::pair{350.0, 360.0}, std::pair{350.0, 0.0},
        std::pair{0.1, 123.456789}, std::pair{-17.3, 1e4 / 3.0}}) {
    const MotionProfile profile(start, target, kLimits);
    EXPECT_EQ(profile.PositionAt(profile.duration_s()), target);
    EXPECT_EQ(profile.PositionAt(profile.duration_s() + 10.0), target);
    EXPECT_EQ(profile.PositionAt(0.0), start);
    EXPECT_EQ(profile.PositionAt(-1.0), start);
    EXPECT_EQ(profile.VelocityAt(profile.duration_s()), 0.0);
  }
}

TEST(MotionProfile, AnglesAreAbsoluteAndMultiTurn) {
  // 350 -> 360 is a short step forward, 350 -> 0 turns almost a full revolution back.
  const MotionProfile forward(350.0, 360.0, kLimits);
  EXPECT_DOUBLE_EQ(forward.distance_deg(), 10.0);
  EXPECT_GT(forward.VelocityAt(forward.duration_s() / 2.0), 0.0);
  const MotionProfile back(350.0, 0.0, kLimits);
  EXPECT_DOUBLE_EQ(back.distance_deg(), 350.0);
  EXPECT_LT(back.VelocityAt(back.duration_s() / 2.0), 0.0);
  EXPECT_NEAR(back.PositionAt(back.duration_s() / 2.0), 175.0, 1e-9);
}

class MotionProfileShape
    : public testing::TestWithParam<std::tuple<double, double, double, double>> {};

// Sampled finely, the position moves monotonically toward the target, never faster than the
// peak speed, the velocity never changes faster than the acceleration, and the velocity is
// the derivative of the position.
TEST_P(MotionProfileShape, ContinuousMonotoneAndWithinLimits) {
  const auto [start, target, speed, acceleration] = GetParam();
  const MotionLimits limits{speed, acceleration};
  const MotionProfile profile(start, target, limits);
  EXPECT_NEAR(profile.duration_s(), MoveDurationS(target - start, limits), 1e-12);
  EXPECT_LE(profile.peak_speed_deg_per_s(), speed * (1 + 1e-12));
  const double direction = target >= start ? 1.0 : -1.0;
  const int steps = 20000;
  const double dt = profile.duration_s() / steps;
  double previous_position = profile.PositionAt(0.0);
  double previous_velocity = 0.0;
  for (int i = 1; i <= steps; ++i) {
    const double t = i * dt;
    const double position = profile.PositionAt(t);
    const double velocity = profile.VelocityAt(t);
    const double step = direction * (position - previous_position);
    ASSERT_GE(step, -1e-9) << "not monotone at t = " << t;
    ASSERT_LE(step, profile.peak_speed_deg_per_s() * dt * (1 + 1e-6) + 1e-9) << "jump at t = " << t;
    ASSERT_LE(std::abs(velocity - previous_velocity), acceleration * dt * (1 + 1e-6) + 1e-9)
        << "velocity jump at t = " << t;
    const double mid_velocity = profile.VelocityAt(t - dt / 2);
    ASSERT_NEAR(position - previous_position, mid_velocity * dt, acceleration * dt * dt + 1e-9)
        << "velocity is not the derivative at t = " << t;
    ASSERT_LE(direction * position, direction * target + 1e-12);
    previous_position = position;
    previous_velocity = velocity;
  }
  EXPECT_EQ(previous_position, target);
  // Symmetric: halfway in time is halfway in angle.
  EXPECT_NEAR(profile.PositionAt(profile.duration_s() / 2), (start + target) / 2, 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Moves, MotionProfileShape,
                         testing::Values(std::tuple{0.0, 10.0, 120.0, 720.0},
                                         std::tuple{0.0, 90.0, 120.0, 720.0},
                                         std::tuple{350.0, 0.0, 120.0, 720.0},
                                         std::tuple{10.0, 10.0 + 20.0, 120.0, 720.0},
                                         std::tuple{-5.0, 1000.0, 30.0, 50.0},
                                         std::tuple{720.0, 719.99, 360.0, 10000.0}));

}  // namespace
}  // namespace revolve::turntable
