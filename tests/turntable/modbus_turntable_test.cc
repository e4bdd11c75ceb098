// ModbusTurntable against the in-process simulated drive (the libmodbus seam): moves, homing,
// every fault kind, retries, stop/disable, idle power-down; and the simulator's own behaviour.
#include "turntable/modbus/modbus_turntable.h"

#include <cmath>
#include <filesystem>
#include <future>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "sim_transport.h"
#include "turntable/modbus/sim_drive.h"

namespace revolve::turntable::modbus {
namespace {

using namespace std::chrono_literals;
using test_support::SimTransport;
using testing::HasSubstr;
namespace fs = std::filesystem;
using SteadyClock = std::chrono::steady_clock;

const fs::path kProfileDir = fs::path(REVOLVE_SOURCE_DIR) / "turntable/modbus/profiles";

DriveProfile Profile(const std::string& name) {
  Expected<DriveProfile> profile = LoadProfileFile(kProfileDir / (name + ".toml"));
  EXPECT_TRUE(profile) << profile.error().ToString();
  return profile.value_or(DriveProfile{});
}

// A fast table: 10 deg in about 35 ms.
ModbusOptions FastOptions() {
  ModbusOptions o;
  o.speed_deg_per_s = 3600.0;
  o.acceleration_deg_per_s2 = 36000.0;
  o.poll_ms = 2.0;
  o.stall_timeout_ms = 150.0;
  o.tolerance_deg = 0.05;
  o.retries = 2;
  return o;
}

struct Rig {
  std::shared_ptr<SimulatedDrive> drive;
  SimTransport* transport = nullptr;  // owned by table
  std::shared_ptr<SimulatedPlate> plate = std::make_shared<SimulatedPlate>();
  std::unique_ptr<ModbusTurntable> table;

