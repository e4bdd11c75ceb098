#include "turntable/modbus/profile.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace revolve::turntable::modbus {
namespace {

Expected<std::int64_t> ParseInteger(std::string_view text) {
  bool negative = false;
  if (text.starts_with('-')) {
    negative = true;
    text.remove_prefix(1);
  }
  int base = 10;
  if (text.starts_with("0x") || text.starts_with("0X")) {
    base = 16;
    text.remove_prefix(2);
  }
  std::int64_t value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value, base);
  if (text.empty() || ec != std::errc() || ptr != text.data() + text.size()) {
    return MakeError(ErrorCode::kBadInput, "expected an integer");
  }
  return negative ? -value : value;
}

Expected<ValueType> ParseValueType(std::string_view text) {
  if (text == "u16") return ValueType::kU16;
  if (text == "i16") return ValueType::kI16;
  if (text == "u32") return ValueType::kU32;
  if (text == "i32") return ValueType::kI32;
  return MakeError(ErrorCode::kBadInput,
                   fmt::format("unknown type \"{}\" (expected u16, i16, u32 or i32)", text));
}

bool IsIdentifier(std::string_view text) {
  if (text.empty() || std::isdigit(static_cast<unsigned char>(text[0])) != 0) return false;
  return std::all_of(text.begin(), text.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_';
  });
}

// "${name*factor:type}" or "literal:type".
Expected<ValueTemplate> ParseValue(std::string_view token, WordOrder order) {
  ValueTemplate value;
  value.word_order = order;
  std::string_view body = token;
  std::string_view type;
  if (body.starts_with("${")) {
    if (!body.ends_with('}')) {
      return MakeError(ErrorCode::kBadInput, fmt::format("\"{}\": missing \"}}\"", token));
    }
    body = body.substr(2, body.size() - 3);
    if (const std::size_t colon = body.find(':'); colon != std::string_view::npos) {
      type = body.substr(colon + 1);
      body = body.substr(0, colon);
    }
    if (const std::size_t star = body.find('*'); star != std::string_view::npos) {
      const std::string_view factor_text = body.substr(star + 1);
      double factor = 0.0;
      const auto [ptr, ec] =
          std::from_chars(factor_text.data(), factor_text.data() + factor_text.size(), factor);
      if (factor_text.empty() || ec != std::errc() ||
          ptr != factor_text.data() + factor_text.size() || !std::isfinite(factor) ||
          factor == 0.0) {
        return MakeError(
            ErrorCode::kBadInput,
            fmt::format("\"{}\": the factor after \"*\" must be a non-zero number", token));
      }
      value.factor = factor;
      body = body.substr(0, star);
    }
    if (!IsIdentifier(body)) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("\"{}\": \"{}\" is not a variable name", token, body));
    }
    value.variable = std::string(body);
  } else {
    if (const std::size_t colon = body.find(':'); colon != std::string_view::npos) {
      type = body.substr(colon + 1);
      body = body.substr(0, colon);
    }
    Expected<std::int64_t> literal = ParseInteger(body);
    if (!literal) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("\"{}\": expected a number or ${{variable}}", token));
    }
    value.literal = *literal;
  }
  if (!type.empty()) {
    Expected<ValueType> parsed = ParseValueType(type);
    if (!parsed) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("\"{}\": {}", token, parsed.error().message));
    }
    value.type = *parsed;
  }
  if (value.variable.empty()) {
    if (Expected<std::vector<std::uint16_t>> fits =
            EncodeValue(value.literal, value.type, value.word_order);
        !fits) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("\"{}\": {}", token, fits.error().message));
    }
  }
  return value;
}

std::vector<std::string_view> Tokens(std::string_view text) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && (std::isspace(static_cast<unsigned char>(text[i])) != 0 ||
                               text[i] == ',' || text[i] == '=')) {
      ++i;
    }
    const std::size_t start = i;
    while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i])) == 0 &&
           text[i] != ',' && text[i] != '=') {
      ++i;
    }
    if (i > start) tokens.push_back(text.substr(start, i - start));
  }
  return tokens;
}

int StepRegisterCount(const Step& step) {
  int count = 0;
  for (const ValueTemplate& v : step.values) count += RegisterCount(v.type);
  return count;
}

