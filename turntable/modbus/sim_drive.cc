#include "turntable/modbus/sim_drive.h"

#include <algorithm>
#include <charconv>
#include <cmath>

#include <fmt/format.h>

#include "base/log.h"

namespace revolve::turntable::modbus {
namespace {

constexpr std::size_t kMaxCombinations = 1'000'000;

double Seconds(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

std::chrono::steady_clock::duration FromSeconds(double s) {
  return std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(s));
}

Expected<double> ParseDouble(std::string_view text) {
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || ec != std::errc() || ptr != text.data() + text.size()) {
    return MakeError(ErrorCode::kBadInput, fmt::format("\"{}\" is not a number", text));
  }
  return value;
}

Expected<int> ParseInt(std::string_view text) {
  int base = 10;
  if (text.starts_with("0x")) {
    base = 16;
    text.remove_prefix(2);
  }
  int value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value, base);
  if (text.empty() || ec != std::errc() || ptr != text.data() + text.size()) {
    return MakeError(ErrorCode::kBadInput, fmt::format("\"{}\" is not an integer", text));
  }
  return value;
}

}  // namespace

Expected<SimFault> ParseSimFault(std::string_view spec) {
  auto bad = [spec](std::string_view what) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("fault \"{}\": {} (expected KIND@MOVE[:ARG], KIND one of alarm, "
                                 "stall, link-drop, no-reply, corrupt, exception)",
                                 spec, what));
  };
  const std::size_t at = spec.find('@');
  if (at == std::string_view::npos) return bad("missing @");
  const std::string_view kind = spec.substr(0, at);
  std::string_view rest = spec.substr(at + 1);
  std::string_view arg;
  if (const std::size_t colon = rest.find(':'); colon != std::string_view::npos) {
    arg = rest.substr(colon + 1);
    rest = rest.substr(0, colon);
  }
  SimFault fault;
  if (kind == "alarm") {
    fault.kind = SimFault::Kind::kAlarm;
  } else if (kind == "stall") {
    fault.kind = SimFault::Kind::kStall;
  } else if (kind == "link-drop") {
    fault.kind = SimFault::Kind::kLinkDrop;
  } else if (kind == "no-reply") {
    fault.kind = SimFault::Kind::kNoReply;
  } else if (kind == "corrupt") {
    fault.kind = SimFault::Kind::kCorrupt;
  } else if (kind == "exception") {
    fault.kind = SimFault::Kind::kException;
    fault.code = 0x04;
    fault.count = 1;
  } else {
    return bad("unknown kind");
  }
  Expected<int> move = ParseInt(rest);
  if (!move || *move < 0) return bad("MOVE must be a move index >= 0");
  fault.move_index = *move;
  if (!arg.empty()) {
    switch (fault.kind) {
      case SimFault::Kind::kAlarm:
      case SimFault::Kind::kStall:
      case SimFault::Kind::kLinkDrop: {
        Expected<double> fraction = ParseDouble(arg);
        if (!fraction || *fraction < 0.0 || *fraction > 1.0) return bad("the fraction is 0..1");
        fault.at_fraction = *fraction;
        break;
      }
      case SimFault::Kind::kException: {
        Expected<int> code = ParseInt(arg);
        if (!code || *code < 1 || *code > 0xFF) return bad("the exception code is 1..255");
        fault.code = *code;
        break;
      }
      case SimFault::Kind::kNoReply:
      case SimFault::Kind::kCorrupt: {
        Expected<int> count = ParseInt(arg);
        if (!count || *count < 0) return bad("the request count is >= 0 (0: all)");
        fault.count = *count;
        break;
      }
    }
  }
  return fault;
}