  SimSnapshot Snapshot(std::chrono::milliseconds later = 0ms) {
    return drive->Inspect(SteadyClock::now() + later);
  }
};

Rig MakeRig(const std::string& profile_name, std::vector<SimFault> faults = {},
            ModbusOptions options = FastOptions(), bool disable_at_end = true) {
  Rig rig;
  SimDriveOptions sim;
  sim.faults = std::move(faults);
  sim.watchdog_ms = 300.0;
  sim.default_accel_hz_s = 1e6;  // for profiles whose move gives no acceleration (MKS)
  sim.alarm_code = 0x31;
  Expected<std::unique_ptr<SimulatedDrive>> drive =
      SimulatedDrive::Create(Profile(profile_name), sim);
  EXPECT_TRUE(drive) << drive.error().ToString();
  rig.drive = std::move(*drive);
  auto transport = std::make_unique<SimTransport>(rig.drive);
  rig.transport = transport.get();
  rig.table = std::make_unique<ModbusTurntable>(options, Profile(profile_name),
                                                std::move(transport), rig.plate, disable_at_end);
  return rig;
}

Clock::time_point In(Clock::duration d) { return Clock::now() + d; }

template <class Predicate>
bool WaitUntil(Predicate predicate, std::chrono::milliseconds timeout) {
  const auto until = Clock::now() + timeout;
  while (Clock::now() < until) {
    if (predicate()) return true;
    std::this_thread::sleep_for(5ms);
  }
  return predicate();
}

double CountsFor(double angle_deg, double steps_per_rev) {
  return std::round(angle_deg / 360.0 * steps_per_rev);
}

TEST(ModbusTurntable, ThirtySixStopsOfTenDegrees) {
  Rig rig = MakeRig("generic");
  ASSERT_TRUE(rig.table->Home(In(2s)));
  for (int k = 0; k < 36; ++k) {
    const double target = k * 10.0;
    Expected<void> moved = rig.table->MoveTo(target, In(2s));
    ASSERT_TRUE(moved) << k << ": " << moved.error().ToString();
    Expected<TurntableState> state = rig.table->State();
    ASSERT_TRUE(state);
    // Within the tolerance of the commanded count, which is within half a count of the angle.
    EXPECT_NEAR(state->angle_deg, target, 0.06) << k;
    EXPECT_TRUE(state->in_position);
    EXPECT_FALSE(state->moving);
    EXPECT_TRUE(state->homed);
    EXPECT_TRUE(state->enabled);
    EXPECT_FALSE(state->open_loop);
    EXPECT_FALSE(state->alarm_code);
    // The drive was told exactly 10 deg per stop, and the plate shows the read-back angle.
    SimSnapshot s = rig.Snapshot();
    EXPECT_EQ(s.target_counts, CountsFor(target, 3200)) << k;
    EXPECT_FALSE(s.moving);
    EXPECT_NEAR(rig.plate->angle_deg.load(), target, 0.06);
    EXPECT_FALSE(rig.plate->moving.load());
  }
  EXPECT_EQ(rig.Snapshot().moves_started, 36);
  EXPECT_THAT(rig.table->Describe(), HasSubstr("profile generic"));
}

TEST(ModbusTurntable, EveryShippedProfileDrivesTheSimulator) {
  for (const std::string name : {"generic", "mks_servo42d", "leadshine_pr", "oriental_az"}) {
    SCOPED_TRACE(name);
    ModbusOptions options = FastOptions();
    options.gear_ratio = 3.0;
    options.reverse = name == "leadshine_pr";
    Rig rig = MakeRig(name, {}, options);
    Expected<void> homed = rig.table->Home(In(2s));
    ASSERT_TRUE(homed) << homed.error().ToString();
    for (double target : {10.0, 20.0, 350.0, 360.0, 0.0, -10.0}) {
      Expected<void> moved = rig.table->MoveTo(target, In(2s));
      ASSERT_TRUE(moved) << target << ": " << moved.error().ToString();
      Expected<TurntableState> state = rig.table->State();
      ASSERT_TRUE(state);
      EXPECT_NEAR(state->angle_deg, target, 0.07);  // tolerance + half a count
      EXPECT_TRUE(state->in_position);
      const double counts =
          CountsFor(target, static_cast<double>(rig.drive->profile().steps_per_rev) * 3.0);
      EXPECT_EQ(rig.Snapshot().target_counts, options.reverse ? -counts : counts);
    }
  }
}

TEST(ModbusTurntable, HomeMakesTheDriveHomeTheZero) {
  Rig rig = MakeRig("generic");
  ASSERT_TRUE(rig.table->MoveTo(90.0, In(2s)));  // allowed before homing
  EXPECT_FALSE(rig.table->State()->homed);
  ASSERT_TRUE(rig.table->Home(In(2s)));
  EXPECT_TRUE(rig.Snapshot().homed);
  EXPECT_NEAR(rig.Snapshot().position_counts, 0.0, 0.5);
  EXPECT_NEAR(rig.table->State()->angle_deg, 0.0, 1e-9);
}

TEST(ModbusTurntable, AlarmDuringMoveIsTypedLatchedAndResetByHome) {
  Rig rig = MakeRig("generic", {SimFault{SimFault::Kind::kAlarm, 2, 0.5, 0, 0x31}});
  ASSERT_TRUE(rig.table->Home(In(2s)));
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(2s)));
  ASSERT_TRUE(rig.table->MoveTo(20.0, In(2s)));
  const auto start = Clock::now();
  Expected<void> moved = rig.table->MoveTo(30.0, In(2s));
  ASSERT_FALSE(moved);
  EXPECT_LT(Clock::now() - start, 1s);
  EXPECT_EQ(moved.error().code, ErrorCode::kAlarm);
  EXPECT_THAT(moved.error().message, HasSubstr("alarm 0x31"));
  EXPECT_THAT(moved.error().message, HasSubstr("position error too large"));  // profile's words
  SimSnapshot s = rig.Snapshot();
  EXPECT_FALSE(s.moving);
  EXPECT_NEAR(s.position_counts, CountsFor(25.0, 3200), 2.0);  // stopped halfway
  Expected<TurntableState> state = rig.table->State();
  ASSERT_TRUE(state);
  EXPECT_EQ(state->alarm_code, 0x31);
  EXPECT_THAT(state->alarm_text, HasSubstr("position error"));
  // Latched: the next move fails without moving; Home() resets it.
  Expected<void> again = rig.table->MoveTo(30.0, In(2s));
  ASSERT_FALSE(again);
  EXPECT_EQ(again.error().code, ErrorCode::kAlarm);
  ASSERT_TRUE(rig.table->Home(In(2s)));
  EXPECT_FALSE(rig.table->State()->alarm_code);
  EXPECT_TRUE(rig.table->MoveTo(30.0, In(2s)));
}

