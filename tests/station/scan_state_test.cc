#include <gtest/gtest.h>

#include "station/scan_state.h"

namespace revolve::station {
namespace {

using Clock = ScanStateMachine::Clock;
using namespace std::chrono_literals;

TEST(ScanStateTest, NamesRoundTrip) {
  for (ScanState s :
       {ScanState::kIdle, ScanState::kHoming, ScanState::kMoving, ScanState::kSettling,
        ScanState::kCapturing, ScanState::kIntegrating, ScanState::kMeshing, ScanState::kWriting,
        ScanState::kDone, ScanState::kFailed, ScanState::kAborted}) {
    auto back = ScanStateFromString(ToString(s));
    ASSERT_TRUE(back.has_value()) << ToString(s);
    EXPECT_EQ(*back, s);
  }
  EXPECT_FALSE(ScanStateFromString("flying").has_value());
}

TEST(ScanStateTest, TransitionTable) {
  using S = ScanState;
  EXPECT_TRUE(IsAllowedTransition(S::kIdle, S::kHoming));
  EXPECT_TRUE(IsAllowedTransition(S::kHoming, S::kMoving));
  EXPECT_TRUE(IsAllowedTransition(S::kMoving, S::kSettling));
  EXPECT_TRUE(IsAllowedTransition(S::kSettling, S::kCapturing));
  EXPECT_TRUE(IsAllowedTransition(S::kCapturing, S::kIntegrating));
  EXPECT_TRUE(IsAllowedTransition(S::kIntegrating, S::kMoving));
  EXPECT_TRUE(IsAllowedTransition(S::kIntegrating, S::kMeshing));
  EXPECT_TRUE(IsAllowedTransition(S::kMeshing, S::kWriting));
  EXPECT_TRUE(IsAllowedTransition(S::kWriting, S::kDone));
  EXPECT_TRUE(IsAllowedTransition(S::kDone, S::kHoming));
  EXPECT_TRUE(IsAllowedTransition(S::kFailed, S::kHoming));
  // Stops are not skipped, and nothing leaves idle but homing.
  EXPECT_FALSE(IsAllowedTransition(S::kMoving, S::kCapturing));
  EXPECT_FALSE(IsAllowedTransition(S::kIdle, S::kMoving));
  EXPECT_FALSE(IsAllowedTransition(S::kWriting, S::kMoving));
  // Every running state can fail or abort; idle and terminal states cannot.
  for (S s : {S::kHoming, S::kMoving, S::kSettling, S::kCapturing, S::kIntegrating, S::kMeshing,
              S::kWriting}) {
    EXPECT_TRUE(IsAllowedTransition(s, S::kFailed)) << ToString(s);
    EXPECT_TRUE(IsAllowedTransition(s, S::kAborted)) << ToString(s);
  }
  EXPECT_FALSE(IsAllowedTransition(S::kIdle, S::kFailed));
  EXPECT_FALSE(IsAllowedTransition(S::kDone, S::kAborted));
}

TEST(ScanStateTest, AFullScanEmitsOneEventPerTransitionWithProgressAndEta) {
  const auto t0 = Clock::time_point{} + 100s;
  ScanStateMachine m("scan-1", 2, 0, t0);
  std::vector<ScanEvent> events;
  auto enter = [&](ScanState s, Clock::time_point t, int stop = -1, double deg = 0) {
    auto e = m.Enter(s, t, stop, deg);
    ASSERT_TRUE(e.has_value()) << e.error().message;
    events.push_back(*e);
  };
  enter(ScanState::kHoming, t0);
  for (int k = 0; k < 2; ++k) {
    const auto t = t0 + 1s + k * 2s;
    enter(ScanState::kMoving, t, k, 180.0 * k);
    enter(ScanState::kSettling, t + 100ms, k, 180.0 * k);
    enter(ScanState::kCapturing, t + 200ms, k, 180.0 * k);
    enter(ScanState::kIntegrating, t + 300ms, k, 180.0 * k);
    m.StopSaved();
  }
  enter(ScanState::kMeshing, t0 + 5s);
  enter(ScanState::kWriting, t0 + 6s);
  enter(ScanState::kDone, t0 + 7s);

  ASSERT_EQ(events.size(), 12u);
  for (std::size_t i = 0; i < events.size(); ++i) EXPECT_EQ(events[i].seq, i + 1);
  EXPECT_EQ(events[0].state, ScanState::kHoming);
  EXPECT_EQ(events[0].stop, -1);
  EXPECT_FALSE(events[0].eta_s.has_value());
  EXPECT_EQ(events[5].state, ScanState::kMoving);
  EXPECT_EQ(events[5].stop, 1);
  EXPECT_DOUBLE_EQ(events[5].angle_deg, 180.0);
  EXPECT_EQ(events[5].stops_done, 1);
  // One stop in 2 s since the first move: one more to go.
  ASSERT_TRUE(events[5].eta_s.has_value());
  EXPECT_NEAR(*events[5].eta_s, 2.0, 1e-9);
  EXPECT_NEAR(events[5].progress, 0.45, 1e-9);
  EXPECT_EQ(events[9].state, ScanState::kMeshing);
  EXPECT_EQ(events[9].stops_done, 2);
  EXPECT_EQ(events[11].state, ScanState::kDone);
  EXPECT_DOUBLE_EQ(events[11].progress, 1.0);
  EXPECT_NEAR(events[11].elapsed_s, 7.0, 1e-9);
  // Progress never goes back.
  for (std::size_t i = 1; i < events.size(); ++i) {
    EXPECT_GE(events[i].progress, events[i - 1].progress);
  }
}

TEST(ScanStateTest, InvalidTransitionIsAnErrorAndChangesNothing) {
  ScanStateMachine m("s", 4, 0, Clock::now());
  auto bad = m.Enter(ScanState::kCapturing, Clock::now(), 0);
  ASSERT_FALSE(bad.has_value());
  EXPECT_EQ(bad.error().code, ErrorCode::kInternal);
  EXPECT_EQ(m.state(), ScanState::kIdle);
  EXPECT_FALSE(m.Fail(Error{ErrorCode::kIo, "x"}, Clock::now()).has_value());
}

TEST(ScanStateTest, FailureCarriesTheReasonAndTheAlarm) {
  ScanStateMachine m("s", 4, 0, Clock::now());
  ASSERT_TRUE(m.Enter(ScanState::kHoming, Clock::now()).has_value());
  ASSERT_TRUE(m.Enter(ScanState::kMoving, Clock::now(), 0, 0.0).has_value());
  auto failed = m.Fail(Error{ErrorCode::kAlarm, "overcurrent"}, Clock::now(), 0x31, "overcurrent");
  ASSERT_TRUE(failed.has_value());
  EXPECT_EQ(failed->state, ScanState::kFailed);
  ASSERT_TRUE(failed->error.has_value());
  EXPECT_EQ(failed->error->code, ErrorCode::kAlarm);
  EXPECT_EQ(failed->alarm_code, 0x31);
  const auto json = failed->ToJson();
  EXPECT_EQ(json["state"], "failed");
  EXPECT_EQ(json["error"]["code"], "alarm");
  EXPECT_EQ(json["alarm"]["code"], 0x31);
  // An abort is its own terminal state.
  ScanStateMachine m2("s", 4, 0, Clock::now());
  ASSERT_TRUE(m2.Enter(ScanState::kHoming, Clock::now()).has_value());
  auto aborted = m2.Fail(Error{ErrorCode::kAborted, "SIGTERM"}, Clock::now());
  ASSERT_TRUE(aborted.has_value());
  EXPECT_EQ(aborted->state, ScanState::kAborted);
}

TEST(ScanStateTest, NotesKeepTheStateAndEventsRoundTripThroughJson) {
  ScanStateMachine m("abc", 36, 12, Clock::now());
  ASSERT_TRUE(m.Enter(ScanState::kHoming, Clock::now()).has_value());
  ASSERT_TRUE(m.Enter(ScanState::kMoving, Clock::now(), 12, 120.0).has_value());
  ScanEvent note = m.Note("camera: re-try 1 of 2", Clock::now());
  EXPECT_EQ(note.state, ScanState::kMoving);
  EXPECT_EQ(note.seq, 3u);
  EXPECT_EQ(note.stops_done, 12);
  note.time = "2026-01-01T00:00:00.000Z";
  auto back = ScanEventFromJson(note.ToJson());
  ASSERT_TRUE(back.has_value()) << back.error().message;
  EXPECT_EQ(back->ToJson(), note.ToJson());
  EXPECT_FALSE(ScanEventFromJson(nlohmann::json::array()).has_value());
  EXPECT_FALSE(ScanEventFromJson({{"state", "nope"}}).has_value());
}

}  // namespace
}  // namespace revolve::station
