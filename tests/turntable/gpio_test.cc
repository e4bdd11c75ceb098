// The GPIO step/dir backend: the step plan (pure) and the turntable against a fake line seam
// that records every edge, on a virtual clock (deterministic, no real sleeping).
#include <cmath>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/config.h"
#include "turntable/gpio/step_dir_turntable.h"
#include "turntable/gpio/step_plan.h"
#ifdef REVOLVE_HAVE_GPIO
#include "turntable/gpio/libgpiod_lines.h"
#endif

namespace revolve::turntable::gpio {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;

// --- the plan ---

TEST(StepPlan, TrapezoidTimes) {
  const double rate = 1000.0;   // steps/s
  const double accel = 4000.0;  // steps/s^2: 0.25 s and 125 steps to full speed
  const StepPlan plan = PlanSteps(1000, rate, accel);
  ASSERT_EQ(plan.step_ns.size(), 1000u);
  EXPECT_NEAR(plan.step_ns[0] * 1e-9, std::sqrt(2.0 / accel), 1e-9);
  // Duration of a trapezoid: d / v + v / a.
  EXPECT_NEAR(plan.duration_s, 1000.0 / rate + rate / accel, 1e-6);
  EXPECT_DOUBLE_EQ(plan.peak_rate_hz, rate);
  for (std::size_t i = 1; i < plan.step_ns.size(); ++i) {
    const std::int64_t interval = plan.step_ns[i] - plan.step_ns[i - 1];
    ASSERT_GT(interval, 0);
    // Never faster than the cap (1 ms), within rounding.
    EXPECT_GE(interval, 999'999) << i;
    if (i > 130 && i < 870) {
      EXPECT_NEAR(interval, 1'000'000, 2) << i;  // cruise
    }
  }
  // Accelerating intervals shrink, decelerating ones grow; the profile is symmetric.
  EXPECT_GT(plan.step_ns[1] - plan.step_ns[0], plan.step_ns[2] - plan.step_ns[1]);
  EXPECT_LT(plan.step_ns[998] - plan.step_ns[997], plan.step_ns[999] - plan.step_ns[998]);
  // Positions 10 -> 11 mirror positions 989 -> 990 (index k holds position k + 1).
  EXPECT_NEAR(plan.step_ns[10] - plan.step_ns[9], plan.step_ns[989] - plan.step_ns[988], 2);
}

TEST(StepPlan, TriangleAndEmpty) {
  const StepPlan plan = PlanSteps(100, 1000.0, 4000.0);  // needs 250 steps to reach the cap
  ASSERT_EQ(plan.step_ns.size(), 100u);
  EXPECT_LT(plan.peak_rate_hz, 1000.0);
  EXPECT_NEAR(plan.duration_s, 2.0 * std::sqrt(100.0 / 4000.0), 1e-6);
  EXPECT_TRUE(PlanSteps(0, 1000.0, 4000.0).step_ns.empty());
  EXPECT_EQ(PlanSteps(1, 1000.0, 4000.0).step_ns.size(), 1u);
}

// --- fakes ---

class VirtualClock final : public StepClock {
 public:
  Clock::time_point Now() override {
    std::lock_guard lock(mutex_);
    return now_;
  }
  void SleepUntil(Clock::time_point until) override {
    std::lock_guard lock(mutex_);
    now_ = std::max(now_, until);
  }

 private:
  std::mutex mutex_;
  Clock::time_point now_ = Clock::now();
};

struct Edge {
  Line line;
  bool active;
  Clock::time_point t;
};

// Records every output change with the virtual time, and simulates the plate the driver turns:
// a STEP rising edge moves it one step in the DIR direction while ENABLE is asserted. The home
// switch is active over [home_at, home_at + home_width) plate steps; `bounce_at` adds a short
// false contact (an edge, but inactive again when the level is checked).
class FakeLines final : public StepDirLines {
 public:
  FakeLines(std::shared_ptr<StepClock> clock, bool has_enable, bool has_home)
      : clock_(std::move(clock)), has_enable_(has_enable), has_home_(has_home) {}

  Expected<void> Set(Line line, bool active) override {
    std::lock_guard lock(mutex_);
    if (line == Line::kEnable && !has_enable_) return {};
    edges.push_back({line, active, clock_->Now()});
    if (line == Line::kDir) dir_ = active;
    if (line == Line::kEnable) enable_ = active;
    if (line == Line::kStep && active) {
      if (!has_enable_ || enable_) plate_steps += dir_ ? 1 : -1;
      ++step_count;
      if (on_step) on_step(step_count);
      if (bounce_at && plate_steps == *bounce_at) pending_edge_ = true;
      const bool now_active = InSwitch();
      if (now_active && !last_active_) pending_edge_ = true;
      last_active_ = now_active;
    }
    return {};
  }
  bool HasEnable() const override { return has_enable_; }
  bool HasHome() const override { return has_home_; }
  Expected<bool> HomeActive() override {
    std::lock_guard lock(mutex_);
    return has_home_ && InSwitch();
  }
  Expected<bool> TakeHomeEdge() override {
    std::lock_guard lock(mutex_);
    return std::exchange(pending_edge_, false) && has_home_;
  }
  std::string Describe() const override { return "fake lines"; }

  std::vector<Edge> Of(Line line) const {
    std::vector<Edge> out;
    for (const Edge& e : edges) {
      if (e.line == line) out.push_back(e);
    }
    return out;
  }
  int Rising(Line line) const {
    int n = 0;
    for (const Edge& e : edges) n += e.line == line && e.active;
    return n;
  }

  std::vector<Edge> edges;
  std::int64_t plate_steps = 0;
  int step_count = 0;
  std::int64_t home_at = 1000;
  std::int64_t home_width = 50;
  std::optional<std::int64_t> bounce_at;
  std::function<void(int)> on_step;

 private:
  bool InSwitch() const { return plate_steps >= home_at && plate_steps < home_at + home_width; }

  std::shared_ptr<StepClock> clock_;
  const bool has_enable_;
  const bool has_home_;
  std::mutex mutex_;
  bool dir_ = false;
  bool enable_ = false;
  bool pending_edge_ = false;
  bool last_active_ = false;
};

// 200 full steps x 16 microsteps x gear 5 = 16000 steps per plate revolution.
GpioOptions Options() {
  GpioOptions o;
  o.full_steps_per_rev = 200;
  o.microsteps = 16;
  o.gear_ratio = 5.0;
  o.speed_deg_per_s = 30.0;          // 1333 steps/s
  o.acceleration_deg_per_s2 = 90.0;  // 4000 steps/s^2
  o.max_step_rate_hz = 2000.0;
  o.pulse_us = 5.0;
  o.dir_setup_us = 10.0;
  o.enable_settle_ms = 10.0;
  o.home_speed_deg_per_s = 45.0;
  o.home_debounce_ms = 5.0;
  o.home_max_deg = 400.0;
  return o;
}

struct Rig {
  std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
  FakeLines* lines = nullptr;  // owned by table
  std::shared_ptr<SimulatedPlate> plate = std::make_shared<SimulatedPlate>();
  std::unique_ptr<StepDirTurntable> table;
};

Rig MakeRig(GpioOptions options = Options(), bool has_enable = true, bool has_home = false) {
  Rig rig;
  auto lines = std::make_unique<FakeLines>(rig.clock, has_enable, has_home);
  rig.lines = lines.get();
  rig.table = std::make_unique<StepDirTurntable>(options, std::move(lines), rig.clock, rig.plate,
                                                 /*disable_at_end=*/true);
  return rig;
}

// Deadlines on the virtual clock (which runs ahead of real time: its sleeps return at once).
Clock::time_point In(const Rig& rig, Clock::duration d) { return rig.clock->Now() + d; }

TEST(StepDirTurntable, TenDegreeMoveFollowsThePlan) {
  Rig rig = MakeRig();
  const Clock::time_point t0 = rig.clock->Now();
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(rig, 10s)));
  // 10 deg of 16000 steps/rev = 444.4 -> 444 steps, all forward.
  EXPECT_EQ(rig.lines->Rising(Line::kStep), 444);
  EXPECT_EQ(rig.lines->plate_steps, 444);
  EXPECT_EQ(rig.table->position_steps(), 444);