std::string Describe(const SimFault& fault) {
  switch (fault.kind) {
    case SimFault::Kind::kAlarm:
      return fmt::format("alarm 0x{:X} at {} of move {}", fault.code, fault.at_fraction,
                         fault.move_index);
    case SimFault::Kind::kStall:
      return fmt::format("stall at {} of move {}", fault.at_fraction, fault.move_index);
    case SimFault::Kind::kLinkDrop:
      return fmt::format("link drop at {} of move {}", fault.at_fraction, fault.move_index);
    case SimFault::Kind::kNoReply:
      return fmt::format("no reply from move command {} ({} requests)", fault.move_index,
                         fault.count == 0 ? std::string("all") : std::to_string(fault.count));
    case SimFault::Kind::kCorrupt:
      return fmt::format("corrupt replies from move command {} ({} requests)", fault.move_index,
                         fault.count == 0 ? std::string("all") : std::to_string(fault.count));
    case SimFault::Kind::kException:
      return fmt::format("exception 0x{:02X} from move command {} ({} requests)", fault.code,
                         fault.move_index,
                         fault.count == 0 ? std::string("all") : std::to_string(fault.count));
  }
  return "?";
}

SimulatedDrive::SimulatedDrive(DriveProfile profile, SimDriveOptions options)
    : profile_(std::move(profile)),
      options_(std::move(options)),
      steps_per_rev_(static_cast<double>(options_.steps_per_rev > 0 ? options_.steps_per_rev
                                                                    : profile_.steps_per_rev)) {}

Expected<std::unique_ptr<SimulatedDrive>> SimulatedDrive::Create(DriveProfile profile,
                                                                 SimDriveOptions options) {
  if (options.default_speed_hz < 0 || options.default_accel_hz_s < 0 || options.settle_ms < 0 ||
      options.watchdog_ms < 0) {
    return MakeError(ErrorCode::kBadInput, "simulated drive: speeds and times must be >= 0");
  }
  std::unique_ptr<SimulatedDrive> drive(new SimulatedDrive(std::move(profile), std::move(options)));
  if (Expected<void> solved = drive->SolveStatus(); !solved) {
    return std::unexpected(solved.error());
  }
  return drive;
}

Expected<void> SimulatedDrive::SolveStatus() {
  const StatusRules& rules = profile_.status;
  struct Rule {
    const StatusExpression* expression;
    int bit;
  };
  std::vector<Rule> present{{&rules.moving, kMoving}};
  if (rules.in_position) present.push_back({&*rules.in_position, kInPosition});
  if (rules.alarm) present.push_back({&*rules.alarm, kAlarm});
  if (rules.enabled) present.push_back({&*rules.enabled, kEnabled});
  if (rules.homed) present.push_back({&*rules.homed, kHomed});
  int mask = 0;
  for (const Rule& rule : present) mask |= rule.bit;

  // Candidate values per searched field.
  std::map<std::string, std::set<std::int64_t>> values;
  std::map<std::string, std::set<int>> bits;
  for (const Rule& rule : present) rule.expression->CollectCandidates(values, bits);
  const std::string position = profile_.position().name;
  const std::string alarm_field = rules.alarm_code_field.value_or("");
  std::vector<std::pair<std::string, std::vector<std::int64_t>>> searched;
  std::set<std::string> names;
  for (const auto& [name, v] : values) names.insert(name);
  for (const auto& [name, b] : bits) names.insert(name);
  std::size_t combinations = 1;
  for (const std::string& name : names) {
    if (name == position || name == alarm_field) continue;
    std::set<std::int64_t> candidates{0};
    if (const auto it = values.find(name); it != values.end()) {
      candidates.insert(it->second.begin(), it->second.end());
    }
    if (const auto it = bits.find(name); it != bits.end()) {
      const std::vector<int> list(it->second.begin(), it->second.end());
      if (list.size() > 12) {
        return MakeError(ErrorCode::kBadInput,
                         fmt::format("profile {}: field {} has too many status bits to simulate",
                                     profile_.name, name));
      }
      for (std::uint32_t subset = 0; subset < (1u << list.size()); ++subset) {
        std::int64_t value = 0;
        for (std::size_t i = 0; i < list.size(); ++i) {
          if ((subset >> i) & 1u) value |= std::int64_t{1} << list[i];
        }
        candidates.insert(value);
      }
    }
    combinations *= candidates.size();
    if (combinations > kMaxCombinations) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("profile {}: the status rules have too many combinations to "
                                   "simulate",
                                   profile_.name));
    }
    searched.emplace_back(name, std::vector<std::int64_t>(candidates.begin(), candidates.end()));
  }

  // Outcome bits -> first field values producing them, per alarm-code state.
  std::map<int, FieldValues> found;
  for (int alarm_state = 0; alarm_state < 2; ++alarm_state) {
    FieldValues current;
    if (!alarm_field.empty()) current[alarm_field] = alarm_state != 0 ? options_.alarm_code : 0;
    std::vector<std::size_t> index(searched.size(), 0);
    for (;;) {
      for (std::size_t i = 0; i < searched.size(); ++i) {
        current[searched[i].first] = searched[i].second[index[i]];
      }
      int outcome = 0;
      for (const Rule& rule : present) {
        if (rule.expression->Evaluate(current)) outcome |= rule.bit;
      }
      // Tag with the alarm-code state so both variants are kept.
      const int key = outcome | (alarm_state << 8);
      found.emplace(key, current);
      std::size_t i = 0;
      while (i < searched.size() && ++index[i] == searched[i].second.size()) index[i++] = 0;
      if (i == searched.size()) break;
    }
  }
  // Best solution for every wanted state: weighted mismatch over the rules present.
  constexpr int kWeights[] = {8, 4, 16, 1, 2};  // moving, in_position, alarm, enabled, homed
  for (int wanted = 0; wanted < 32; ++wanted) {
    const int alarm_state = (wanted & kAlarm) != 0 ? 1 : 0;
    int best_cost = 1 << 30;
    const FieldValues* best = nullptr;
    for (const auto& [key, solution] : found) {
      int cost = (key >> 8) != alarm_state ? 1000 : 0;
      const int diff = (key & 0xFF) ^ wanted;
      for (int b = 0; b < 5; ++b) {
        if ((mask >> b & 1) != 0 && (diff >> b & 1) != 0) cost += kWeights[b];
      }
      if (cost < best_cost) {
        best_cost = cost;
        best = &solution;
      }
    }
    if (best != nullptr) solutions_[wanted] = *best;
  }
  return {};
}

