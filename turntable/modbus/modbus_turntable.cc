#include "turntable/modbus/modbus_turntable.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "base/log.h"

namespace revolve::turntable::modbus {
namespace {

using Ms = std::chrono::duration<double, std::milli>;

Clock::duration FromMs(double ms) { return std::chrono::duration_cast<Clock::duration>(Ms(ms)); }

// Clears a flag guarded by `mutex` when it goes out of scope.
class BusyScope {
 public:
  BusyScope(std::mutex& mutex, bool& busy) : mutex_(mutex), busy_(busy) {
    std::lock_guard lock(mutex_);
    busy_ = true;
  }
  ~BusyScope() {
    std::lock_guard lock(mutex_);
    busy_ = false;
  }
  BusyScope(const BusyScope&) = delete;
  BusyScope& operator=(const BusyScope&) = delete;

 private:
  std::mutex& mutex_;
  bool& busy_;
};

Variables MergedParams(const DriveProfile& profile, const ModbusOptions& options) {
  Variables params(profile.params.begin(), profile.params.end());
  for (const auto& [name, value] : options.params) params[name] = value;
  return params;
}

Kinematics KinematicsOf(const ModbusOptions& options, const DriveProfile& profile) {
  Kinematics k;
  k.steps_per_rev = static_cast<double>(options.steps_per_rev > 0 ? options.steps_per_rev
                                                                  : profile.steps_per_rev);
  k.gear_ratio = options.gear_ratio;
  k.reverse = options.reverse;
  return k;
}

}  // namespace

double Kinematics::CountsFromDeg(double angle_deg) const {
  return (reverse ? -1.0 : 1.0) * angle_deg / 360.0 * CountsPerPlateRev();
}

double Kinematics::DegFromCounts(double counts) const {
  return (reverse ? -1.0 : 1.0) * counts / CountsPerPlateRev() * 360.0;
}

Variables MoveVariables(const Kinematics& kinematics, std::int64_t target_counts,
                        std::int64_t from_counts, double speed_deg_per_s,
                        double acceleration_deg_per_s2, const Variables& params) {
  Variables v = params;
  const double motor_rev_per_deg = kinematics.gear_ratio / 360.0;
  const double counts_per_deg = kinematics.CountsPerPlateRev() / 360.0;
  v["target"] = static_cast<double>(target_counts);
  v["delta"] = static_cast<double>(target_counts - from_counts);
  v["speed_rpm"] = speed_deg_per_s * motor_rev_per_deg * 60.0;
  v["speed_hz"] = speed_deg_per_s * counts_per_deg;
  const double accel_rpm_s = acceleration_deg_per_s2 * motor_rev_per_deg * 60.0;
  v["accel_rpm_s"] = accel_rpm_s;
  v["accel_hz_s"] = acceleration_deg_per_s2 * counts_per_deg;
  v["accel_ms"] = speed_deg_per_s / acceleration_deg_per_s2 * 1000.0;
  v["accel_ms_per_krpm"] = 1000.0 / accel_rpm_s * 1000.0;
  return v;
}

std::string AlarmText(const DriveProfile& profile, std::optional<std::int64_t> code) {
  if (code) {
    if (const auto it = profile.alarm_texts.find(*code); it != profile.alarm_texts.end()) {
      return fmt::format("alarm 0x{:X}: {}", *code, it->second);
    }
    return fmt::format(
        "alarm 0x{:X} (see the alarm list in the drive's manual); remove the "
        "cause, then home the table, which resets the alarm",
        *code);
  }
  return "the drive reports an alarm (see its display or manual); remove the cause, then home "
         "the table, which resets the alarm";
}

ModbusTurntable::ModbusTurntable(ModbusOptions options, DriveProfile profile,
                                 std::unique_ptr<ModbusTransport> transport,
                                 std::shared_ptr<SimulatedPlate> plate, bool disable_at_end)
    : options_(std::move(options)),
      profile_(std::move(profile)),
      kinematics_(KinematicsOf(options_, profile_)),
      params_(MergedParams(profile_, options_)),
      plate_(std::move(plate)),
      disable_at_end_(disable_at_end),
      tolerance_counts_(static_cast<std::int64_t>(
          std::floor(options_.tolerance_deg / 360.0 * kinematics_.CountsPerPlateRev()))),
      transport_(std::move(transport)),
      idle_(
          profile_.FindCommand("disable") != nullptr ? options_.idle_disable_s : 0.0, op_mutex_,
          [this] {
            std::lock_guard lock(mutex_);
            return enabled_ && !busy_;
          },
          [this] { PowerDownIdle(); }) {}

ModbusTurntable::~ModbusTurntable() {
  idle_.Shutdown();
  Stop();
  if (disable_at_end_) {
    if (Expected<void> off = RunCommand("disable", params_, true); !off) {
      Logger("turntable")->warn("could not power the motor down: {}", off.error().message);
    }
  }
}

std::string ModbusTurntable::Describe() const {
  return fmt::format("modbus {}, profile {} ({}), {} counts/rev x gear {}{}, {} deg/s",
                     transport_->Describe(), profile_.name, profile_.description,
                     kinematics_.steps_per_rev, kinematics_.gear_ratio,
                     kinematics_.reverse ? ", reversed" : "", options_.speed_deg_per_s);
}

double ModbusTurntable::AngleOf(std::int64_t counts) const {
  std::lock_guard lock(mutex_);
  return kinematics_.DegFromCounts(static_cast<double>(counts - offset_counts_));
}

Expected<std::vector<std::uint16_t>> ModbusTurntable::Transact(const Request& request) {
  TransactionError last;
  const int attempts = options_.retries + 1;
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    std::lock_guard lock(io_mutex_);
    TransactionResult<std::vector<std::uint16_t>> result = transport_->Execute(request);
    if (result) return std::move(*result);
    last = std::move(result.error());
    if (!last.transient) return std::unexpected(last.error);
    if (attempt < attempts) {
      Logger("turntable")
          ->debug("attempt {} of {} failed, retrying: {}", attempt, attempts, last.error.message);
      if (Expected<void> recovered = transport_->Recover(last.reconnect); !recovered) {
        last.error = recovered.error();
        if (last.error.code != ErrorCode::kLinkDown) return std::unexpected(last.error);
      }
    }
  }
  last.error.message += fmt::format(" (after {} attempt{})", attempts, attempts == 1 ? "" : "s");
  return std::unexpected(last.error);
}