  const std::vector<Edge> steps = rig.lines->Of(Line::kStep);
  const std::vector<Edge> dir = rig.lines->Of(Line::kDir);
  const std::vector<Edge> enable = rig.lines->Of(Line::kEnable);
  ASSERT_EQ(dir.size(), 1u);
  EXPECT_TRUE(dir[0].active);  // forward
  ASSERT_EQ(enable.size(), 1u);
  EXPECT_TRUE(enable[0].active);
  const Clock::time_point first_step = steps.front().t;
  EXPECT_GE(first_step - dir[0].t, 10us);     // dir_setup_us
  EXPECT_GE(first_step - enable[0].t, 10ms);  // enable_settle_ms
  EXPECT_GE(dir[0].t, t0);

  // Pulses: high for pulse_us, and the rising edges at exactly the planned times.
  const double rate = 30.0 / 360.0 * 16000.0;
  const double accel = 90.0 / 360.0 * 16000.0;
  const StepPlan plan = PlanSteps(444, rate, accel);
  const Clock::time_point start = first_step - std::chrono::nanoseconds(plan.step_ns[0]);
  int rising = 0;
  for (std::size_t i = 0; i < steps.size(); ++i) {
    if (steps[i].active) {
      EXPECT_EQ(steps[i].t - start, std::chrono::nanoseconds(plan.step_ns[rising])) << rising;
      ASSERT_LT(i + 1, steps.size());
      EXPECT_FALSE(steps[i + 1].active);
      EXPECT_EQ(steps[i + 1].t - steps[i].t, 5us);
      ++rising;
    }
  }
  EXPECT_EQ(rising, 444);