Expected<Step> ParseStep(std::string_view text, WordOrder order) {
  const std::vector<std::string_view> tokens = Tokens(text);
  Step step;
  step.text = std::string(text);
  if (tokens.empty()) return MakeError(ErrorCode::kBadInput, "empty step");
  const std::string_view op = tokens[0];
  if (op == "sleep_ms") {
    Expected<std::int64_t> ms =
        tokens.size() == 2 ? ParseInteger(tokens[1]) : MakeError(ErrorCode::kBadInput, "");
    if (!ms || *ms < 0 || *ms > 10000) {
      return MakeError(ErrorCode::kBadInput, "expected \"sleep_ms N\" with N in 0..10000");
    }
    step.kind = Step::Kind::kSleep;
    step.sleep_ms = static_cast<int>(*ms);
    return step;
  }
  if (op == "write_register") {
    step.kind = Step::Kind::kWriteRegister;
  } else if (op == "write_registers") {
    step.kind = Step::Kind::kWriteRegisters;
  } else if (op == "write_coil") {
    step.kind = Step::Kind::kWriteCoil;
  } else {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("unknown operation \"{}\" (expected write_register, "
                                 "write_registers, write_coil or sleep_ms)",
                                 op));
  }
  if (tokens.size() < 3) {
    return MakeError(ErrorCode::kBadInput, fmt::format("expected \"{} ADDRESS VALUE...\"", op));
  }
  Expected<std::int64_t> address = ParseInteger(tokens[1]);
  if (!address || *address < 0 || *address > 0xFFFF) {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("\"{}\": the address must be 0..0xFFFF (a PDU address)", tokens[1]));
  }
  step.address = static_cast<std::uint16_t>(*address);
  for (std::size_t i = 2; i < tokens.size(); ++i) {
    Expected<ValueTemplate> value = ParseValue(tokens[i], order);
    if (!value) return std::unexpected(value.error());
    step.values.push_back(std::move(*value));
  }
  const int count = StepRegisterCount(step);
  switch (step.kind) {
    case Step::Kind::kWriteRegister:
      if (step.values.size() != 1 || count != 1) {
        return MakeError(ErrorCode::kBadInput,
                         "write_register (FC06) takes exactly one 16-bit value; use "
                         "write_registers for 32-bit values");
      }
      break;
    case Step::Kind::kWriteRegisters:
      if (count > kMaxWriteRegisters) {
        return MakeError(ErrorCode::kBadInput, fmt::format("{} registers: FC16 writes at most {}",
                                                           count, kMaxWriteRegisters));
      }
      break;
    case Step::Kind::kWriteCoil:
      if (step.values.size() != 1 || !step.values[0].variable.empty() ||
          (step.values[0].literal != 0 && step.values[0].literal != 1)) {
        return MakeError(ErrorCode::kBadInput, "write_coil takes one value, 0 or 1");
      }
      break;
    case Step::Kind::kSleep:
      break;
  }
  if (step.address + count - 1 > 0xFFFF) {
    return MakeError(ErrorCode::kBadInput, "the registers run past address 0xFFFF");
  }
  return step;
}

const toml::table* TableAt(const config::Document& document, std::string_view key) {
  const toml::node* node = document.root.get(key);
  return node != nullptr ? node->as_table() : nullptr;
}

std::vector<std::string> KeysOf(const toml::table* table) {
  std::vector<std::string> keys;
  if (table == nullptr) return keys;
  for (auto&& [key, node] : *table) keys.emplace_back(key.str());
  return keys;
}

Expected<WordOrder> ParseWordOrder(const config::Section& section, WordOrder fallback) {
  Expected<std::string> text =
      section.String("word_order", fallback == WordOrder::kHighFirst ? "high_first" : "low_first",
                     {"high_first", "low_first"});
  if (!text) return std::unexpected(text.error());
  return *text == "high_first" ? WordOrder::kHighFirst : WordOrder::kLowFirst;
}