Expected<void> ModbusTurntable::RunCommand(std::string_view name, const Variables& variables,
                                           bool optional) {
  const Command* command = profile_.FindCommand(name);
  if (command == nullptr) {
    if (optional) return {};
    return MakeError(ErrorCode::kUnsupported,
                     fmt::format("profile {} has no \"{}\" command", profile_.name, name));
  }
  Expected<std::vector<RenderedStep>> steps = RenderCommand(profile_, *command, variables);
  if (!steps) return std::unexpected(steps.error());
  for (const RenderedStep& step : *steps) {
    if (!step.request) {
      std::this_thread::sleep_for(std::chrono::milliseconds(step.sleep_ms));
      continue;
    }
    Expected<std::vector<std::uint16_t>> done = Transact(*step.request);
    if (!done) {
      return std::unexpected(WithContext(done.error(), fmt::format("sending \"{}\"", name)));
    }
  }
  return {};
}

Expected<ModbusTurntable::DriveStatus> ModbusTurntable::ReadStatus() {
  FieldValues values;
  for (const FieldRead& read : PlanFieldReads(profile_)) {
    Request request;
    request.function = read.table == RegisterTable::kInput ? FunctionCode::kReadInputRegisters
                                                           : FunctionCode::kReadHoldingRegisters;
    request.address = read.address;
    request.count = read.count;
    Expected<std::vector<std::uint16_t>> registers = Transact(request);
    if (!registers) {
      return std::unexpected(WithContext(registers.error(), "reading the drive status"));
    }
    DecodeFields(profile_, read, *registers, values);
  }
  DriveStatus status;
  const Field& position = profile_.position();
  status.position_counts =
      std::llround(static_cast<double>(values[position.name]) * position.scale);
  const StatusRules& rules = profile_.status;
  status.moving = rules.moving.Evaluate(values);
  status.in_position = !rules.in_position || rules.in_position->Evaluate(values);
  status.alarm = rules.alarm && rules.alarm->Evaluate(values);
  if (rules.enabled) status.enabled = rules.enabled->Evaluate(values);
  if (rules.homed) status.homed = rules.homed->Evaluate(values);
  if (rules.alarm_code_field && status.alarm) status.alarm_code = values[*rules.alarm_code_field];
  return status;
}

