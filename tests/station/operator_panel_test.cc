#include <deque>

#include <gtest/gtest.h>

#include "station/operator_panel.h"

namespace revolve::station {
namespace {

using namespace std::chrono_literals;

MonoTime Ms(double ms) {
  return std::chrono::duration_cast<MonoTime>(std::chrono::duration<double, std::milli>(ms));
}

// Scripted edges, levels set by the test, outputs recorded.
class FakeLines final : public OperatorLines {
 public:
  bool Has(PanelButton) const override { return true; }
  bool Has(PanelOutput) const override { return true; }
  std::vector<int> EventFds() const override { return {}; }
  Expected<std::vector<ButtonEdge>> ReadEdges() override {
    std::vector<ButtonEdge> out(pending.begin(), pending.end());
    pending.clear();
    return out;
  }
  Expected<bool> Active(PanelButton b) override {
    return b == PanelButton::kStart ? start_level : abort_level;
  }
  Expected<void> Set(PanelOutput o, bool on) override {
    (o == PanelOutput::kLed ? led_writes : lamp_writes).push_back(on);
    return {};
  }
  std::string Describe() const override { return "fake"; }

  // A bounce train: `n` edges alternating, 0.6 ms apart, ending at `final_level`.
  void Bounce(PanelButton b, double t_ms, int n, bool final_level) {
    for (int i = 0; i < n; ++i) {
      const bool to_active = ((n - 1 - i) % 2 == 0) ? final_level : !final_level;
      pending.push_back(ButtonEdge{b, to_active, Ms(t_ms + 0.6 * i)});
    }
    (b == PanelButton::kStart ? start_level : abort_level) = final_level;
  }

