#include "config/config.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <utility>

#include <fmt/format.h>

#include <fmt/ranges.h>
#include "base/text_file.h"

namespace revolve::config {
namespace {

std::string JoinAllowed(std::initializer_list<std::string_view> allowed) {
  std::string out;
  for (std::string_view a : allowed) {
    if (!out.empty()) out += ", ";
    out += '"';
    out += a;
    out += '"';
  }
  return out;
}

// The value of a TOML number node as a double, or why it cannot be one: an integer beyond 2^53
// is not representable exactly (toml++ would give no value, and the caller's fallback would
// silently take its place); nan and inf are never valid option values.
std::expected<double, std::string> FiniteDouble(const toml::node& node) {
  if (const toml::value<std::int64_t>* integer = node.as_integer()) {
    const std::int64_t v = integer->get();
    if (v > kMaxExactInteger || v < -kMaxExactInteger) {
      return std::unexpected(
          fmt::format("{} is too large to be represented exactly as a number (at most 2^53 = {})",
                      v, kMaxExactInteger));
    }
    return static_cast<double>(v);
  }
  if (const toml::value<double>* floating = node.as_floating_point()) {
    const double v = floating->get();
    if (!std::isfinite(v)) {
      return std::unexpected(fmt::format("{} is not a finite number", v));
    }
    return v;
  }
  return std::unexpected(std::string("expected a number"));
}

}  // namespace

Expected<Document> Parse(std::string text, std::string origin) {
  Document document;
  document.origin = std::move(origin);
  document.text = std::move(text);
  try {
    document.root = toml::parse(document.text, document.origin);
  } catch (const toml::parse_error& e) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{}:{}:{}: TOML syntax error: {}", document.origin,
                                 e.source().begin.line, e.source().begin.column, e.description()));
  }
  return document;
}

Expected<Document> LoadFile(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return MakeError(
        ErrorCode::kNotFound,
        fmt::format("{}: config file not found (check the path given to --config)", path.string()));
  }
  if (std::filesystem::is_directory(path, ec)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{}: is a directory, expected a TOML config file", path.string()));
  }
  // 16 MB is far more than any configuration; a device or FIFO is refused, never read.
  auto text = ReadRegularFile(path, std::uintmax_t{16} << 20);
  if (!text) {
    return MakeError(text.error().code,
                     fmt::format("{} (expected a TOML config file)", text.error().message));
  }
  return Parse(std::move(*text), path.string());
}

Section::Section(const Document& document, std::string path, const toml::table* table)
    : document_(&document),
      path_(std::move(path)),
      table_(table),
      read_keys_(std::make_shared<std::set<std::string, std::less<>>>()) {}

Section Section::Root(const Document& document) { return Section(document, "", &document.root); }

const toml::node* Section::Find(std::string_view key) const {
  read_keys_->emplace(key);
  if (table_ == nullptr) return nullptr;
  return table_->get(key);
}

bool Section::Has(std::string_view key) const {
  return table_ != nullptr && table_->get(key) != nullptr;
}