Expected<Field> ParseField(const config::Section& section, std::string name, WordOrder order) {
  Field field;
  field.name = std::move(name);
  Expected<std::string> table = section.String("table", "holding", {"holding", "input"});
  if (!table) return std::unexpected(table.error());
  field.table = *table == "input" ? RegisterTable::kInput : RegisterTable::kHolding;
  if (!section.Has("address")) return std::unexpected(section.BadValue("address", "is required"));
  Expected<std::int64_t> address = section.Integer("address", 0, 0, 0xFFFF);
  if (!address) return std::unexpected(address.error());
  field.address = static_cast<std::uint16_t>(*address);
  Expected<std::string> type = section.String("type", "u16", {"u16", "i16", "u32", "i32"});
  if (!type) return std::unexpected(type.error());
  field.type = *ParseValueType(*type);
  Expected<WordOrder> word_order = ParseWordOrder(section, order);
  if (!word_order) return std::unexpected(word_order.error());
  field.word_order = *word_order;
  Expected<double> scale = section.Number("scale", 1.0, -1e9, 1e9);
  if (!scale) return std::unexpected(scale.error());
  if (*scale == 0.0) return std::unexpected(section.BadValue("scale", "must not be 0"));
  field.scale = *scale;
  if (field.address + RegisterCount(field.type) - 1 > 0xFFFF) {
    return std::unexpected(section.BadValue("address", "the field runs past address 0xFFFF"));
  }
  if (Expected<void> known = section.CheckNoUnknownKeys(); !known) {
    return std::unexpected(known.error());
  }
  return field;
}

}  // namespace

int RegisterCount(ValueType type) {
  return type == ValueType::kU32 || type == ValueType::kI32 ? 2 : 1;
}

std::string_view ToString(ValueType type) {
  switch (type) {
    case ValueType::kU16:
      return "u16";
    case ValueType::kI16:
      return "i16";
    case ValueType::kU32:
      return "u32";
    case ValueType::kI32:
      return "i32";
  }
  return "?";
}

Expected<std::vector<std::uint16_t>> EncodeValue(std::int64_t value, ValueType type,
                                                 WordOrder order) {
  std::int64_t min = 0;
  std::int64_t max = 0;
  switch (type) {
    case ValueType::kU16:
      max = 0xFFFF;
      break;
    case ValueType::kI16:
      min = std::numeric_limits<std::int16_t>::min();
      max = std::numeric_limits<std::int16_t>::max();
      break;
    case ValueType::kU32:
      max = 0xFFFFFFFFLL;
      break;
    case ValueType::kI32:
      min = std::numeric_limits<std::int32_t>::min();
      max = std::numeric_limits<std::int32_t>::max();
      break;
  }
  if (value < min || value > max) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{} does not fit {} ({} .. {})", value, ToString(type), min, max));
  }
  const auto bits = static_cast<std::uint32_t>(value);
  if (RegisterCount(type) == 1) return std::vector<std::uint16_t>{static_cast<std::uint16_t>(bits)};
  const auto high = static_cast<std::uint16_t>(bits >> 16);
  const auto low = static_cast<std::uint16_t>(bits & 0xFFFF);
  if (order == WordOrder::kHighFirst) return std::vector<std::uint16_t>{high, low};
  return std::vector<std::uint16_t>{low, high};
}

std::int64_t DecodeValue(std::span<const std::uint16_t> registers, ValueType type,
                         WordOrder order) {
  switch (type) {
    case ValueType::kU16:
      return registers[0];
    case ValueType::kI16:
      return static_cast<std::int16_t>(registers[0]);
    case ValueType::kU32:
    case ValueType::kI32: {
      const std::uint32_t high = order == WordOrder::kHighFirst ? registers[0] : registers[1];
      const std::uint32_t low = order == WordOrder::kHighFirst ? registers[1] : registers[0];
      const std::uint32_t bits = high << 16 | low;
      return type == ValueType::kU32 ? static_cast<std::int64_t>(bits)
                                     : static_cast<std::int64_t>(static_cast<std::int32_t>(bits));
    }
  }
  return 0;
}

const Command* DriveProfile::FindCommand(std::string_view command_name) const {
  const auto it = commands.find(command_name);
  return it == commands.end() ? nullptr : &it->second;
}