  Expected<TurntableState> state = rig.table->State();
  ASSERT_TRUE(state);
  EXPECT_TRUE(state->open_loop);
  EXPECT_TRUE(state->in_position);
  EXPECT_FALSE(state->moving);
  EXPECT_TRUE(state->enabled);
  EXPECT_NEAR(state->angle_deg, 444.0 / 16000.0 * 360.0, 1e-9);
  EXPECT_NEAR(rig.plate->angle_deg.load(), state->angle_deg, 1e-9);
  EXPECT_EQ(rig.table->overruns(), 0);
  EXPECT_THAT(rig.table->Describe(), HasSubstr("open loop"));
}

TEST(StepDirTurntable, ThirtySixStopsCountExactlyWithoutDrift) {
  Rig rig = MakeRig();
  for (int k = 0; k < 36; ++k) {
    ASSERT_TRUE(rig.table->MoveTo(k * 10.0, In(rig, 10s)));
    EXPECT_EQ(rig.table->position_steps(), std::llround(k * 10.0 / 360.0 * 16000.0)) << k;
  }
  EXPECT_EQ(rig.lines->plate_steps, 15556);  // 350 deg
  EXPECT_EQ(rig.lines->Rising(Line::kStep), 15556);
  EXPECT_EQ(rig.lines->Of(Line::kDir).size(), 1u);    // never turned back
  EXPECT_EQ(rig.lines->Rising(Line::kEnable), 1);     // enabled once
  ASSERT_TRUE(rig.table->MoveTo(0.0, In(rig, 60s)));  // 350 deg back
  EXPECT_EQ(rig.lines->plate_steps, 0);
  EXPECT_FALSE(rig.lines->Of(Line::kDir).back().active);
}

TEST(StepDirTurntable, ReverseDirectionFlipsDir) {
  GpioOptions options = Options();
  options.reverse = true;
  Rig rig = MakeRig(options);
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(rig, 10s)));
  EXPECT_FALSE(rig.lines->Of(Line::kDir).front().active);
  EXPECT_EQ(rig.lines->plate_steps, -444);  // the motor turns the other way
  EXPECT_NEAR(rig.table->State()->angle_deg, 444.0 / 16000.0 * 360.0, 1e-9);
}

TEST(StepDirTurntable, StepRateIsCapped) {
  GpioOptions options = Options();
  options.speed_deg_per_s = 360.0;  // 16 kHz wanted
  options.acceleration_deg_per_s2 = 3600.0;
  Rig rig = MakeRig(options);
  ASSERT_TRUE(rig.table->MoveTo(90.0, In(rig, 10s)));
  const std::vector<Edge> steps = rig.lines->Of(Line::kStep);
  Clock::time_point previous{};
  for (const Edge& e : steps) {
    if (!e.active) continue;
    if (previous != Clock::time_point{}) {
      EXPECT_GE(e.t - previous, 499us);  // 2 kHz cap
    }
    previous = e.t;
  }
}

TEST(StepDirTurntable, HomeStopsAtTheSwitchEdge) {
  Rig rig = MakeRig(Options(), true, true);
  rig.lines->home_at = 1000;
  ASSERT_TRUE(rig.table->Home(In(rig, 10s)));
  EXPECT_EQ(rig.lines->plate_steps, 1000);  // stopped on the step that closed the switch
  EXPECT_EQ(rig.table->position_steps(), 0);
  EXPECT_TRUE(rig.table->State()->homed);
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(rig, 10s)));
  EXPECT_EQ(rig.lines->plate_steps, 1444);
}

TEST(StepDirTurntable, HomeIgnoresABounce) {
  Rig rig = MakeRig(Options(), true, true);
  rig.lines->home_at = 1000;
  rig.lines->bounce_at = 900;  // an edge, but the switch is open again after the debounce
  ASSERT_TRUE(rig.table->Home(In(rig, 10s)));
  EXPECT_EQ(rig.lines->plate_steps, 1000);
  EXPECT_EQ(rig.table->position_steps(), 0);
}

