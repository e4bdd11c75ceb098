// The operator panel: a start button, an optional abort button, a status LED and an optional
// lamp relay, on GPIO lines behind the OperatorLines seam (libgpiod: operator_gpio.h; tests: a
// fake). The debounce and the LED patterns are pure and tested apart from the lines.
//
// (The turntable's GPIO seam, turntable/gpio/step_dir_lines.h, is specific to STEP/DIR/ENABLE,
// so the panel has its own small seam; both sit on libgpiod 1.6.)
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"
#include "station/scan_state.h"
#include "station/station_config.h"

namespace revolve::station {

// Monotonic time (CLOCK_MONOTONIC, as std::chrono::steady_clock and the kernel's GPIO event
// timestamps on Linux >= 5.7) in nanoseconds.
using MonoTime = std::chrono::nanoseconds;
MonoTime MonoNow();

enum class PanelButton { kStart, kAbort };
enum class PanelOutput { kLed, kLamp };

struct ButtonEdge {
  PanelButton button = PanelButton::kStart;
  bool to_active = true;  // toward pressed
  MonoTime timestamp{0};
};

class OperatorLines {
 public:
  virtual ~OperatorLines() = default;
  virtual bool Has(PanelButton button) const = 0;
  virtual bool Has(PanelOutput output) const = 0;
  // Descriptors that become readable when edges are pending (for poll()).
  virtual std::vector<int> EventFds() const = 0;
  // The pending edges, without waiting. Errors: io, no_device.
  virtual Expected<std::vector<ButtonEdge>> ReadEdges() = 0;
  // A button's logical level now (true: pressed). False for a button that is not there.
  virtual Expected<bool> Active(PanelButton button) = 0;
  // Drives an output to its logical level (true: lit / on); active-low wiring is applied below
  // the seam. Does nothing for an output that is not there. Errors: io, no_device.
  virtual Expected<void> Set(PanelOutput output, bool on) = 0;
  virtual std::string Describe() const = 0;
};

// Software debounce (libgpiod 1.x has none): an edge toward pressed arms a press; the press is
// confirmed once the line has been quiet for `window` since its last edge and reads pressed.
// A bounce train gives one press; release bounce and spikes give none.
class Debouncer {
 public:
  explicit Debouncer(std::chrono::nanoseconds window) : window_(window) {}

  void OnEdge(bool to_active, MonoTime t);
  // True once per confirmed press.
  bool Poll(MonoTime now, bool level_active);
  // When Poll() can next confirm a press; nullopt when none is armed.
  std::optional<MonoTime> Deadline() const;

 private:
  std::chrono::nanoseconds window_;
  bool armed_ = false;
  MonoTime last_edge_{0};
};

enum class LedPattern {
  kOff,
  kReady,     // steady: idle, last scan done or aborted
  kScanning,  // slow blink, 1 Hz
  kFault,     // fast blink, 5 Hz: last scan failed or the devices are down
};
std::string_view ToString(LedPattern pattern);

LedPattern PatternFor(ScanState state, bool devices_ok);
// Whether the LED is lit `since` after the pattern started.
bool LedLit(LedPattern pattern, std::chrono::nanoseconds since);
// The lamp relay is on while a scan runs.
bool LampOn(ScanState state);

enum class PanelCommand { kStart, kAbort };

// The panel's I/O shell over the lines.
class OperatorPanel {
 public:
  OperatorPanel(std::unique_ptr<OperatorLines> lines, const OperatorOptions& options);

  std::vector<int> PollFds() const { return lines_->EventFds(); }

  // Reads the pending edges and returns the confirmed presses. Call when a poll fd is readable
  // and on every tick. A line error is logged once and ignored (the socket still works).
  std::vector<PanelCommand> Service(MonoTime now);

  // Shows `pattern` on the LED and switches the lamp, at `now` (writes only changes).
  void Show(LedPattern pattern, bool lamp_on, MonoTime now);

  // When Service()/Show() next has something to do (a debounce deadline, a blink edge).
  std::optional<MonoTime> NextDeadline(MonoTime now) const;

  LedPattern pattern() const { return pattern_; }
  std::string Describe() const { return lines_->Describe(); }

 private:
  void Report(const Error& error);

  std::unique_ptr<OperatorLines> lines_;
  Debouncer start_;
  Debouncer abort_;
  LedPattern pattern_ = LedPattern::kOff;
  MonoTime pattern_start_{0};
  std::optional<bool> led_;
  std::optional<bool> lamp_;
  bool reported_error_ = false;
};

// The panel of [operator] through libgpiod, or nullptr when no line is configured.
// Errors: unsupported (this build has no libgpiod), not_found, busy, no_device, io.
Expected<std::unique_ptr<OperatorLines>> OpenPanelLines(const OperatorOptions& options);

}  // namespace revolve::station
