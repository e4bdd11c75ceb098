#include "station/operator_panel.h"

#include "base/log.h"

namespace revolve::station {
namespace {

using namespace std::chrono_literals;

constexpr std::chrono::nanoseconds kScanningHalfPeriod = 500ms;
constexpr std::chrono::nanoseconds kFaultHalfPeriod = 100ms;

std::optional<std::chrono::nanoseconds> HalfPeriod(LedPattern pattern) {
  switch (pattern) {
    case LedPattern::kScanning:
      return kScanningHalfPeriod;
    case LedPattern::kFault:
      return kFaultHalfPeriod;
    default:
      return std::nullopt;
  }
}

}  // namespace

MonoTime MonoNow() {
  return std::chrono::duration_cast<MonoTime>(std::chrono::steady_clock::now().time_since_epoch());
}

void Debouncer::OnEdge(bool to_active, MonoTime t) {
  if (to_active) armed_ = true;
  if (t > last_edge_) last_edge_ = t;
}

bool Debouncer::Poll(MonoTime now, bool level_active) {
  if (!armed_ || now - last_edge_ < window_) return false;
  armed_ = false;
  return level_active;
}

std::optional<MonoTime> Debouncer::Deadline() const {
  if (!armed_) return std::nullopt;
  return last_edge_ + window_;
}

std::string_view ToString(LedPattern pattern) {
  switch (pattern) {
    case LedPattern::kOff:
      return "off";
    case LedPattern::kReady:
      return "ready";
    case LedPattern::kScanning:
      return "scanning";
    case LedPattern::kFault:
      return "fault";
  }
  return "off";
}

LedPattern PatternFor(ScanState state, bool devices_ok) {
  if (state == ScanState::kFailed) return LedPattern::kFault;
  if (IsActive(state)) return LedPattern::kScanning;
  return devices_ok ? LedPattern::kReady : LedPattern::kFault;
}

bool LedLit(LedPattern pattern, std::chrono::nanoseconds since) {
  if (pattern == LedPattern::kOff) return false;
  const auto half = HalfPeriod(pattern);
  if (!half) return true;
  if (since.count() < 0) since = std::chrono::nanoseconds(0);
  return (since / *half) % 2 == 0;
}

bool LampOn(ScanState state) { return IsActive(state); }

OperatorPanel::OperatorPanel(std::unique_ptr<OperatorLines> lines, const OperatorOptions& options)
    : lines_(std::move(lines)),
      start_(std::chrono::duration_cast<std::chrono::nanoseconds>(
          std::chrono::duration<double, std::milli>(options.debounce_ms))),
      abort_(std::chrono::duration_cast<std::chrono::nanoseconds>(
          std::chrono::duration<double, std::milli>(options.debounce_ms))) {}

void OperatorPanel::Report(const Error& error) {
  if (reported_error_) return;
  reported_error_ = true;
  Logger("station")->error("operator panel ({}): {}", lines_->Describe(), error.message);
}

std::vector<PanelCommand> OperatorPanel::Service(MonoTime now) {
  std::vector<PanelCommand> commands;
  Expected<std::vector<ButtonEdge>> edges = lines_->ReadEdges();
  if (!edges) {
    Report(edges.error());
    return commands;
  }
  for (const ButtonEdge& edge : *edges) {
    (edge.button == PanelButton::kStart ? start_ : abort_).OnEdge(edge.to_active, edge.timestamp);
  }
  auto poll = [&](Debouncer& debouncer, PanelButton button, PanelCommand command) {
    if (!debouncer.Deadline() || now < *debouncer.Deadline()) return;
    Expected<bool> level = lines_->Active(button);
    if (!level) {
      Report(level.error());
      return;
    }
    if (debouncer.Poll(now, *level)) commands.push_back(command);
  };
  poll(abort_, PanelButton::kAbort, PanelCommand::kAbort);
  poll(start_, PanelButton::kStart, PanelCommand::kStart);
  return commands;
}

void OperatorPanel::Show(LedPattern pattern, bool lamp_on, MonoTime now) {
  if (pattern != pattern_) {
    pattern_ = pattern;
    pattern_start_ = now;
  }
  const bool lit = LedLit(pattern_, now - pattern_start_);
  if (lines_->Has(PanelOutput::kLed) && led_ != lit) {
    if (auto set = lines_->Set(PanelOutput::kLed, lit); set) {
      led_ = lit;
    } else {
      Report(set.error());
    }
  }
  if (lines_->Has(PanelOutput::kLamp) && lamp_ != lamp_on) {
    if (auto set = lines_->Set(PanelOutput::kLamp, lamp_on); set) {
      lamp_ = lamp_on;
    } else {
      Report(set.error());
    }
  }
}

std::optional<MonoTime> OperatorPanel::NextDeadline(MonoTime now) const {
  std::optional<MonoTime> next;
  auto consider = [&next](std::optional<MonoTime> t) {
    if (t && (!next || *t < *next)) next = t;
  };
  consider(start_.Deadline());
  consider(abort_.Deadline());
  if (const auto half = HalfPeriod(pattern_); half && lines_->Has(PanelOutput::kLed)) {
    const auto since = now - pattern_start_;
    consider(pattern_start_ + (since / *half + 1) * *half);
  }
  return next;
}

}  // namespace revolve::station