// The steps of ParseProfile, one per table; each fills its part of `profile` or names the key.
namespace {

// [profile]: description, steps_per_rev (required), word order.
Expected<void> ParseHead(const config::Document& /*document*/, const config::Section& root,
                         DriveProfile& profile) {
  Expected<config::Section> head = root.Child("profile");
  if (!head) return std::unexpected(head.error());
  Expected<std::string> description = head->String("description", profile.name);
  if (!description) return std::unexpected(description.error());
  profile.description = *description;
  if (!head->Has("steps_per_rev")) {
    return std::unexpected(head->BadValue(
        "steps_per_rev", "is required: the drive's counts per motor revolution (see the manual)"));
  }
  Expected<std::int64_t> steps = head->Integer("steps_per_rev", 0, 1, 100'000'000);
  if (!steps) return std::unexpected(steps.error());
  profile.steps_per_rev = *steps;
  Expected<WordOrder> order = ParseWordOrder(*head, WordOrder::kHighFirst);
  if (!order) return std::unexpected(order.error());
  profile.word_order = *order;
  if (Expected<void> known = head->CheckNoUnknownKeys(); !known) {
    return std::unexpected(known.error());
  }
  return {};
}

// [params]: named numbers the commands may use (not the move variables).
Expected<void> ParseParams(const config::Document& document, const config::Section& root,
                           DriveProfile& profile) {
  Expected<config::Section> params = root.Child("params");
  if (!params) return std::unexpected(params.error());
  for (const std::string& key : KeysOf(TableAt(document, "params"))) {
    if (std::find(std::begin(kMoveVariables), std::end(kMoveVariables), key) !=
        std::end(kMoveVariables)) {
      return std::unexpected(params->BadValue(key, "is the name of a move variable"));
    }
    Expected<double> value = params->Number(key, 0.0, -1e12, 1e12);
    if (!value) return std::unexpected(value.error());
    profile.params[key] = *value;
  }
  return {};
}

// [fields.*]: the registers read back; position is required.
Expected<void> ParseFields(const config::Document& document, const config::Section& root,
                           DriveProfile& profile) {
  Expected<config::Section> fields = root.Child("fields");
  if (!fields) return std::unexpected(fields.error());
  for (const std::string& key : KeysOf(TableAt(document, "fields"))) {
    if (!IsIdentifier(key)) {
      return std::unexpected(fields->BadValue(key, "field names are letters, digits and _"));
    }
    Expected<config::Section> field_section = fields->Child(key);
    if (!field_section) return std::unexpected(field_section.error());
    Expected<Field> field = ParseField(*field_section, key, profile.word_order);
    if (!field) return std::unexpected(field.error());
    profile.fields[key] = std::move(*field);
  }
  if (!profile.fields.contains("position")) {
    return std::unexpected(fields->BadValue(
        "position", "is required: [fields.position] holds the read-back position in counts"));
  }
  return {};
}

// [commands]: ordered register writes; move and stop are required.
Expected<void> ParseCommands(const config::Document& document, const config::Section& root,
                             DriveProfile& profile) {
  Expected<config::Section> commands = root.Child("commands");
  if (!commands) return std::unexpected(commands.error());
  for (const std::string& key : KeysOf(TableAt(document, "commands"))) {
    if (std::find(std::begin(kCommandNames), std::end(kCommandNames), key) ==
        std::end(kCommandNames)) {
      return std::unexpected(commands->BadValue(
          key,
          "unknown command (expected enable, disable, move, home, stop, reset_alarm or "
          "init)"));
    }
    Expected<std::vector<std::string>> texts = commands->Strings(key, {});
    if (!texts) return std::unexpected(texts.error());
    Command command;
    command.name = key;
    for (std::size_t i = 0; i < texts->size(); ++i) {
      Expected<Step> step = ParseStep((*texts)[i], profile.word_order);
      if (!step) {
        return std::unexpected(
            commands->BadValue(key, fmt::format("step {}: {}", i + 1, step.error().message)));
      }
      for (const ValueTemplate& value : step->values) {
        if (value.variable.empty() || profile.params.contains(value.variable)) continue;
        const bool move_variable = std::find(std::begin(kMoveVariables), std::end(kMoveVariables),
                                             value.variable) != std::end(kMoveVariables);
        if (key != "move" || !move_variable) {
          return std::unexpected(commands->BadValue(
              key, fmt::format("step {}: unknown variable ${{{}}} (move may use {}; every "
                               "command may use the names in [params])",
                               i + 1, value.variable, fmt::join(kMoveVariables, ", "))));
        }
      }
      command.steps.push_back(std::move(*step));
    }
    if (command.steps.empty()) {
      return std::unexpected(commands->BadValue(key, "has no steps"));
    }
    profile.commands[key] = std::move(command);
  }
  for (std::string_view required : {"move", "stop"}) {
    if (!profile.commands.contains(required)) {
      return std::unexpected(
          commands->BadValue(required, "is required (an ordered list of register writes)"));
    }
  }
  return {};
}

// [status]: expressions over the fields; moving is required.
Expected<void> ParseStatus(const config::Document& /*document*/, const config::Section& root,
                           DriveProfile& profile) {
  Expected<config::Section> status = root.Child("status");
  if (!status) return std::unexpected(status.error());
  auto rule = [&](std::string_view key,
                  bool required) -> Expected<std::optional<StatusExpression>> {
    if (!status->Has(key)) {
      if (required) return std::unexpected(status->BadValue(key, "is required"));
      return std::optional<StatusExpression>();
    }
    Expected<std::string> text = status->String(key, "");
    if (!text) return std::unexpected(text.error());
    Expected<StatusExpression> expression = StatusExpression::Parse(*text);
    if (!expression) return std::unexpected(status->BadValue(key, expression.error().message));
    for (const std::string& field : expression->Fields()) {
      if (!profile.fields.contains(field)) {
        return std::unexpected(status->BadValue(
            key, fmt::format("\"{}\" is not a field of this profile ([fields.{}] is missing)",
                             field, field)));
      }
    }
    return std::optional<StatusExpression>(std::move(*expression));
  };
  Expected<std::optional<StatusExpression>> moving = rule("moving", true);
  if (!moving) return std::unexpected(moving.error());
  profile.status.moving = std::move(**moving);
  struct Optional {
    std::string_view key;
    std::optional<StatusExpression>* out;
  };
  for (const Optional& o :
       {Optional{"in_position", &profile.status.in_position},
        Optional{"alarm", &profile.status.alarm}, Optional{"enabled", &profile.status.enabled},
        Optional{"homed", &profile.status.homed}}) {
    Expected<std::optional<StatusExpression>> parsed = rule(o.key, false);
    if (!parsed) return std::unexpected(parsed.error());
    *o.out = std::move(*parsed);
  }
  if (status->Has("alarm_code")) {
    Expected<std::string> field = status->String("alarm_code", "");
    if (!field) return std::unexpected(field.error());
    if (!profile.fields.contains(*field)) {
      return std::unexpected(status->BadValue(
          "alarm_code", fmt::format("\"{}\" is not a field of this profile", *field)));
    }
    profile.status.alarm_code_field = *field;
  }
  if (Expected<void> known = status->CheckNoUnknownKeys(); !known) {
    return std::unexpected(known.error());
  }
  return {};
}

// [alarms]: texts by alarm code.
Expected<void> ParseAlarms(const config::Document& document, const config::Section& root,
                           DriveProfile& profile) {
  Expected<config::Section> alarms = root.Child("alarms");
  if (!alarms) return std::unexpected(alarms.error());
  for (const std::string& key : KeysOf(TableAt(document, "alarms"))) {
    Expected<std::int64_t> code = ParseInteger(key);
    if (!code) {
      return std::unexpected(alarms->BadValue(key, "alarm keys are codes (decimal or 0x hex)"));
    }
    Expected<std::string> text = alarms->String(key, "");
    if (!text) return std::unexpected(text.error());
    profile.alarm_texts[*code] = *text;
  }
  return {};
}

}  // namespace

