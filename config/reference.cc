#include "config/reference.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace revolve::config {
namespace {

// Bounds at or beyond this are no bound at all (infinity, INT64_MAX).
constexpr double kUnbounded = 1e15;

std::string Range(const KeyRecord& r) {
  const bool has_min = r.min && *r.min > -kUnbounded;
  const bool has_max = r.max && *r.max < kUnbounded;
  const std::string min = has_min ? FormatReferenceNumber(*r.min) : "";
  const std::string max = has_max ? FormatReferenceNumber(*r.max) : "";
  if (has_min && has_max) return fmt::format("{}{}, {}]", r.above_min ? "(" : "[", min, max);
  if (has_min) return fmt::format("{} {}", r.above_min ? ">" : "≥", min);
  if (has_max) return fmt::format("≤ {}", max);
  return "";
}

std::string Allowed(const KeyRecord& r) {
  if (!r.allowed.empty()) {
    std::string out;
    for (const std::string& a : r.allowed) out += fmt::format("{}`{}`", out.empty() ? "" : ", ", a);
    return out;
  }
  std::string range = Range(r);
  if (r.type == "numbers" && !range.empty()) range = "each in " + range;
  if (!r.count.empty()) range += (range.empty() ? "" : "; ") + r.count;
  return range;
}

// Cell text: a `|` would end the cell.
std::string Cell(std::string_view text) {
  std::string out;
  for (char c : text) {
    if (c == '|') out += '\\';
    out += c;
  }
  return out;
}

// The values of `part` over `records`, each once, joined by " or ".
template <class Part>
std::string Joined(const std::vector<const KeyRecord*>& records, Part part) {
  std::vector<std::string> seen;
  for (const KeyRecord* r : records) {
    std::string v = part(*r);
    if (!v.empty() && std::find(seen.begin(), seen.end(), v) == seen.end()) seen.push_back(v);
  }
  std::string out;
  for (const std::string& v : seen) out += (out.empty() ? "" : " or ") + v;
  return out;
}

const KeyDoc* FindDoc(std::span<const KeyDoc> keys, std::string_view table, std::string_view key) {
  for (const KeyDoc& d : keys) {
    if (d.table == table && d.key == key) return &d;
  }
  return nullptr;
}

// The tables in reference order: those of `tables` first, then any other recorded one.
std::vector<std::string> TableOrder(const Reference& reference, std::span<const TableDoc> tables) {
  std::vector<std::string> order;
  for (const TableDoc& t : tables) order.emplace_back(t.table);
  for (const KeyRecord& r : reference.keys()) {
    if (std::find(order.begin(), order.end(), r.table) == order.end()) order.push_back(r.table);
  }
  return order;
}

// The GitHub anchor of the heading "`[table]`".
std::string Anchor(std::string_view table) {
  std::string out;
  for (char c : table) {
    if (c != '.') out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return out;
}

}  // namespace

std::string FormatReferenceNumber(double value) {
  if (std::abs(value) < kUnbounded && value == std::floor(value)) {
    return fmt::format("{}", static_cast<long long>(value));
  }
  return fmt::format("{}", value);
}

void Reference::Note(KeyRecord record) {
  for (const KeyRecord& r : keys_) {
    if (r.table != record.table || r.key != record.key) continue;
    if (r.type == record.type || (r.type == "path" && record.type == "string")) return;
  }
  keys_.push_back(std::move(record));
}

KeyRecord* Reference::Find(std::string_view table, std::string_view key) {
  for (auto it = keys_.rbegin(); it != keys_.rend(); ++it) {
    if (it->table == table && it->key == key) return &*it;
  }
  return nullptr;
}

std::string MarkdownReference(const Reference& reference, std::string_view intro,
                              std::span<const TableDoc> tables, std::span<const KeyDoc> keys) {
  std::string out(intro);
  const std::vector<std::string> order = TableOrder(reference, tables);
  out += "\nTables:";
  for (std::size_t i = 0; i < order.size(); ++i) {
    out += fmt::format("{}[`[{}]`](#{})", i == 0 ? " " : " ·\n", order[i], Anchor(order[i]));
  }
  out += "\n";
  for (const std::string& table : order) {
    out += fmt::format("\n## `[{}]`\n", table);
    for (const TableDoc& t : tables) {
      if (t.table == table && !t.text.empty()) out += fmt::format("\n{}\n", t.text);
    }
    // The keys of the table in the order of their descriptions, then any other in the order
    // they are read; a key read as two types is one row.
    std::vector<std::string> names;
    auto add = [&](std::string_view key) {
      const bool read =
          std::any_of(reference.keys().begin(), reference.keys().end(),
                      [&](const KeyRecord& r) { return r.table == table && r.key == key; });
      if (read && std::find(names.begin(), names.end(), key) == names.end())
        names.emplace_back(key);
    };
    for (const KeyDoc& d : keys) {
      if (d.table == table) add(d.key);
    }
    for (const KeyRecord& r : reference.keys()) {
      if (r.table == table) add(r.key);
    }
    if (names.empty()) continue;
    out += "\n| key | type | default | allowed | meaning |\n|---|---|---|---|---|\n";
    for (const std::string& name : names) {
      std::vector<const KeyRecord*> records;
      for (const KeyRecord& r : reference.keys()) {
        if (r.table == table && r.key == name) records.push_back(&r);
      }
      const KeyDoc* doc = FindDoc(keys, table, name);
      std::string type = Joined(records, [](const KeyRecord& r) { return r.type; });
      if (doc != nullptr && !doc->unit.empty()) type += fmt::format(" ({})", doc->unit);
      std::string fallback = Joined(records, [](const KeyRecord& r) {
        return r.optional ? std::string("unset") : "`" + r.fallback + "`";
      });
      std::string allowed = Joined(records, Allowed);
      if (doc != nullptr && !doc->type_override.empty()) type = doc->type_override;
      if (doc != nullptr && !doc->default_override.empty()) fallback = doc->default_override;
      if (doc != nullptr && !doc->allowed_override.empty()) allowed = doc->allowed_override;
      out += fmt::format("| `{}` | {} | {} | {} | {} |\n", name, Cell(type), Cell(fallback),
                         Cell(allowed), doc != nullptr ? Cell(doc->text) : "");
    }
  }
  return out;
}

std::vector<std::string> ReferenceGaps(const Reference& reference, std::span<const TableDoc> tables,
                                       std::span<const KeyDoc> keys) {
  std::vector<std::string> gaps;
  for (const KeyRecord& r : reference.keys()) {
    const std::string line = fmt::format("[{}] {}: no description", r.table, r.key);
    if (FindDoc(keys, r.table, r.key) == nullptr &&
        std::find(gaps.begin(), gaps.end(), line) == gaps.end()) {
      gaps.push_back(line);
    }
  }
  for (const KeyDoc& d : keys) {
    const bool read =
        std::any_of(reference.keys().begin(), reference.keys().end(),
                    [&](const KeyRecord& r) { return r.table == d.table && r.key == d.key; });
    if (!read)
      gaps.push_back(fmt::format("[{}] {}: described, but no parser reads it", d.table, d.key));
    if (d.text.empty()) gaps.push_back(fmt::format("[{}] {}: empty description", d.table, d.key));
  }
  for (const std::string& table : TableOrder(reference, tables)) {
    const bool described = std::any_of(tables.begin(), tables.end(),
                                       [&](const TableDoc& t) { return t.table == table; });
    if (!described) gaps.push_back(fmt::format("[{}]: a table missing from the table list", table));
  }
  return gaps;
}

}  // namespace revolve::config