double SimulatedDrive::PositionAt(const Motion& motion, Clock::time_point t) const {
  if (motion.frozen) return motion.frozen_counts;
  return motion.profile.PositionAt(Seconds(t - motion.start));
}

void SimulatedDrive::Advance(Clock::time_point now) {
  if (!motion_) return;
  Motion& m = *motion_;
  const Clock::time_point watchdog =
      options_.watchdog_ms > 0 && last_request_
          ? *last_request_ + FromSeconds(options_.watchdog_ms / 1000.0)
          : Clock::time_point::max();
  if (m.fault) {
    const Clock::time_point at =
        m.start + FromSeconds(m.fault->at_fraction * m.profile.duration_s());
    if (at <= now && at <= watchdog) {
      const double counts = PositionAt(m, at);
      const SimFault fault = *m.fault;
      m.fault.reset();
      switch (fault.kind) {
        case SimFault::Kind::kAlarm:
          position_counts_ = counts;
          alarm_code_ = fault.code;
          enabled_ = false;
          motion_.reset();
          Logger("turntable")
              ->info("simulated drive: alarm 0x{:X} at {:.0f} counts", fault.code, counts);
          return;
        case SimFault::Kind::kStall:
          m.frozen = true;
          m.frozen_counts = counts;
          Logger("turntable")->info("simulated drive: stalled at {:.0f} counts", counts);
          break;
        case SimFault::Kind::kLinkDrop:
          link_down_at_ = at;
          Logger("turntable")->info("simulated drive: link dropped at {:.0f} counts", counts);
          break;
        default:
          break;
      }
    }
  }
  if (watchdog <= now) {
    position_counts_ = PositionAt(m, watchdog);
    motion_.reset();
    Logger("turntable")
        ->info("simulated drive: no request for {} ms: watchdog stopped the motor",
               options_.watchdog_ms);
    return;
  }
  position_counts_ = PositionAt(m, now);
  if (!m.frozen && Seconds(now - m.start) >= m.profile.duration_s() + m.settle_s) {
    position_counts_ = m.profile.target_deg();
    if (m.homing) homed_ = true;
    motion_.reset();
  }
}