TEST(ModbusTurntable, StallIsDetectedAndTheMotorStopped) {
  Rig rig = MakeRig("mks_servo42d", {SimFault{SimFault::Kind::kStall, 1, 0.4, 0, 0}});
  ASSERT_TRUE(rig.table->Home(In(2s)));
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(2s)));
  const auto start = Clock::now();
  Expected<void> moved = rig.table->MoveTo(20.0, In(3s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kStalled);
  EXPECT_THAT(moved.error().message, HasSubstr("stopped turning"));
  EXPECT_LT(Clock::now() - start, 1s);  // stall_timeout_ms 150, far before the deadline
  EXPECT_FALSE(rig.Snapshot().moving);  // "stop" was sent
}

TEST(ModbusTurntable, StallNearTheDeadlineIsStalledNotTimeout) {
  ModbusOptions options = FastOptions();
  options.stall_timeout_ms = 5000.0;  // longer than the deadline
  Rig rig = MakeRig("generic", {SimFault{SimFault::Kind::kStall, 0, 0.3, 0, 0}}, options);
  Expected<void> moved = rig.table->MoveTo(90.0, In(400ms));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kStalled);
  EXPECT_FALSE(rig.Snapshot().moving);
}

TEST(ModbusTurntable, SlowMovePastTheDeadlineIsTimeout) {
  ModbusOptions options = FastOptions();
  options.speed_deg_per_s = 90.0;
  options.acceleration_deg_per_s2 = 900.0;
  Rig rig = MakeRig("generic", {}, options);
  const auto start = Clock::now();
  Expected<void> moved = rig.table->MoveTo(180.0, In(200ms));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kTimeout);
  EXPECT_LT(Clock::now() - start, 400ms);
  EXPECT_FALSE(rig.Snapshot().moving);
}

TEST(ModbusTurntable, NoReplyIsLinkDownAfterBoundedRetries) {
  Rig rig = MakeRig("generic", {SimFault{SimFault::Kind::kNoReply, 1, 0, 0, 0}});
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(2s)));
  const int before = rig.transport->requests();
  Expected<void> moved = rig.table->MoveTo(20.0, In(2s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kLinkDown);
  EXPECT_THAT(moved.error().message, HasSubstr("no reply"));
  EXPECT_THAT(moved.error().message, HasSubstr("after 3 attempts"));
  // The move's first write (FC16 target) got through; the trigger was lost: 3 tries, then 3
  // tries of "stop"; nothing more.
  EXPECT_EQ(rig.transport->requests() - before, 7);
  EXPECT_FALSE(rig.Snapshot().moving);  // the lost command never started a move
}

TEST(ModbusTurntable, OneLostReplyIsRetriedTransparently) {
  Rig rig = MakeRig("generic", {SimFault{SimFault::Kind::kNoReply, 1, 0, 1, 0}});
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(2s)));
  Expected<void> moved = rig.table->MoveTo(20.0, In(2s));
  ASSERT_TRUE(moved) << moved.error().ToString();
  EXPECT_EQ(rig.transport->recoveries(), 1);
  EXPECT_NEAR(rig.table->State()->angle_deg, 20.0, 0.05);
}

