#include "turntable/mock/mock_turntable.h"

#include <atomic>
#include <cmath>
#include <future>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace revolve::turntable {
namespace {

using namespace std::chrono_literals;
using testing::HasSubstr;

// Real-table parameters; `time_scale` sets how fast the test runs (0.01: a 90 deg move, 0.94 s
// on a real table, takes about 9 ms).
MockOptions Options(double time_scale, std::vector<MockFault> faults = {}) {
  MockOptions options;
  options.speed_deg_per_s = 120.0;
  options.acceleration_deg_per_s2 = 720.0;
  options.settle_ms = 20.0;
  options.time_scale = time_scale;
  options.tolerance_deg = 0.01;
  options.faults = std::move(faults);
  return options;
}

Clock::time_point In(Clock::duration d) { return Clock::now() + d; }

TurntableState StateOf(Turntable& table) {
  Expected<TurntableState> state = table.State();
  EXPECT_TRUE(state);
  return state.value_or(TurntableState{});
}

// Waits (bounded) until `predicate` holds; false when it never did.
template <class Predicate>
bool Eventually(Predicate predicate, Clock::duration limit = 5s) {
  const Clock::time_point end = In(limit);
  while (Clock::now() < end) {
    if (predicate()) return true;
    std::this_thread::sleep_for(200us);
  }
  return predicate();
}

TEST(MockTurntable, StartsEnabledNotHomedAtThePlateAngle) {
  auto plate = std::make_shared<SimulatedPlate>();
  plate->angle_deg = 37.0;
  MockTurntable table(Options(0.01), plate);
  const TurntableState state = StateOf(table);
  EXPECT_DOUBLE_EQ(state.angle_deg, 37.0);
  EXPECT_TRUE(state.enabled);
  EXPECT_FALSE(state.homed);
  EXPECT_FALSE(state.moving);
  EXPECT_TRUE(state.in_position);
  EXPECT_FALSE(state.open_loop);
  EXPECT_FALSE(state.alarm_code);
  EXPECT_THAT(table.Describe(), HasSubstr("mock"));
}

TEST(MockTurntable, MoveToReachesTheTargetAndReportsInPosition) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(Options(0.01), plate);
  ASSERT_TRUE(table.MoveTo(10.0, In(5s)));
  const TurntableState state = StateOf(table);
  EXPECT_NEAR(state.angle_deg, 10.0, 0.01);
  EXPECT_TRUE(state.in_position);
  EXPECT_FALSE(state.moving);
  EXPECT_TRUE(state.enabled);
  EXPECT_FALSE(state.homed);  // allowed before Home, but not homed
  EXPECT_EQ(plate->angle_deg.load(), 10.0);
  EXPECT_FALSE(plate->moving.load());
}

TEST(MockTurntable, AFullScanOfStopsIsAbsoluteAndMultiTurn) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(Options(0.005), plate);
  ASSERT_TRUE(table.Home(In(5s)));
  EXPECT_TRUE(StateOf(table).homed);
  for (int k = 1; k <= 36; ++k) {
    const double target_deg = 10.0 * k;
    ASSERT_TRUE(table.MoveTo(target_deg, In(5s))) << k;
    const TurntableState state = StateOf(table);
    EXPECT_EQ(state.angle_deg, target_deg);
    EXPECT_TRUE(state.in_position);
    EXPECT_EQ(plate->angle_deg.load(), target_deg);
  }
  // 360 is one turn further than 0, not 0 again: the last move was a 10 deg step.
  EXPECT_EQ(StateOf(table).angle_deg, 360.0);
  EXPECT_EQ(table.RealMoveDuration(350.0, 360.0), table.RealMoveDuration(0.0, 10.0));
  EXPECT_GT(table.RealMoveDuration(350.0, 0.0), table.RealMoveDuration(350.0, 360.0));
}

TEST(MockTurntable, HomeGoesToTheNearestTurnAndZeroesTheCounter) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(Options(0.01), plate);
  ASSERT_TRUE(table.MoveTo(370.0, In(5s)));
  ASSERT_TRUE(table.Home(In(5s)));
  const TurntableState state = StateOf(table);
  EXPECT_EQ(state.angle_deg, 0.0);
  EXPECT_TRUE(state.homed);
  EXPECT_TRUE(state.in_position);
  EXPECT_EQ(plate->angle_deg.load(), 0.0);
}