int SimulatedDrive::StatusBits() const {
  int bits = 0;
  if (motion_) bits |= kMoving;
  if (!motion_ && !alarm_code_ && std::fabs(position_counts_ - target_counts_) < 0.5) {
    bits |= kInPosition;
  }
  if (alarm_code_) bits |= kAlarm;
  if (enabled_) bits |= kEnabled;
  if (homed_) bits |= kHomed;
  return bits;
}

std::vector<std::uint16_t> SimulatedDrive::ReadRegisters(RegisterTable table, std::uint16_t address,
                                                         std::uint16_t count) {
  std::vector<std::uint16_t> out(count, 0);
  if (table == RegisterTable::kHolding) {
    for (std::uint16_t i = 0; i < count; ++i) {
      const auto it = holding_.find(static_cast<std::uint16_t>(address + i));
      if (it != holding_.end()) out[i] = it->second;
    }
  }
  FieldValues values = solutions_[StatusBits()];
  const Field& position = profile_.position();
  values[position.name] = std::llround(position_counts_ / position.scale);
  if (profile_.status.alarm_code_field) {
    values[*profile_.status.alarm_code_field] = alarm_code_.value_or(0);
  }
  for (const auto& [name, value] : values) {
    const Field& field = profile_.fields.find(name)->second;
    if (field.table != table) continue;
    Expected<std::vector<std::uint16_t>> encoded = EncodeValue(value, field.type, field.word_order);
    if (!encoded) {
      // Wrap like a real register would.
      const auto bits = static_cast<std::uint32_t>(value);
      encoded = EncodeValue(field.type == ValueType::kU16 || field.type == ValueType::kI16
                                ? static_cast<std::int64_t>(bits & 0xFFFF)
                                : static_cast<std::int64_t>(bits),
                            field.type == ValueType::kI16   ? ValueType::kU16
                            : field.type == ValueType::kI32 ? ValueType::kU32
                                                            : field.type,
                            field.word_order);
    }
    for (std::size_t i = 0; i < encoded->size(); ++i) {
      const int at = field.address + static_cast<int>(i) - address;
      if (at >= 0 && at < count) out[static_cast<std::size_t>(at)] = (*encoded)[i];
    }
  }
  return out;
}

std::optional<std::string> SimulatedDrive::MatchCommand(const Request& request) const {
  std::optional<std::string> best;
  int best_literals = -1;
  for (const auto& [name, command] : profile_.commands) {
    const Step* last = nullptr;
    for (const Step& step : command.steps) {
      if (step.kind != Step::Kind::kSleep) last = &step;
    }
    if (last == nullptr || last->address != request.address) continue;
    const bool function_ok = (last->kind == Step::Kind::kWriteRegister &&
                              request.function == FunctionCode::kWriteSingleRegister) ||
                             (last->kind == Step::Kind::kWriteRegisters &&
                              request.function == FunctionCode::kWriteMultipleRegisters) ||
                             (last->kind == Step::Kind::kWriteCoil &&
                              request.function == FunctionCode::kWriteSingleCoil);
    if (!function_ok) continue;
    std::size_t offset = 0;
    int literals = 0;
    bool ok = true;
    for (const ValueTemplate& value : last->values) {
      const int n = RegisterCount(value.type);
      if (offset + static_cast<std::size_t>(n) > request.values.size()) {
        ok = false;
        break;
      }
      if (value.variable.empty()) {
        Expected<std::vector<std::uint16_t>> encoded =
            EncodeValue(value.literal, value.type, value.word_order);
        if (last->kind == Step::Kind::kWriteCoil) {
          ok = ok && (request.values[0] != 0) == (value.literal != 0);
        } else {
          for (int i = 0; i < n; ++i) {
            ok = ok && encoded &&
                 (*encoded)[static_cast<std::size_t>(i)] == request.values[offset + i];
          }
        }
        ++literals;
      }
      offset += static_cast<std::size_t>(n);
    }
    if (!ok || offset != request.values.size()) continue;
    if (literals > best_literals) {
      best_literals = literals;
      best = name;
    }
  }
  return best;
}