TEST(ModbusTurntable, ExceptionResponseIsProtocolAndNotRetried) {
  Rig rig = MakeRig("generic", {SimFault{SimFault::Kind::kException, 0, 0, 1, 0x02}});
  Expected<void> moved = rig.table->MoveTo(10.0, In(2s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kProtocol);
  EXPECT_THAT(moved.error().message, HasSubstr("illegal data address"));
  EXPECT_EQ(rig.transport->recoveries(), 0);
  EXPECT_FALSE(rig.Snapshot().moving);
}

TEST(ModbusTurntable, CorruptRepliesAreProtocolErrorsAfterRetries) {
  Rig rig = MakeRig("generic", {SimFault{SimFault::Kind::kCorrupt, 0, 0, 0, 0}});
  Expected<void> moved = rig.table->MoveTo(10.0, In(2s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kProtocol);
  EXPECT_THAT(moved.error().message, HasSubstr("bad CRC"));
  EXPECT_THAT(moved.error().message, HasSubstr("after 3 attempts"));
  // The drive executed the move (only the replies were bad); the stop it then got (its reply
  // was bad too) ended it.
  EXPECT_FALSE(rig.Snapshot().moving);
}

TEST(ModbusTurntable, LinkDroppedMidMoveIsLinkDownAndTheWatchdogStopsTheMotor) {
  Rig rig = MakeRig("generic", {SimFault{SimFault::Kind::kLinkDrop, 1, 0.3, 0, 0}});
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(2s)));
  const auto start = Clock::now();
  Expected<void> moved = rig.table->MoveTo(200.0, In(2s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kLinkDown);
  EXPECT_LT(Clock::now() - start, 1s);
  EXPECT_TRUE(rig.Snapshot().link_down);
  EXPECT_FALSE(rig.Snapshot(400ms).moving);  // the drive's 300 ms watchdog
}

TEST(ModbusTurntable, StopFromAnotherThreadAbortsPromptly) {
  ModbusOptions options = FastOptions();
  options.speed_deg_per_s = 90.0;
  Rig rig = MakeRig("generic", {}, options);
  auto move = std::async(std::launch::async, [&] { return rig.table->MoveTo(360.0, In(10s)); });
  std::this_thread::sleep_for(50ms);
  const auto start = Clock::now();
  rig.table->Stop();
  Expected<void> moved = move.get();
  EXPECT_LT(Clock::now() - start, 200ms);
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kAborted);
  EXPECT_FALSE(rig.Snapshot().moving);
  EXPECT_GT(rig.Snapshot().position_counts, 0.0);
}

TEST(ModbusTurntable, ConcurrentMoveIsBusy) {
  ModbusOptions options = FastOptions();
  options.speed_deg_per_s = 90.0;
  Rig rig = MakeRig("generic", {}, options);
  auto move = std::async(std::launch::async, [&] { return rig.table->MoveTo(90.0, In(10s)); });
  std::this_thread::sleep_for(30ms);
  Expected<void> second = rig.table->MoveTo(10.0, In(1s));
  ASSERT_FALSE(second);
  EXPECT_EQ(second.error().code, ErrorCode::kBusy);
  rig.table->Stop();
  (void)move.get();
}

TEST(ModbusTurntable, DisableThenMoveFailsUntilHome) {
  Rig rig = MakeRig("leadshine_pr");
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(2s)));
  ASSERT_TRUE(rig.table->Disable());
  EXPECT_FALSE(rig.Snapshot().enabled);
  Expected<void> moved = rig.table->MoveTo(20.0, In(2s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kBadInput);
  EXPECT_FALSE(rig.table->State()->enabled);
  ASSERT_TRUE(rig.table->Home(In(2s)));
  EXPECT_TRUE(rig.table->MoveTo(20.0, In(2s)));
}