TEST(MockTurntable, ThePlateFollowsDuringAMove) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(Options(0.25), plate);  // 90 deg: about 0.23 s
  std::vector<double> moving_samples;
  std::atomic<bool> done = false;
  std::jthread sampler([&] {
    while (!done) {
      if (plate->moving) moving_samples.push_back(plate->angle_deg);
      std::this_thread::sleep_for(500us);
    }
  });
  ASSERT_TRUE(table.MoveTo(90.0, In(10s)));
  done = true;
  sampler.join();
  int between = 0;
  for (std::size_t i = 0; i < moving_samples.size(); ++i) {
    EXPECT_GE(moving_samples[i], 0.0);
    EXPECT_LE(moving_samples[i], 90.0);
    if (i > 0) {
      EXPECT_GE(moving_samples[i], moving_samples[i - 1]) << "plate went backwards";
    }
    if (moving_samples[i] > 1.0 && moving_samples[i] < 89.0) ++between;
  }
  EXPECT_GE(between, 5) << "the plate did not report intermediate angles";
  EXPECT_EQ(plate->angle_deg.load(), 90.0);
  EXPECT_FALSE(plate->moving.load());
}

TEST(MockTurntable, SettleTimeComesBeforeInPosition) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockOptions options = Options(1.0);
  options.settle_ms = 500.0;
  MockTurntable table(options, plate);
  auto move = std::async(std::launch::async, [&] { return table.MoveTo(1.0, In(10s)); });
  TurntableState settling;
  ASSERT_TRUE(Eventually([&] {
    settling = StateOf(table);
    return !settling.moving && settling.angle_deg == 1.0;
  }));
  if (!settling.in_position) {  // normally; a very late poll may already see the end
    EXPECT_TRUE(plate->moving.load()) << "the plate still rings while settling";
  }
  ASSERT_TRUE(move.get());
  EXPECT_TRUE(StateOf(table).in_position);
  EXPECT_FALSE(plate->moving.load());
}

TEST(MockTurntable, DeadlineGivesTimeoutWithTheMotorStopped) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(Options(1.0), plate);  // 180 deg: 1.7 s
  Expected<void> moved = table.MoveTo(180.0, In(50ms));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kTimeout);
  const TurntableState state = StateOf(table);
  EXPECT_FALSE(state.moving);
  EXPECT_FALSE(state.in_position);
  EXPECT_GT(state.angle_deg, 0.0);
  EXPECT_LT(state.angle_deg, 180.0);
  EXPECT_FALSE(plate->moving.load());
  std::this_thread::sleep_for(20ms);
  EXPECT_EQ(StateOf(table).angle_deg, state.angle_deg) << "the motor kept turning";
  EXPECT_EQ(plate->angle_deg.load(), state.angle_deg);
}

TEST(MockTurntable, APassedDeadlineDoesNotMove) {
  MockTurntable table(Options(0.01), nullptr);
  Expected<void> moved = table.MoveTo(10.0, Clock::now() - 1ms);
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kTimeout);
  EXPECT_EQ(StateOf(table).angle_deg, 0.0);
}

TEST(MockTurntable, StopFromAnotherThreadAbortsAMovePromptly) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(Options(1.0), plate);  // 3600 deg: 30 s
  auto move = std::async(std::launch::async, [&] { return table.MoveTo(3600.0, In(60s)); });
  ASSERT_TRUE(Eventually([&] { return plate->angle_deg > 1.0; }));
  table.Stop();
  ASSERT_EQ(move.wait_for(2s), std::future_status::ready) << "Stop() did not end the move";
  Expected<void> moved = move.get();
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kAborted);
  const TurntableState state = StateOf(table);
  EXPECT_FALSE(state.moving);
  EXPECT_FALSE(state.in_position);
  EXPECT_TRUE(state.enabled);
  EXPECT_LT(state.angle_deg, 3600.0);
  EXPECT_FALSE(plate->moving.load());
  std::this_thread::sleep_for(10ms);
  EXPECT_EQ(StateOf(table).angle_deg, state.angle_deg);
  // The drive works on afterwards; Stop() while idle is harmless.
  table.Stop();
  MockTurntable fast(Options(0.01), nullptr);
  ASSERT_TRUE(fast.MoveTo(5.0, In(5s)));
}