void ModbusTurntable::Publish(const DriveStatus& status) {
  if (!plate_) return;
  plate_->angle_deg.store(AngleOf(status.position_counts));
  plate_->moving.store(status.moving);
}

bool ModbusTurntable::Pause(Clock::time_point until) {
  std::unique_lock lock(wait_mutex_);
  wake_.wait_until(lock, until, [this] { return abort_.load(); });
  return !abort_.load();
}

void ModbusTurntable::StopMotor() noexcept {
  try {
    if (Expected<void> stopped = RunCommand("stop", params_, false); !stopped) {
      Logger("turntable")->warn("could not send stop to the drive: {}", stopped.error().message);
    }
  } catch (const std::exception& e) {
    Logger("turntable")->error("stopping the drive threw: {}", e.what());
  } catch (...) {
    Logger("turntable")->error("stopping the drive threw");
  }
}

void ModbusTurntable::Stop() noexcept {
  abort_.store(true);
  { std::lock_guard lock(wait_mutex_); }
  wake_.notify_all();
  StopMotor();
}

Error ModbusTurntable::AlarmError(const DriveStatus& status) {
  const std::string text = AlarmText(profile_, status.alarm_code);
  Error error{ErrorCode::kAlarm, fmt::format("the drive stopped on {} (at {:.3f} deg)", text,
                                             AngleOf(status.position_counts))};
  std::lock_guard lock(mutex_);
  latched_alarm_ = error;
  alarm_code_ = status.alarm_code;
  return error;
}

Expected<void> ModbusTurntable::EnsureEnabled() {
  bool init = false;
  {
    std::lock_guard lock(mutex_);
    if (enabled_) return {};
    init = !init_done_;
  }
  if (init) {
    if (Expected<void> ran = RunCommand("init", params_, true); !ran) return ran;
    std::lock_guard lock(mutex_);
    init_done_ = true;
  }
  if (Expected<void> on = RunCommand("enable", params_, true); !on) return on;
  std::lock_guard lock(mutex_);
  enabled_ = true;
  return {};
}

Expected<ModbusTurntable::DriveStatus> ModbusTurntable::PollStatus(std::string_view aborted) {
  if (abort_.load()) {
    StopMotor();
    return MakeError(ErrorCode::kAborted, std::string(aborted));
  }
  Expected<DriveStatus> status = ReadStatus();
  if (!status) {
    StopMotor();
    return std::unexpected(status.error());
  }
  Publish(*status);
  if (status->alarm) {
    Error error = AlarmError(*status);
    StopMotor();
    return std::unexpected(error);
  }
  return status;
}

Expected<void> ModbusTurntable::WaitForMove(std::int64_t target_counts,
                                            Clock::time_point deadline) {
  const auto stall_window = FromMs(options_.stall_timeout_ms);
  std::int64_t progress_counts = 0;
  Clock::time_point progress_time = Clock::now();
  bool first = true;
  int in_position_polls = 0;
  constexpr std::string_view aborted = "the move was stopped on request";
  for (;;) {
    Expected<DriveStatus> status = PollStatus(aborted);
    if (!status) return std::unexpected(status.error());
    const Clock::time_point now = Clock::now();
    const std::int64_t error_counts = std::llabs(status->position_counts - target_counts);
    const bool at_target = error_counts <= tolerance_counts_;
    if (!status->moving && status->in_position && at_target) {
      if (++in_position_polls >= options_.in_position_polls) return {};
    } else {
      in_position_polls = 0;
    }
    if (first || std::llabs(status->position_counts - progress_counts) >
                     std::max<std::int64_t>(tolerance_counts_, 0)) {
      progress_counts = status->position_counts;
      progress_time = now;
      first = false;
    }
    const bool no_progress = now - progress_time > stall_window;
    // At the deadline, a plate that has not moved for a moment counts as stalled.
    const bool no_recent_progress =
        now - progress_time >
        std::min<Clock::duration>(stall_window, std::chrono::milliseconds(200));
    auto where = [&] {
      return fmt::format("at {:.3f} deg, target {:.3f} deg, drive {}",
                         AngleOf(status->position_counts), AngleOf(target_counts),
                         status->moving ? "still reports moving" : "reports stopped");
    };
    if (no_progress && !at_target) {
      StopMotor();
      return MakeError(ErrorCode::kStalled,
                       fmt::format("the plate stopped turning for {} ms before reaching its "
                                   "target ({}): check for a jammed plate, a slipping belt or "
                                   "too little motor current",
                                   options_.stall_timeout_ms, where()));
    }
    if (now >= deadline) {
      StopMotor();
      if (no_recent_progress && !at_target) {
        return MakeError(ErrorCode::kStalled,
                         fmt::format("the move did not finish by its deadline ({})", where()));
      }
      return MakeError(ErrorCode::kTimeout,
                       fmt::format("the move did not finish by its deadline ({}): lower the "
                                   "step or raise speed_deg_per_s / scan.move_timeout_s",
                                   where()));
    }
    if (!Pause(std::min(now + FromMs(options_.poll_ms), deadline))) {
      StopMotor();
      return MakeError(ErrorCode::kAborted, std::string(aborted));
    }
  }
}

