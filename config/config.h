// TOML configuration: parsing with errors that name the file, line, column and key; typed
// getters with defaults and ranges; unknown keys are errors.
//
// Each module parses its own section next to its options struct, through `Section`.
#pragma once

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <toml++/toml.h>

#include "base/error.h"
#include "config/reference.h"

namespace revolve::config {

// A parsed document and where it came from (a path, or "<embedded default config>").
struct Document {
  std::string origin;
  std::string text;
  toml::table root;
  // When set, every getter of the document's Sections records the key it reads (for the
  // configuration reference; see config/reference.h). Not owned.
  Reference* reference = nullptr;
};

// Reads and parses a file. Errors: not_found (names the file), bad_input with
// "<file>:<line>:<column>: <what is wrong>" for a syntax error.
Expected<Document> LoadFile(const std::filesystem::path& path);

// Parses text; `origin` names it in errors.
Expected<Document> Parse(std::string text, std::string origin);

// The configuration shipped with revolve (config/examples/default.toml): the simulated rig.
std::string_view EmbeddedDefault();
inline constexpr std::string_view kEmbeddedOrigin = "<embedded default config>";

// The largest integer a double holds exactly (2^53): an integer beyond it on a number key is an
// error, never rounded or replaced.
inline constexpr std::int64_t kMaxExactInteger = std::int64_t{1} << 53;

// One table of a document. Remembers which keys were read so that unknown keys can be
// reported. A missing table behaves as an empty one. Cheap to copy; copies share the record of
// read keys. The Document must outlive it.
class Section {
 public:
  Section(const Document& document, std::string path, const toml::table* table);

  // The top-level table of a document.
  static Section Root(const Document& document);

  // "[turntable.mock]" style dotted path of this table ("" for the root).
  const std::string& path() const { return path_; }
  const std::string& origin() const { return document_->origin; }
  bool Has(std::string_view key) const;

  // Typed getters: the value of `key`, or `fallback` when it is absent. A value of the wrong
  // type or outside [min, max] is a bad_input error naming file:line:column and the key. Every
  // number read (Number, Numbers) is finite (nan and inf are errors) and representable (an
  // integer beyond 2^53 on a number key is an error).
  Expected<double> Number(std::string_view key, double fallback, double min, double max) const;
  Expected<std::int64_t> Integer(std::string_view key, std::int64_t fallback, std::int64_t min,
                                 std::int64_t max) const;
  Expected<bool> Boolean(std::string_view key, bool fallback) const;
  // `allowed` empty means any string.
  Expected<std::string> String(std::string_view key, std::string fallback,
                               std::initializer_list<std::string_view> allowed = {}) const;
  // A file or folder path (a string). A relative path is taken relative to the config file's
  // folder, so a config and the files it names move together; the embedded default's paths
  // stay as given. Empty stays empty.
  Expected<std::filesystem::path> Path(std::string_view key,
                                       const std::filesystem::path& fallback = {}) const;
  // An array of numbers; `count` 0 means any length.
  Expected<std::vector<double>> Numbers(std::string_view key, std::vector<double> fallback,
                                        std::size_t count = 0) const;
  // An array of strings.
  Expected<std::vector<std::string>> Strings(std::string_view key,
                                             std::vector<std::string> fallback) const;

  // The sub-table `key` (an empty Section when absent; an error when `key` is not a table).
  Expected<Section> Child(std::string_view key) const;

  // bad_input naming the first key of this table that no getter asked for, with its position.
  // Sub-tables are checked by their own Section.
  Expected<void> CheckNoUnknownKeys() const;

  // A bad_input error "<file>:<line>:<column>: <path.key>: <what>" at the key's position (or the
  // table's, when the key is absent).
  Error BadValue(std::string_view key, std::string_view what) const;

  // The record of the key `key` read last, while the document records a reference (else
  // nullptr): for a caller that checks more than the getter did (a bound excluded, say).
  KeyRecord* Recorded(std::string_view key) const;

 private:
  const toml::node* Find(std::string_view key) const;
  std::string Where(const toml::node* node) const;
  std::string Dotted(std::string_view key) const;
  // Records `key` when the document records a reference.
  void Note(std::string_view key, std::string_view type, std::string fallback,
            std::optional<double> min = {}, std::optional<double> max = {},
            std::initializer_list<std::string_view> allowed = {}) const;

  const Document* document_;
  std::string path_;
  const toml::table* table_;
  std::shared_ptr<std::set<std::string, std::less<>>> read_keys_;
};

}  // namespace revolve::config