TEST(MockTurntable, OnlyOneMoveAtATime) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(Options(1.0), plate);
  auto move = std::async(std::launch::async, [&] { return table.MoveTo(3600.0, In(60s)); });
  ASSERT_TRUE(Eventually([&] { return plate->moving.load(); }));
  Expected<void> second = table.MoveTo(10.0, In(1s));
  ASSERT_FALSE(second);
  EXPECT_EQ(second.error().code, ErrorCode::kBusy);
  Expected<void> home = table.Home(In(1s));
  ASSERT_FALSE(home);
  EXPECT_EQ(home.error().code, ErrorCode::kBusy);
  table.Stop();
  EXPECT_EQ(move.get().error().code, ErrorCode::kAborted);
}

TEST(MockTurntable, DisableAbortsAMoveAndADisabledDriveRefusesMovesUntilHome) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(Options(1.0), plate);
  auto move = std::async(std::launch::async, [&] { return table.MoveTo(3600.0, In(60s)); });
  ASSERT_TRUE(Eventually([&] { return plate->angle_deg > 1.0; }));
  ASSERT_TRUE(table.Disable());
  ASSERT_EQ(move.wait_for(2s), std::future_status::ready);
  EXPECT_EQ(move.get().error().code, ErrorCode::kAborted);
  EXPECT_FALSE(StateOf(table).enabled);

  Expected<void> refused = table.MoveTo(10.0, In(1s));
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(refused.error().message, HasSubstr("disabled"));
}

TEST(MockTurntable, HomeEnablesADisabledDrive) {
  MockTurntable table(Options(0.01), nullptr);
  ASSERT_TRUE(table.Home(In(5s)));
  ASSERT_TRUE(table.Disable());
  TurntableState state = StateOf(table);
  EXPECT_FALSE(state.enabled);
  EXPECT_TRUE(state.homed);  // the encoder keeps counting while de-energized
  ASSERT_TRUE(table.Home(In(5s)));
  state = StateOf(table);
  EXPECT_TRUE(state.enabled);
  EXPECT_TRUE(state.homed);
  EXPECT_TRUE(table.MoveTo(20.0, In(5s)));
}

TEST(MockTurntable, NonFiniteTargetIsBadInput) {
  MockTurntable table(Options(0.01), nullptr);
  EXPECT_EQ(table.MoveTo(std::nan(""), In(1s)).error().code, ErrorCode::kBadInput);
  EXPECT_EQ(table.MoveTo(INFINITY, In(1s)).error().code, ErrorCode::kBadInput);
}

TEST(MockTurntableFaults, StallGivesStalledAtTheDeadline) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(Options(0.01, {MockFault{.kind = MockFault::Kind::kStall}}), plate);
  Expected<void> moved = table.MoveTo(90.0, In(100ms));  // would take 9 ms without the fault
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kStalled);
  const TurntableState state = StateOf(table);
  EXPECT_NEAR(state.angle_deg, 45.0, 1e-9);  // halfway in time is halfway in angle
  EXPECT_FALSE(state.moving);
  EXPECT_FALSE(state.in_position);
  EXPECT_FALSE(plate->moving.load());
  // One move only: the next one works.
  EXPECT_TRUE(table.MoveTo(90.0, In(5s)));
}