TEST(ModbusTurntable, IdlePowerDownAndReenableOnTheNextMove) {
  ModbusOptions options = FastOptions();
  options.idle_disable_s = 0.1;
  Rig rig = MakeRig("generic", {}, options);
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(2s)));
  EXPECT_TRUE(rig.Snapshot().enabled);
  EXPECT_TRUE(WaitUntil([&] { return !rig.Snapshot().enabled; }, 2s));
  Expected<void> moved = rig.table->MoveTo(20.0, In(2s));
  ASSERT_TRUE(moved) << moved.error().ToString();
  EXPECT_TRUE(rig.Snapshot().enabled);
}

TEST(ModbusTurntable, DestructorStopsAndDisables) {
  Rig rig = MakeRig("generic");
  ASSERT_TRUE(rig.table->MoveTo(10.0, In(2s)));
  std::shared_ptr<SimulatedDrive> drive = rig.drive;
  rig.table.reset();
  EXPECT_FALSE(drive->Inspect(SteadyClock::now()).enabled);

  Rig keep = MakeRig("generic", {}, FastOptions(), /*disable_at_end=*/false);
  ASSERT_TRUE(keep.table->MoveTo(10.0, In(2s)));
  drive = keep.drive;
  keep.table.reset();
  EXPECT_TRUE(drive->Inspect(SteadyClock::now()).enabled);
}

TEST(ModbusTurntable, BadTargetAndOverflowAreBadInput) {
  Rig rig = MakeRig("generic");
  EXPECT_EQ(rig.table->MoveTo(std::nan(""), In(1s)).error().code, ErrorCode::kBadInput);
  ModbusOptions options = FastOptions();
  options.gear_ratio = 1000.0;  // 600000 rpm and 2.8e9 counts: neither fits its register
  options.steps_per_rev = 100'000'000;
  Rig big = MakeRig("mks_servo42d", {}, options);
  Expected<void> moved = big.table->MoveTo(10.0, In(1s));
  ASSERT_FALSE(moved);
  EXPECT_EQ(moved.error().code, ErrorCode::kBadInput);
  EXPECT_THAT(moved.error().message, HasSubstr("does not fit"));
}

// --- the simulator itself ---