Expected<DriveProfile> ParseProfile(const config::Document& document, std::string name) {
  DriveProfile profile;
  profile.name = std::move(name);
  profile.origin = document.origin;
  const config::Section root = config::Section::Root(document);
  for (auto* step :
       {ParseHead, ParseParams, ParseFields, ParseCommands, ParseStatus, ParseAlarms}) {
    if (Expected<void> parsed = step(document, root, profile); !parsed) {
      return std::unexpected(parsed.error());
    }
  }
  if (Expected<void> known = root.CheckNoUnknownKeys(); !known) {
    return std::unexpected(known.error());
  }
  return profile;
}

Expected<DriveProfile> LoadProfileFile(const std::filesystem::path& path) {
  Expected<config::Document> document = config::LoadFile(path);
  if (!document) return std::unexpected(document.error());
  return ParseProfile(*document, path.stem().string());
}

Expected<std::vector<RenderedStep>> RenderCommand(const DriveProfile& profile,
                                                  const Command& command,
                                                  const Variables& variables) {
  std::vector<RenderedStep> out;
  for (std::size_t i = 0; i < command.steps.size(); ++i) {
    const Step& step = command.steps[i];
    auto fail = [&](const std::string& what) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("profile {} ({}), command {}, step {} \"{}\": {}", profile.name,
                                   profile.origin, command.name, i + 1, step.text, what));
    };
    RenderedStep rendered;
    if (step.kind == Step::Kind::kSleep) {
      rendered.sleep_ms = step.sleep_ms;
      out.push_back(std::move(rendered));
      continue;
    }
    std::vector<std::uint16_t> registers;
    for (const ValueTemplate& value : step.values) {
      std::int64_t number = value.literal;
      if (!value.variable.empty()) {
        const auto it = variables.find(value.variable);
        if (it == variables.end()) return fail(fmt::format("${{{}}} has no value", value.variable));
        const double scaled = it->second * value.factor;
        if (!std::isfinite(scaled) || std::fabs(scaled) > 9e15) {
          return fail(fmt::format("${{{}}} = {} is not a usable number", value.variable, scaled));
        }
        number = std::llround(scaled);
      }
      Expected<std::vector<std::uint16_t>> encoded =
          EncodeValue(number, value.type, value.word_order);
      if (!encoded) {
        return fail(fmt::format(
            "{}{}",
            value.variable.empty() ? "" : "${" + value.variable + "} = ", encoded.error().message));
      }
      registers.insert(registers.end(), encoded->begin(), encoded->end());
    }
    Request request;
    request.address = step.address;
    request.values = std::move(registers);
    switch (step.kind) {
      case Step::Kind::kWriteRegister:
        request.function = FunctionCode::kWriteSingleRegister;
        break;
      case Step::Kind::kWriteRegisters:
        request.function = FunctionCode::kWriteMultipleRegisters;
        break;
      case Step::Kind::kWriteCoil:
        request.function = FunctionCode::kWriteSingleCoil;
        break;
      case Step::Kind::kSleep:
        break;
    }
    rendered.request = std::move(request);
    out.push_back(std::move(rendered));
  }
  return out;
}