TEST(StepDirTurntable, HomeStartingOnTheSwitchBacksOffFirst) {
  Rig rig = MakeRig(Options(), true, true);
  rig.lines->home_at = -10;  // the plate starts on the switch
  ASSERT_TRUE(rig.table->Home(In(rig, 10s)));
  EXPECT_EQ(rig.lines->plate_steps, -10);
  EXPECT_EQ(rig.table->position_steps(), 0);
}

TEST(StepDirTurntable, MissingSwitchIsNotFound) {
  GpioOptions options = Options();
  options.home_max_deg = 30.0;
  Rig rig = MakeRig(options, true, true);
  rig.lines->home_at = 100000;
  Expected<void> homed = rig.table->Home(In(rig, 10s));
  ASSERT_FALSE(homed);
  EXPECT_EQ(homed.error().code, ErrorCode::kNotFound);
  EXPECT_THAT(homed.error().message, HasSubstr("home switch did not trigger within 30 deg"));
  EXPECT_EQ(rig.lines->plate_steps, static_cast<std::int64_t>(std::ceil(30.0 / 360.0 * 16000.0)));
}

TEST(StepDirTurntable, HomeWithoutSwitchGoesToTheNearestWholeTurn) {
  Rig rig = MakeRig();
  ASSERT_TRUE(rig.table->MoveTo(370.0, In(rig, 60s)));
  ASSERT_TRUE(rig.table->Home(In(rig, 60s)));
  EXPECT_EQ(rig.lines->plate_steps, 16000);
  EXPECT_EQ(rig.table->position_steps(), 0);
  EXPECT_NEAR(rig.table->State()->angle_deg, 0.0, 1e-12);
}

TEST(StepDirTurntable, StopEndsTheMoveAfterTheCurrentStepAndCountsExactly) {
  Rig rig = MakeRig();
  rig.lines->on_step = [&](int n) {
    if (n == 100) rig.table->Stop();
  };
  Expected<void> moved = rig.table->MoveTo(90.0, In(rig, 60s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kAborted);
  EXPECT_EQ(rig.lines->plate_steps, 100);
  EXPECT_EQ(rig.table->position_steps(), 100);
  EXPECT_FALSE(rig.table->State()->moving);
  EXPECT_FALSE(rig.table->State()->in_position);
  rig.lines->on_step = nullptr;
  EXPECT_TRUE(rig.table->MoveTo(10.0, In(rig, 10s)));  // the next move works again
  EXPECT_EQ(rig.lines->plate_steps, 444);
}

TEST(StepDirTurntable, DeadlineStopsEmissionWithTimeout) {
  Rig rig = MakeRig();
  Expected<void> moved = rig.table->MoveTo(180.0, rig.clock->Now() + 500ms);
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kTimeout);
  EXPECT_GT(rig.table->position_steps(), 0);
  EXPECT_LT(rig.table->position_steps(), 8000);
  EXPECT_EQ(rig.table->position_steps(), rig.lines->plate_steps);
}

TEST(StepDirTurntable, DisableReleasesEnableUntilHome) {
  Rig rig = MakeRig();
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(rig, 10s)));
  ASSERT_TRUE(rig.table->Disable());
  EXPECT_FALSE(rig.lines->Of(Line::kEnable).back().active);
  EXPECT_FALSE(rig.table->State()->enabled);
  Expected<void> moved = rig.table->MoveTo(20.0, In(rig, 10s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kBadInput);
  ASSERT_TRUE(rig.table->Home(In(rig, 60s)));
  EXPECT_TRUE(rig.lines->Of(Line::kEnable).back().active);
}

TEST(StepDirTurntable, IdlePowerDownAndReenable) {
  GpioOptions options = Options();
  options.idle_disable_s = 0.05;
  Rig rig = MakeRig(options);
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(rig, 10s)));
  const auto until = Clock::now() + 2s;
  while (Clock::now() < until && rig.lines->Of(Line::kEnable).back().active) {
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_FALSE(rig.lines->Of(Line::kEnable).back().active);
  ASSERT_TRUE(rig.table->MoveTo(20.0, In(rig, 10s)));
  EXPECT_EQ(rig.lines->Rising(Line::kEnable), 2);
  EXPECT_EQ(rig.lines->plate_steps, 889);  // steps are not lost by powering down
}