TEST(SimulatedDrive, FollowsATrapezoidAndSolvesEveryProfilesStatus) {
  for (const std::string name : {"generic", "mks_servo42d", "leadshine_pr", "oriental_az"}) {
    SCOPED_TRACE(name);
    const DriveProfile profile = Profile(name);
    SimDriveOptions options;
    options.settle_ms = 0.0;
    options.watchdog_ms = 0.0;  // no polling in this test
    auto drive = SimulatedDrive::Create(profile, options);
    ASSERT_TRUE(drive);
    const auto t0 = SteadyClock::now();
    auto send = [&](const std::string& command, const Variables& v, SteadyClock::time_point t) {
      Variables all(profile.params.begin(), profile.params.end());
      for (const auto& [k, x] : v) all[k] = x;
      auto steps = RenderCommand(profile, *profile.FindCommand(command), all);
      ASSERT_TRUE(steps) << steps.error().message;
      for (const RenderedStep& step : *steps) {
        if (!step.request) continue;
        SimReply reply = (*drive)->Handle(EncodeRequestPdu(*step.request), t);
        EXPECT_EQ(reply.action, SimReply::Action::kReply);
        EXPECT_EQ(reply.pdu[0] & 0x80, 0) << command;
      }
    };
    // The status as the profile's rules read it from the simulator's registers.
    auto status = [&](SteadyClock::time_point t) {
      FieldValues values;
      for (const FieldRead& read : PlanFieldReads(profile)) {
        Request r{read.table == RegisterTable::kInput ? FunctionCode::kReadInputRegisters
                                                      : FunctionCode::kReadHoldingRegisters,
                  read.address,
                  read.count,
                  {}};
        SimReply reply = (*drive)->Handle(EncodeRequestPdu(r), t);
        std::vector<std::uint16_t> regs;
        for (int i = 0; i < read.count; ++i) {
          regs.push_back(
              static_cast<std::uint16_t>(reply.pdu[2 + 2 * i] << 8 | reply.pdu[3 + 2 * i]));
        }
        DecodeFields(profile, read, regs, values);
      }
      return values;
    };
    send("enable", {}, t0);
    // steps_per_rev counts at 1 rev/s, 10 rev/s^2: 1 rev takes 1.1 s.
    const double spr = static_cast<double>(profile.steps_per_rev);
    send("move",
         {{"target", spr},
          {"delta", spr},
          {"speed_rpm", 60},
          {"speed_hz", spr},
          {"accel_rpm_s", 600},
          {"accel_hz_s", 10 * spr},
          {"accel_ms", 100},
          {"accel_ms_per_krpm", 1000.0 / 600 * 1000}},
         t0);
    FieldValues mid = status(t0 + 550ms);
    EXPECT_TRUE(profile.status.moving.Evaluate(mid));
    EXPECT_NEAR(static_cast<double>(mid.at("position")) * profile.position().scale, spr / 2,
                spr * 0.01);
    if (profile.status.in_position) {
      EXPECT_FALSE(profile.status.in_position->Evaluate(mid));
    }
    FieldValues end = status(t0 + 1200ms);
    EXPECT_FALSE(profile.status.moving.Evaluate(end));
    EXPECT_EQ(end.at("position"), profile.steps_per_rev);
    if (profile.status.in_position) {
      EXPECT_TRUE(profile.status.in_position->Evaluate(end));
    }
    EXPECT_FALSE(profile.status.alarm->Evaluate(end));
    if (profile.status.enabled) {
      EXPECT_TRUE(profile.status.enabled->Evaluate(end));
    }
    send("home", {}, t0 + 1300ms);
    FieldValues homed = status(t0 + 3000ms);
    EXPECT_TRUE(profile.status.homed->Evaluate(homed));
    EXPECT_EQ(homed.at("position"), 0);
  }
}

TEST(SimulatedDrive, FaultSpecs) {
  Expected<SimFault> alarm = ParseSimFault("alarm@3:0.25");
  ASSERT_TRUE(alarm);
  EXPECT_EQ(alarm->kind, SimFault::Kind::kAlarm);
  EXPECT_EQ(alarm->move_index, 3);
  EXPECT_DOUBLE_EQ(alarm->at_fraction, 0.25);
  Expected<SimFault> exception = ParseSimFault("exception@1:2");
  ASSERT_TRUE(exception);
  EXPECT_EQ(exception->code, 2);
  EXPECT_EQ(exception->count, 1);
  EXPECT_EQ(ParseSimFault("no-reply@0:1")->count, 1);
  EXPECT_EQ(ParseSimFault("link-drop@2")->kind, SimFault::Kind::kLinkDrop);
  for (const char* bad : {"alarm", "fire@1", "stall@x", "stall@1:2", "exception@1:0"}) {
    EXPECT_FALSE(ParseSimFault(bad)) << bad;
  }
}

TEST(SimulatedDrive, IgnoresMovesWhileDisabledAndAnswersUnknownFunctions) {
  auto drive = SimulatedDrive::Create(Profile("generic"), {});
  ASSERT_TRUE(drive);
  const auto t0 = SteadyClock::now();
  Request move{FunctionCode::kWriteSingleRegister, 0, 0, {3}};
  ASSERT_EQ((*drive)->Handle(EncodeRequestPdu(move), t0).pdu[0], 0x06);
  EXPECT_FALSE((*drive)->Inspect(t0).moving);
  SimReply reply = (*drive)->Handle(FromHex("2B 0E 01 00"), t0);
  EXPECT_EQ(ToHex(reply.pdu), "AB 01");
}

}  // namespace
}  // namespace revolve::turntable::modbus
