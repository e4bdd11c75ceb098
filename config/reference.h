// The configuration reference, made from the parsers themselves: while a Document's `reference`
// is set, every typed getter of its Sections records the key it reads (table, type, default,
// range or allowed values). MarkdownReference joins those records with each key's description
// (a KeyDoc table next to each module's parser) into docs/configuration.md.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace revolve::config {

// One key as a parser reads it.
struct KeyRecord {
  std::string table;     // dotted path of its table: "turntable.mock"
  std::string key;       // "speed_deg_per_s"
  std::string type;      // number, integer, boolean, string, path, numbers, strings
  std::string fallback;  // the default in TOML notation: 30, "mock", [1, 2]
  std::optional<double> min, max;
  bool above_min = false;            // min itself is not allowed
  std::vector<std::string> allowed;  // strings: the allowed values (empty: any)
  std::string count;                 // numbers: "3 or none", "groups of 6"
  bool optional = false;             // read only when present: no default
};

// The records of one parse (or several: a key read again with the same type is kept once).
class Reference {
 public:
  // Adds `record` unless its table, key and type are known already. A "string" read of a key
  // already known as a "path" is the path's own read and adds nothing.
  void Note(KeyRecord record);
  // The last record of table.key, or nullptr.
  KeyRecord* Find(std::string_view table, std::string_view key);
  const std::vector<KeyRecord>& keys() const { return keys_; }

 private:
  std::vector<KeyRecord> keys_;
};

// The description of one key; `unit` and the overrides are optional. An override (Markdown)
// replaces what the records say, for the few keys a parser reads in more than one way (an
// integer or a string, say) or checks beyond the getter's range.
struct KeyDoc {
  std::string_view table;
  std::string_view key;
  std::string_view unit;
  std::string_view text;
  std::string_view type_override = {};
  std::string_view default_override = {};
  std::string_view allowed_override = {};
};

// The description of a table (Markdown, may be empty), in the order the reference lists them.
struct TableDoc {
  std::string_view table;
  std::string_view text;
};

// The descriptions of one module's tables and keys.
struct OptionDocs {
  std::span<const TableDoc> tables;
  std::span<const KeyDoc> keys;
};

// Markdown: `intro`, then one section per table of `tables` with a row per recorded key.
std::string MarkdownReference(const Reference& reference, std::string_view intro,
                              std::span<const TableDoc> tables, std::span<const KeyDoc> keys);

// What does not match between the records and the descriptions, one line each: a recorded key
// or table with no description, a description of a key or table that no parser reads.
std::vector<std::string> ReferenceGaps(const Reference& reference, std::span<const TableDoc> tables,
                                       std::span<const KeyDoc> keys);

// A number as the reference writes it: integers without a fraction, others shortest.
std::string FormatReferenceNumber(double value);

}  // namespace revolve::config