// Lets a test keep the fake lines after the turntable that uses them is gone.
class SharedLines final : public StepDirLines {
 public:
  explicit SharedLines(std::shared_ptr<FakeLines> inner) : inner_(std::move(inner)) {}
  Expected<void> Set(Line line, bool active) override { return inner_->Set(line, active); }
  bool HasEnable() const override { return inner_->HasEnable(); }
  bool HasHome() const override { return inner_->HasHome(); }
  Expected<bool> HomeActive() override { return inner_->HomeActive(); }
  Expected<bool> TakeHomeEdge() override { return inner_->TakeHomeEdge(); }
  std::string Describe() const override { return inner_->Describe(); }

 private:
  std::shared_ptr<FakeLines> inner_;
};

TEST(StepDirTurntable, DestructorReleasesEnableWhenConfigured) {
  for (const bool disable_at_end : {true, false}) {
    auto clock = std::make_shared<VirtualClock>();
    auto lines = std::make_shared<FakeLines>(clock, true, false);
    auto table = std::make_unique<StepDirTurntable>(Options(), std::make_unique<SharedLines>(lines),
                                                    clock, nullptr, disable_at_end);
    ASSERT_TRUE(table->MoveTo(10.0, clock->Now() + 10s));
    table.reset();
    EXPECT_EQ(lines->Of(Line::kEnable).back().active, !disable_at_end);
  }
}

#ifdef REVOLVE_HAVE_GPIO
TEST(LibgpiodLines, MissingChipIsATypedError) {
  GpioOptions options = Options();
  options.chip = "revolve-no-such-gpiochip";
  options.step.offset = 1;
  options.dir.offset = 2;
  Expected<std::unique_ptr<StepDirLines>> lines = OpenLibgpiodLines(options);
  ASSERT_FALSE(lines);
  EXPECT_TRUE(lines.error().code == ErrorCode::kNotFound ||
              lines.error().code == ErrorCode::kNoDevice)
      << lines.error().ToString();
  EXPECT_THAT(lines.error().message, HasSubstr("revolve-no-such-gpiochip"));
}
#endif

// --- options ---

Expected<GpioOptions> Parse(const std::string& text) {
  Expected<config::Document> document = config::Parse(text, "gpio.toml");
  if (!document) return std::unexpected(document.error());
  Expected<config::Section> section = config::Section::Root(*document).Child("gpio");
  if (!section) return std::unexpected(section.error());
  return ParseGpioOptions(*section);
}

TEST(GpioOptionsParse, LinesByOffsetOrName) {
  Expected<GpioOptions> o = Parse(
      "[gpio]\nchip = \"pinctrl-bcm2711\"\nstep = 17\ndir = \"GPIO27\"\nenable = 22\n"
      "enable_active_low = true\nhome = \"GPIO5\"\nmicrosteps = 8\ngear_ratio = 4.5\n"
      "direction = \"reverse\"\nhome_direction = \"reverse\"\nidle_disable_s = 30\n");
  ASSERT_TRUE(o) << o.error().ToString();
  EXPECT_EQ(o->step.offset, 17);
  EXPECT_EQ(o->dir.name, "GPIO27");
  EXPECT_TRUE(o->enable.active_low);
  EXPECT_TRUE(o->home.active_low);  // default for a switch to ground
  EXPECT_EQ(o->home.name, "GPIO5");
  EXPECT_TRUE(o->reverse);
  EXPECT_TRUE(o->home_reverse);
  EXPECT_DOUBLE_EQ(o->StepsPerPlateRev(), 200 * 8 * 4.5);
}

TEST(GpioOptionsParse, ErrorsNameFileLineAndKey) {
  for (const auto& [text, expect] : std::vector<std::pair<std::string, std::string>>{
           {"[gpio]\ndir = 3\n", "gpio.step: is required"},
           {"[gpio]\nstep = 3\ndir = 3\n", "gpio.dir: must be another line"},
           {"[gpio]\nstep = 3\ndir = 4\nmicrosteps = 0\n", "gpio.toml:4:14: gpio.microsteps"},
           {"[gpio]\nstep = 3\ndir = 4\nstep_pin = 3\n",
            "gpio.toml:4:1: unknown key \"gpio.step_pin\""},
           {"[gpio]\nstep = 3\ndir = 4\npulse_us = 10\nmax_step_rate_hz = 90000\n",
            "no room for 10 us pulses"},
           {"[gpio]\nstep = true\ndir = 4\n", "gpio.step: expected a line offset"}}) {
    Expected<GpioOptions> o = Parse(text);
    ASSERT_FALSE(o) << text;
    EXPECT_THAT(o.error().message, HasSubstr(expect)) << text;
  }
}

}  // namespace
}  // namespace revolve::turntable::gpio