  std::deque<ButtonEdge> pending;
  bool start_level = false;
  bool abort_level = false;
  std::vector<bool> led_writes;
  std::vector<bool> lamp_writes;
};

TEST(DebouncerTest, ABounceTrainIsOnePress) {
  Debouncer d(30ms);
  // Five edges in 3 ms, ending pressed.
  for (int i = 0; i < 5; ++i) d.OnEdge(i % 2 == 0, Ms(100 + 0.6 * i));
  EXPECT_FALSE(d.Poll(Ms(110), true));  // not quiet long enough
  ASSERT_TRUE(d.Deadline().has_value());
  EXPECT_EQ(*d.Deadline(), Ms(100 + 2.4) + 30ms);
  EXPECT_TRUE(d.Poll(Ms(140), true));
  EXPECT_FALSE(d.Poll(Ms(200), true));  // held: no second press
  EXPECT_FALSE(d.Deadline().has_value());
}

TEST(DebouncerTest, ReleaseBounceAndSpikesAreNotPresses) {
  Debouncer d(30ms);
  // Release with bounce: edges toward pressed, but the line ends released.
  d.OnEdge(false, Ms(0));
  d.OnEdge(true, Ms(0.5));
  d.OnEdge(false, Ms(1.0));
  EXPECT_FALSE(d.Poll(Ms(40), false));
  // A 1 ms spike.
  d.OnEdge(true, Ms(100));
  d.OnEdge(false, Ms(101));
  EXPECT_FALSE(d.Poll(Ms(140), false));
  // Later a clean press counts.
  d.OnEdge(true, Ms(300));
  EXPECT_TRUE(d.Poll(Ms(331), true));
}

TEST(LedPatternTest, PatternsFollowTheState) {
  EXPECT_EQ(PatternFor(ScanState::kIdle, true), LedPattern::kReady);
  EXPECT_EQ(PatternFor(ScanState::kDone, true), LedPattern::kReady);
  EXPECT_EQ(PatternFor(ScanState::kAborted, true), LedPattern::kReady);
  EXPECT_EQ(PatternFor(ScanState::kCapturing, true), LedPattern::kScanning);
  EXPECT_EQ(PatternFor(ScanState::kHoming, false), LedPattern::kScanning);
  EXPECT_EQ(PatternFor(ScanState::kFailed, true), LedPattern::kFault);
  EXPECT_EQ(PatternFor(ScanState::kIdle, false), LedPattern::kFault);
  EXPECT_TRUE(LampOn(ScanState::kMoving));
  EXPECT_FALSE(LampOn(ScanState::kDone));
  EXPECT_FALSE(LampOn(ScanState::kIdle));
}

TEST(LedPatternTest, BlinkRates) {
  // Ready: steady.
  for (int ms = 0; ms < 2000; ms += 50) EXPECT_TRUE(LedLit(LedPattern::kReady, Ms(ms)));
  EXPECT_FALSE(LedLit(LedPattern::kOff, Ms(0)));
  // Scanning: 1 Hz; fault: 5 Hz. Count the on/off changes over 2 s.
  auto changes = [](LedPattern p) {
    int n = 0;
    bool last = LedLit(p, Ms(0));
    for (int ms = 1; ms <= 2000; ++ms) {
      const bool lit = LedLit(p, Ms(ms - 0.5));
      n += lit != last;
      last = lit;
    }
    return n;
  };
  EXPECT_EQ(changes(LedPattern::kScanning), 3);  // on 0-500, off -1000, on -1500, off -2000
  EXPECT_EQ(changes(LedPattern::kFault), 19);
  EXPECT_TRUE(LedLit(LedPattern::kScanning, Ms(499)));
  EXPECT_FALSE(LedLit(LedPattern::kScanning, Ms(501)));
  EXPECT_FALSE(LedLit(LedPattern::kFault, Ms(150)));
}

TEST(OperatorPanelTest, ButtonPressesBecomeCommandsOnce) {
  auto lines = std::make_unique<FakeLines>();
  FakeLines* fake = lines.get();
  OperatorOptions options;
  options.debounce_ms = 30;
  OperatorPanel panel(std::move(lines), options);

  fake->Bounce(PanelButton::kStart, 1000, 5, true);
  EXPECT_TRUE(panel.Service(Ms(1005)).empty());
  ASSERT_TRUE(panel.NextDeadline(Ms(1005)).has_value());
  auto commands = panel.Service(Ms(1040));
  ASSERT_EQ(commands.size(), 1u);
  EXPECT_EQ(commands[0], PanelCommand::kStart);
  EXPECT_TRUE(panel.Service(Ms(1100)).empty());
  // Release (with bounce): nothing.
  fake->Bounce(PanelButton::kStart, 1500, 3, false);
  EXPECT_TRUE(panel.Service(Ms(1600)).empty());
  // The abort button.
  fake->Bounce(PanelButton::kAbort, 2000, 1, true);
  commands = panel.Service(Ms(2031));
  ASSERT_EQ(commands.size(), 1u);
  EXPECT_EQ(commands[0], PanelCommand::kAbort);
}

TEST(OperatorPanelTest, LedAndLampFollowTheScan) {
  auto lines = std::make_unique<FakeLines>();
  FakeLines* fake = lines.get();
  OperatorPanel panel(std::move(lines), OperatorOptions{});

  panel.Show(LedPattern::kReady, false, Ms(0));
  panel.Show(LedPattern::kReady, false, Ms(100));  // no change, no write
  EXPECT_EQ(fake->led_writes, (std::vector<bool>{true}));
  EXPECT_EQ(fake->lamp_writes, (std::vector<bool>{false}));

  // Scanning: blinks at 1 Hz, the lamp is on.
  fake->led_writes.clear();
  for (int ms = 1000; ms <= 3000; ms += 100) panel.Show(LedPattern::kScanning, true, Ms(ms));
  EXPECT_EQ(fake->led_writes, (std::vector<bool>{false, true, false, true}));
  EXPECT_EQ(fake->lamp_writes, (std::vector<bool>{false, true}));
  EXPECT_EQ(panel.pattern(), LedPattern::kScanning);
  // The next blink edge is the loop's deadline.
  ASSERT_TRUE(panel.NextDeadline(Ms(3000)).has_value());
  EXPECT_EQ(*panel.NextDeadline(Ms(3000)), Ms(3500));

  // A fault: fast blink, lamp off.
  fake->led_writes.clear();
  for (int ms = 4000; ms < 5000; ms += 50) panel.Show(LedPattern::kFault, false, Ms(ms));
  EXPECT_EQ(fake->led_writes.size(), 9u);
  EXPECT_EQ(fake->lamp_writes.back(), false);
}

TEST(OperatorPanelTest, NoLinesConfiguredMeansNoPanel) {
  auto lines = OpenPanelLines(OperatorOptions{});
  ASSERT_TRUE(lines.has_value());
  EXPECT_EQ(*lines, nullptr);
}

TEST(OperatorPanelTest, AMissingChipIsATypedError) {
  OperatorOptions options;
  options.chip = "/dev/gpiochip-that-does-not-exist";
  options.start_button.offset = 17;
  auto lines = OpenPanelLines(options);
  ASSERT_FALSE(lines.has_value());
  EXPECT_TRUE(lines.error().code == ErrorCode::kNotFound ||
              lines.error().code == ErrorCode::kUnsupported ||
              lines.error().code == ErrorCode::kNoDevice)
      << lines.error().ToString();
  EXPECT_FALSE(lines.error().message.empty());
}

}  // namespace
}  // namespace revolve::station