Expected<void> ModbusTurntable::WaitForHome(Clock::time_point deadline) {
  const Clock::time_point start = Clock::now();
  bool seen_moving = false;
  constexpr std::string_view aborted = "homing was stopped on request";
  for (;;) {
    Expected<DriveStatus> status = PollStatus(aborted);
    if (!status) return std::unexpected(status.error());
    const Clock::time_point now = Clock::now();
    seen_moving = seen_moving || status->moving;
    const std::optional<bool> homed = status->homed;  // nullopt: the profile has no "homed" rule
    const bool done = !status->moving &&
                      (homed ? *homed : seen_moving || now - start > 2 * FromMs(options_.poll_ms));
    if (done) {
      std::lock_guard lock(mutex_);
      offset_counts_ = status->position_counts;
      commanded_counts_ = status->position_counts;
      return {};
    }
    if (now >= deadline) {
      StopMotor();
      return MakeError(ErrorCode::kTimeout,
                       fmt::format("homing did not finish by its deadline (drive {}, homed {}): "
                                   "check the home sensor and the drive's homing settings",
                                   status->moving ? "moving" : "stopped",
                                   homed ? (*homed ? "yes" : "no") : "unknown"));
    }
    if (!Pause(std::min(now + FromMs(options_.poll_ms), deadline))) {
      StopMotor();
      return MakeError(ErrorCode::kAborted, std::string(aborted));
    }
  }
}

Expected<void> ModbusTurntable::Home(Clock::time_point deadline) {
  std::unique_lock op(op_mutex_, std::try_to_lock);
  if (!op.owns_lock()) return std::unexpected(BusyError());
  BusyScope busy(mutex_, busy_);
  abort_.store(false);
  idle_.Touch();
  auto fail = [](Error error) { return std::unexpected(WithContext(std::move(error), "homing")); };
  if (Expected<void> reset = RunCommand("reset_alarm", params_, true); !reset) {
    return fail(reset.error());
  }
  {
    std::lock_guard lock(mutex_);
    latched_alarm_.reset();
    alarm_code_.reset();
    explicitly_disabled_ = false;
    enabled_ = false;
  }
  if (Expected<void> on = EnsureEnabled(); !on) return fail(on.error());
  if (profile_.FindCommand("home") != nullptr) {
    if (Expected<void> sent = RunCommand("home", params_, false); !sent) {
      StopMotor();
      return fail(sent.error());
    }
    if (Expected<void> homed = WaitForHome(deadline); !homed) return fail(homed.error());
  } else {
    // No homing procedure: the nearest whole plate revolution becomes 0 deg.
    Expected<DriveStatus> status = ReadStatus();
    if (!status) return fail(status.error());
    std::int64_t offset = 0;
    {
      std::lock_guard lock(mutex_);
      offset = offset_counts_;
    }
    const double revs =
        static_cast<double>(status->position_counts - offset) / kinematics_.CountsPerPlateRev();
    const auto target =
        offset +
        static_cast<std::int64_t>(std::llround(std::round(revs) * kinematics_.CountsPerPlateRev()));
    const Variables variables =
        MoveVariables(kinematics_, target, status->position_counts, options_.speed_deg_per_s,
                      options_.acceleration_deg_per_s2, params_);
    if (Expected<void> sent = RunCommand("move", variables, false); !sent) {
      StopMotor();
      return fail(sent.error());
    }
    {
      std::lock_guard lock(mutex_);
      commanded_counts_ = target;
    }
    if (Expected<void> moved = WaitForMove(target, deadline); !moved) return fail(moved.error());
    std::lock_guard lock(mutex_);
    offset_counts_ = target;
  }
  {
    std::lock_guard lock(mutex_);
    homed_ = true;
  }
  idle_.Touch();
  return {};
}