Variables SimulatedDrive::DecodeVariables(const Command& command) const {
  Variables variables;
  for (const Step& step : command.steps) {
    if (step.kind == Step::Kind::kSleep || step.kind == Step::Kind::kWriteCoil) continue;
    int address = step.address;
    for (const ValueTemplate& value : step.values) {
      const int n = RegisterCount(value.type);
      if (!value.variable.empty()) {
        std::vector<std::uint16_t> registers;
        for (int i = 0; i < n; ++i) {
          const auto it = holding_.find(static_cast<std::uint16_t>(address + i));
          registers.push_back(it != holding_.end() ? it->second : 0);
        }
        variables[value.variable] =
            static_cast<double>(DecodeValue(registers, value.type, value.word_order)) /
            value.factor;
      }
      address += n;
    }
  }
  return variables;
}

void SimulatedDrive::StartMotion(double target_counts, double speed_hz, double accel_hz_s,
                                 bool homing, Clock::time_point now) {
  const double default_speed =
      options_.default_speed_hz > 0 ? options_.default_speed_hz : steps_per_rev_;
  const double default_accel =
      options_.default_accel_hz_s > 0 ? options_.default_accel_hz_s : 10.0 * steps_per_rev_;
  MotionLimits limits;
  limits.speed_deg_per_s = speed_hz > 0 ? speed_hz : default_speed;
  limits.acceleration_deg_per_s2 = accel_hz_s > 0 ? accel_hz_s : default_accel;
  Motion motion;
  motion.profile = MotionProfile(position_counts_, target_counts, limits);
  motion.start = now;
  motion.settle_s = options_.settle_ms / 1000.0;
  motion.homing = homing;
  if (!homing) {
    for (const SimFault& fault : options_.faults) {
      if (fault.move_index == moves_started_ &&
          (fault.kind == SimFault::Kind::kAlarm || fault.kind == SimFault::Kind::kStall ||
           fault.kind == SimFault::Kind::kLinkDrop)) {
        motion.fault = fault;
        if (fault.kind == SimFault::Kind::kAlarm && fault.code == SimFault{}.code) {
          motion.fault->code = options_.alarm_code;
        }
      }
    }
    ++moves_started_;
  }
  target_counts_ = target_counts;
  motion_ = std::move(motion);
}

void SimulatedDrive::Apply(const std::string& name, Clock::time_point now) {
  auto log = Logger("turntable");
  const Command& command = profile_.commands.find(name)->second;
  if (name == "enable") {
    if (!alarm_code_) enabled_ = true;
  } else if (name == "disable") {
    enabled_ = false;
    motion_.reset();
    target_counts_ = position_counts_;
  } else if (name == "stop") {
    motion_.reset();
    target_counts_ = position_counts_;
  } else if (name == "reset_alarm") {
    alarm_code_.reset();
  } else if (name == "home") {
    if (!enabled_ || alarm_code_) {
      log->info("simulated drive: home ignored ({})", alarm_code_ ? "alarm" : "disabled");
      return;
    }
    homed_ = false;
    StartMotion(0.0, 0.0, 0.0, true, now);
  } else if (name == "move") {
    if (!enabled_ || alarm_code_) {
      log->info("simulated drive: move ignored ({})", alarm_code_ ? "alarm" : "disabled");
      return;
    }
    const Variables v = DecodeVariables(command);
    auto get = [&v](std::string_view key) -> std::optional<double> {
      const auto it = v.find(key);
      return it == v.end() ? std::nullopt : std::optional(it->second);
    };
    double target = target_counts_;
    if (auto t = get("target")) {
      target = *t;
    } else if (auto d = get("delta")) {
      target = target_counts_ + *d;
    }
    double speed = 0.0;
    if (auto s = get("speed_hz")) {
      speed = *s;
    } else if (auto r = get("speed_rpm")) {
      speed = *r * steps_per_rev_ / 60.0;
    }
    double accel = 0.0;
    if (auto a = get("accel_hz_s")) {
      accel = *a;
    } else if (auto r = get("accel_rpm_s")) {
      accel = *r * steps_per_rev_ / 60.0;
    } else if (auto k = get("accel_ms_per_krpm"); k && *k > 0) {
      accel = 1000.0 / (*k / 1000.0) * steps_per_rev_ / 60.0;
    } else if (auto ms = get("accel_ms"); ms && *ms > 0 && speed > 0) {
      accel = speed / (*ms / 1000.0);
    }
    log->debug("simulated drive: move to {:.0f} counts at {:.0f} Hz, {:.0f} Hz/s", target, speed,
               accel);
    StartMotion(target, speed, accel, false, now);
  }
}