TEST(MockTurntableFaults, AStalledDriveStillReportsMoving) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockTurntable table(
      Options(0.01, {MockFault{.kind = MockFault::Kind::kStall, .at_fraction = 0.25}}), plate);
  auto move = std::async(std::launch::async, [&] { return table.MoveTo(90.0, In(60s)); });
  ASSERT_TRUE(Eventually([&] { return StateOf(table).angle_deg > 0.0; }));
  std::this_thread::sleep_for(30ms);  // well past the 9 ms the move would take
  const TurntableState state = StateOf(table);
  EXPECT_TRUE(state.moving);
  EXPECT_FALSE(state.in_position);
  EXPECT_LT(state.angle_deg, 45.0);
  EXPECT_FALSE(plate->moving.load()) << "a stalled plate stands still";
  table.Stop();
  EXPECT_EQ(move.get().error().code, ErrorCode::kAborted);
}

TEST(MockTurntableFaults, AlarmLatchesUntilHome) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockFault alarm{.kind = MockFault::Kind::kAlarm, .alarm_code = 0x42, .alarm_text = "overheat"};
  MockTurntable table(Options(0.01, {alarm}), plate);
  Expected<void> moved = table.MoveTo(90.0, In(5s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kAlarm);
  EXPECT_THAT(moved.error().message, HasSubstr("0x42"));
  EXPECT_THAT(moved.error().message, HasSubstr("overheat"));
  TurntableState state = StateOf(table);
  EXPECT_EQ(state.alarm_code, 0x42);
  EXPECT_EQ(state.alarm_text, "overheat");
  EXPECT_FALSE(state.enabled);
  EXPECT_FALSE(state.moving);
  EXPECT_FALSE(state.in_position);
  EXPECT_NEAR(state.angle_deg, 45.0, 1e-9);
  EXPECT_FALSE(plate->moving.load());

  Expected<void> latched = table.MoveTo(10.0, In(5s));
  ASSERT_FALSE(latched);
  EXPECT_EQ(latched.error().code, ErrorCode::kAlarm);
  EXPECT_EQ(StateOf(table).angle_deg, state.angle_deg);

  ASSERT_TRUE(table.Home(In(5s)));
  state = StateOf(table);
  EXPECT_FALSE(state.alarm_code);
  EXPECT_TRUE(state.alarm_text.empty());
  EXPECT_TRUE(state.enabled);
  EXPECT_TRUE(state.homed);
  EXPECT_EQ(state.angle_deg, 0.0);
  EXPECT_TRUE(table.MoveTo(90.0, In(5s)));
}

TEST(MockTurntableFaults, LinkDownHitsTheChosenMovesAndIsTransient) {
  auto plate = std::make_shared<SimulatedPlate>();
  MockFault link{
      .kind = MockFault::Kind::kLinkDown, .move_index = 1, .count = 2, .at_fraction = 0.0};
  MockTurntable table(Options(0.01, {link}), plate);
  ASSERT_TRUE(table.MoveTo(10.0, In(5s)));  // move 0
  for (int i = 0; i < 2; ++i) {             // moves 1 and 2
    Expected<void> moved = table.MoveTo(20.0, In(5s));
    ASSERT_FALSE(moved) << i;
    EXPECT_EQ(moved.error().code, ErrorCode::kLinkDown);
    const TurntableState state = StateOf(table);
    EXPECT_EQ(state.angle_deg, 10.0) << "at_fraction 0 fails before the plate moves";
    EXPECT_FALSE(state.moving);
    EXPECT_TRUE(state.enabled);
  }
  ASSERT_TRUE(table.MoveTo(20.0, In(5s)));  // move 3
  EXPECT_EQ(StateOf(table).angle_deg, 20.0);
}

TEST(MockTurntableFaults, HomeIsNeverFaultedAndRejectedMovesAreNotCounted) {
  MockTurntable table(Options(0.01, {MockFault{.kind = MockFault::Kind::kLinkDown}}), nullptr);
  ASSERT_TRUE(table.Home(In(5s)));
  ASSERT_TRUE(table.Disable());
  EXPECT_EQ(table.MoveTo(10.0, In(5s)).error().code, ErrorCode::kBadInput);  // not counted
  ASSERT_TRUE(table.Home(In(5s)));
  EXPECT_EQ(table.MoveTo(10.0, In(5s)).error().code, ErrorCode::kLinkDown);  // move 0
  EXPECT_TRUE(table.MoveTo(10.0, In(5s)));
}

}  // namespace
}  // namespace revolve::turntable