Expected<void> ModbusTurntable::MoveTo(double angle_deg, Clock::time_point deadline) {
  std::unique_lock op(op_mutex_, std::try_to_lock);
  if (!op.owns_lock()) return std::unexpected(BusyError());
  if (Expected<void> usable = CheckTargetAngle(angle_deg); !usable) return usable;
  std::int64_t target = 0;
  {
    std::lock_guard lock(mutex_);
    if (explicitly_disabled_) {
      return MakeError(ErrorCode::kBadInput,
                       "the drive is disabled (motor power off): home the table to enable it");
    }
    if (latched_alarm_) {
      Error error = *latched_alarm_;
      error.message += "; home the table to reset the alarm";
      return std::unexpected(error);
    }
    target = offset_counts_ + std::llround(kinematics_.CountsFromDeg(angle_deg));
  }
  BusyScope busy(mutex_, busy_);
  abort_.store(false);
  idle_.Touch();
  auto context = [angle_deg](Error error) {
    return std::unexpected(
        WithContext(std::move(error), fmt::format("moving to {:.3f} deg", angle_deg)));
  };
  if (Expected<void> on = EnsureEnabled(); !on) return context(on.error());
  std::optional<std::int64_t> from;
  {
    std::lock_guard lock(mutex_);
    from = commanded_counts_;
  }
  if (!from) {
    // The first move of this process: "delta" starts from where the drive is.
    Expected<DriveStatus> status = ReadStatus();
    if (!status) return context(status.error());
    from = status->position_counts;
  }
  const Variables variables = MoveVariables(kinematics_, target, *from, options_.speed_deg_per_s,
                                            options_.acceleration_deg_per_s2, params_);
  if (Expected<void> sent = RunCommand("move", variables, false); !sent) {
    if (sent.error().code != ErrorCode::kBadInput) StopMotor();
    return context(sent.error());
  }
  {
    std::lock_guard lock(mutex_);
    commanded_counts_ = target;
  }
  Expected<void> moved = WaitForMove(target, deadline);
  idle_.Touch();
  if (!moved) return context(moved.error());
  return {};
}

Expected<TurntableState> ModbusTurntable::State() {
  Expected<DriveStatus> status = ReadStatus();
  if (!status) return std::unexpected(status.error());
  Publish(*status);
  TurntableState state;
  state.angle_deg = AngleOf(status->position_counts);
  state.moving = status->moving;
  std::lock_guard lock(mutex_);
  // Before any move of this process, "in position" is the drive's own word.
  state.in_position = !status->moving && status->in_position && !status->alarm &&
                      (!commanded_counts_ || std::llabs(status->position_counts -
                                                        *commanded_counts_) <= tolerance_counts_);
  state.enabled = status->enabled.value_or(enabled_);
  state.homed = homed_;
  state.open_loop = false;
  if (status->alarm || latched_alarm_) {
    const std::optional<std::int64_t> code = status->alarm ? status->alarm_code : alarm_code_;
    if (code) state.alarm_code = static_cast<int>(*code);
    state.alarm_text = AlarmText(profile_, code);
  }
  return state;
}

Expected<void> ModbusTurntable::Disable() {
  abort_.store(true);
  { std::lock_guard lock(wait_mutex_); }
  wake_.notify_all();
  StopMotor();
  Expected<void> off = RunCommand("disable", params_, true);
  std::lock_guard lock(mutex_);
  explicitly_disabled_ = true;
  if (!off) return std::unexpected(WithContext(off.error(), "disabling the drive"));
  enabled_ = false;
  return {};
}

void ModbusTurntable::PowerDownIdle() {
  Logger("turntable")
      ->info("idle for {} s: powering the motor down (the next move powers it up)",
             options_.idle_disable_s);
  Expected<void> off = RunCommand("disable", params_, false);
  if (!off) Logger("turntable")->warn("idle power-down failed: {}", off.error().message);
  std::lock_guard lock(mutex_);
  enabled_ = false;
}

}  // namespace revolve::turntable::modbus