std::string Section::Dotted(std::string_view key) const {
  return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

std::string Section::Where(const toml::node* node) const {
  if (node == nullptr && table_ != nullptr) node = table_;
  if (node == nullptr || node->source().begin.line == 0) return document_->origin;
  return fmt::format("{}:{}:{}", document_->origin, node->source().begin.line,
                     node->source().begin.column);
}

Error Section::BadValue(std::string_view key, std::string_view what) const {
  const toml::node* node = table_ != nullptr ? table_->get(key) : nullptr;
  return Error{ErrorCode::kBadInput, fmt::format("{}: {}: {}", Where(node), Dotted(key), what)};
}

void Section::Note(std::string_view key, std::string_view type, std::string fallback,
                   std::optional<double> min, std::optional<double> max,
                   std::initializer_list<std::string_view> allowed) const {
  if (document_->reference == nullptr) return;
  KeyRecord record;
  record.table = path_;
  record.key = key;
  record.type = type;
  record.fallback = std::move(fallback);
  record.min = min;
  record.max = max;
  record.allowed.assign(allowed.begin(), allowed.end());
  document_->reference->Note(std::move(record));
}

KeyRecord* Section::Recorded(std::string_view key) const {
  return document_->reference == nullptr ? nullptr : document_->reference->Find(path_, key);
}

Expected<double> Section::Number(std::string_view key, double fallback, double min,
                                 double max) const {
  Note(key, "number", FormatReferenceNumber(fallback), min, max);
  const toml::node* node = Find(key);
  if (node == nullptr) return fallback;
  const std::expected<double, std::string> number = FiniteDouble(*node);
  if (!number) return std::unexpected(BadValue(key, number.error()));
  const double value = *number;
  // Written so that a nan bound or value can never pass.
  if (!(value >= min && value <= max)) {
    return std::unexpected(
        BadValue(key, fmt::format("{} is out of range [{}, {}]", value, min, max)));
  }
  return value;
}

Expected<std::int64_t> Section::Integer(std::string_view key, std::int64_t fallback,
                                        std::int64_t min, std::int64_t max) const {
  Note(key, "integer", std::to_string(fallback), static_cast<double>(min),
       static_cast<double>(max));
  const toml::node* node = Find(key);
  if (node == nullptr) return fallback;
  if (!node->is_integer()) return std::unexpected(BadValue(key, "expected an integer"));
  const std::int64_t value = node->as_integer()->get();
  if (value < min || value > max) {
    return std::unexpected(
        BadValue(key, fmt::format("{} is out of range [{}, {}]", value, min, max)));
  }
  return value;
}

Expected<bool> Section::Boolean(std::string_view key, bool fallback) const {
  Note(key, "boolean", fallback ? "true" : "false");
  const toml::node* node = Find(key);
  if (node == nullptr) return fallback;
  if (!node->is_boolean()) return std::unexpected(BadValue(key, "expected true or false"));
  return node->as_boolean()->get();
}

Expected<std::string> Section::String(std::string_view key, std::string fallback,
                                      std::initializer_list<std::string_view> allowed) const {
  Note(key, "string", fmt::format("\"{}\"", fallback), {}, {}, allowed);
  const toml::node* node = Find(key);
  if (node == nullptr) return fallback;
  if (!node->is_string()) return std::unexpected(BadValue(key, "expected a string"));
  std::string value = node->as_string()->get();
  if (allowed.size() > 0 &&
      std::find(allowed.begin(), allowed.end(), std::string_view(value)) == allowed.end()) {
    return std::unexpected(
        BadValue(key, fmt::format("\"{}\" is not one of {}", value, JoinAllowed(allowed))));
  }
  return value;
}

Expected<std::filesystem::path> Section::Path(std::string_view key,
                                              const std::filesystem::path& fallback) const {
  Note(key, "path", fmt::format("\"{}\"", fallback.string()));
  Expected<std::string> value = String(key, fallback.string());
  if (!value) return std::unexpected(value.error());
  std::filesystem::path path(*value);
  if (path.empty() || !path.is_relative() || origin() == kEmbeddedOrigin) return path;
  const std::filesystem::path base = std::filesystem::path(origin()).parent_path();
  return base.empty() ? path : (base / path).lexically_normal();
}

Expected<std::vector<double>> Section::Numbers(std::string_view key, std::vector<double> fallback,
                                               std::size_t count) const {
  Note(key, "numbers", fallback.empty() ? "[]" : fmt::format("[{}]", fmt::join(fallback, ", ")));
  if (KeyRecord* r = Recorded(key); r != nullptr && count != 0) {
    r->count = fmt::format("exactly {}", count);
  }
  const toml::node* node = Find(key);
  if (node == nullptr) return fallback;
  const toml::array* array = node->as_array();
  if (array == nullptr) return std::unexpected(BadValue(key, "expected an array of numbers"));
  std::vector<double> values;
  for (const toml::node& element : *array) {
    if (!element.is_number()) {
      return std::unexpected(BadValue(key, "expected an array of numbers"));
    }
    const std::expected<double, std::string> number = FiniteDouble(element);
    if (!number) {
      return std::unexpected(
          BadValue(key, fmt::format("element {}: {}", values.size() + 1, number.error())));
    }
    values.push_back(*number);
  }
  if (count != 0 && values.size() != count) {
    return std::unexpected(
        BadValue(key, fmt::format("expected {} numbers, got {}", count, values.size())));
  }
  return values;
}

Expected<std::vector<std::string>> Section::Strings(std::string_view key,
                                                    std::vector<std::string> fallback) const {
  Note(key, "strings",
       fallback.empty() ? "[]" : fmt::format("[\"{}\"]", fmt::join(fallback, "\", \"")));
  const toml::node* node = Find(key);
  if (node == nullptr) return fallback;
  const toml::array* array = node->as_array();
  if (array == nullptr) return std::unexpected(BadValue(key, "expected an array of strings"));
  std::vector<std::string> values;
  for (const toml::node& element : *array) {
    if (!element.is_string()) {
      return std::unexpected(BadValue(key, "expected an array of strings"));
    }
    values.push_back(element.as_string()->get());
  }
  return values;
}

Expected<Section> Section::Child(std::string_view key) const {
  const toml::node* node = Find(key);
  if (node == nullptr) return Section(*document_, Dotted(key), nullptr);
  if (!node->is_table()) return std::unexpected(BadValue(key, "expected a table"));
  return Section(*document_, Dotted(key), node->as_table());
}

Expected<void> Section::CheckNoUnknownKeys() const {
  if (table_ == nullptr) return {};
  // Tables iterate in key order; report the unknown key that comes first in the file.
  const toml::key* first = nullptr;
  for (auto&& [key, node] : *table_) {
    if (read_keys_->contains(key.str())) continue;
    const auto position = [](const toml::key& k) {
      return std::pair(k.source().begin.line, k.source().begin.column);
    };
    if (first == nullptr || position(key) < position(*first)) first = &key;
  }
  if (first == nullptr) return {};
  std::string where = document_->origin;
  if (first->source().begin.line != 0) {
    where = fmt::format("{}:{}:{}", document_->origin, first->source().begin.line,
                        first->source().begin.column);
  }
  return MakeError(ErrorCode::kBadInput, fmt::format("{}: unknown key \"{}\" (check the spelling; "
                                                     "docs/configuration.md lists every key)",
                                                     where, Dotted(first->str())));
}

}  // namespace revolve::config