std::vector<FieldRead> PlanFieldReads(const DriveProfile& profile) {
  std::vector<const Field*> sorted;
  sorted.reserve(profile.fields.size());
  for (const auto& [name, field] : profile.fields) sorted.push_back(&field);
  std::sort(sorted.begin(), sorted.end(), [](const Field* a, const Field* b) {
    return std::pair(a->table, a->address) < std::pair(b->table, b->address);
  });
  std::vector<FieldRead> reads;
  for (const Field* field : sorted) {
    const int count = RegisterCount(field->type);
    if (!reads.empty()) {
      FieldRead& last = reads.back();
      if (last.table == field->table && last.address + last.count == field->address &&
          last.count + count <= kMaxReadRegisters) {
        last.count = static_cast<std::uint16_t>(last.count + count);
        last.fields.push_back(field->name);
        continue;
      }
      // Overlapping fields (two views of one register) share the read when it covers them.
      if (last.table == field->table && field->address >= last.address &&
          field->address + count <= last.address + last.count) {
        last.fields.push_back(field->name);
        continue;
      }
    }
    reads.push_back(
        FieldRead{field->table, field->address, static_cast<std::uint16_t>(count), {field->name}});
  }
  return reads;
}

void DecodeFields(const DriveProfile& profile, const FieldRead& read,
                  std::span<const std::uint16_t> registers, FieldValues& out) {
  for (const std::string& name : read.fields) {
    const Field& field = profile.fields.find(name)->second;
    const std::size_t offset = field.address - read.address;
    if (offset + RegisterCount(field.type) > registers.size()) continue;
    out[name] = DecodeValue(registers.subspan(offset), field.type, field.word_order);
  }
}

}  // namespace revolve::turntable::modbus