SimReply SimulatedDrive::Handle(std::span<const std::uint8_t> request_pdu, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  SimReply reply;
  if (link_down_at_ && now >= *link_down_at_) {
    Advance(now);
    reply.action = SimReply::Action::kDrop;
    return reply;
  }
  std::expected<Request, PduRejection> request = DecodeRequestPdu(request_pdu);
  if (!request) {
    reply.pdu =
        EncodeExceptionPdu(request_pdu.empty() ? 0 : request_pdu[0], request.error().exception);
    return reply;
  }
  std::optional<std::string> command;
  if (!request->IsRead()) command = MatchCommand(*request);
  if (command == "move") {
    for (const SimFault& fault : options_.faults) {
      if (fault.move_index == move_requests_ &&
          (fault.kind == SimFault::Kind::kNoReply || fault.kind == SimFault::Kind::kCorrupt ||
           fault.kind == SimFault::Kind::kException)) {
        protocol_fault_ = fault;
        protocol_fault_left_ = fault.count == 0 ? -1 : fault.count;
        Logger("turntable")->info("simulated drive: {}", Describe(fault));
      }
    }
    ++move_requests_;
  }
  std::optional<SimFault> fault;
  if (protocol_fault_ && protocol_fault_left_ != 0) {
    fault = protocol_fault_;
    if (protocol_fault_left_ > 0) --protocol_fault_left_;
  }
  if (fault && fault->kind == SimFault::Kind::kNoReply) {
    Advance(now);
    reply.action = SimReply::Action::kDrop;
    return reply;
  }
  if (fault && fault->kind == SimFault::Kind::kException) {
    Advance(now);
    reply.pdu = EncodeExceptionPdu(static_cast<std::uint8_t>(request->function),
                                   static_cast<ExceptionCode>(fault->code));
    return reply;
  }
  Advance(now);
  last_request_ = now;
  if (request->IsRead()) {
    const RegisterTable table = request->function == FunctionCode::kReadInputRegisters
                                    ? RegisterTable::kInput
                                    : RegisterTable::kHolding;
    reply.pdu = EncodeResponsePdu(*request, ReadRegisters(table, request->address, request->count));
  } else {
    if (request->function == FunctionCode::kWriteSingleCoil) {
      coils_[request->address] = request->values[0] != 0;
    } else {
      for (std::size_t i = 0; i < request->values.size(); ++i) {
        holding_[static_cast<std::uint16_t>(request->address + i)] = request->values[i];
      }
    }
    if (command) Apply(*command, now);
    reply.pdu = EncodeResponsePdu(*request, {});
  }
  if (fault && fault->kind == SimFault::Kind::kCorrupt) reply.action = SimReply::Action::kCorrupt;
  return reply;
}

SimSnapshot SimulatedDrive::Inspect(Clock::time_point now) {
  std::lock_guard lock(mutex_);
  Advance(now);
  SimSnapshot s;
  s.position_counts = position_counts_;
  s.target_counts = std::llround(target_counts_);
  s.moving = motion_.has_value();
  s.in_position = (StatusBits() & kInPosition) != 0;
  s.enabled = enabled_;
  s.homed = homed_;
  s.alarm_code = alarm_code_;
  s.moves_started = moves_started_;
  s.link_down = link_down_at_ && now >= *link_down_at_;
  return s;
}

bool SimulatedDrive::LinkDown(Clock::time_point now) {
  std::lock_guard lock(mutex_);
  Advance(now);
  return link_down_at_ && now >= *link_down_at_;
}

}  // namespace revolve::turntable::modbus
