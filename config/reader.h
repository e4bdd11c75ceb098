// Reader: a parser over one config::Section that reads as a list of keys. Each getter sets `out`
// from its key (and leaves it as is when the key is absent) unless an earlier getter failed; the
// first error is kept and reported by Finish() (or error()).
#pragma once

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "base/error.h"
#include "config/config.h"

namespace revolve::config {

class Reader {
 public:
  explicit Reader(const Section& section) : section_(section) {}

  // A number in [min, max].
  void Number(std::string_view key, double& out, double min, double max);
  // A number in (min, max]: "must be greater than <min> (and at most <max>)".
  void NumberAbove(std::string_view key, double& out, double min, double max);
  // An integer in [min, max], stored into any integer type.
  template <class Int>
  void Integer(std::string_view key, Int& out, std::int64_t min, std::int64_t max) {
    if (error_) return;
    if (Expected<std::int64_t> v = section_.Integer(key, out, min, max); v) {
      out = static_cast<Int>(*v);
    } else {
      error_ = v.error();
    }
  }
  void Boolean(std::string_view key, bool& out);
  // `allowed` empty means any string.
  void String(std::string_view key, std::string& out,
              std::initializer_list<std::string_view> allowed = {});
  void Strings(std::string_view key, std::vector<std::string>& out);
  // An array of numbers in [min, max] whose length is a multiple of `group` (0: any length;
  // `exact` > 0: exactly that many, or none).
  void Numbers(std::string_view key, std::vector<double>& out, double min, double max,
               std::size_t group, std::size_t exact = 0);
  // A path, relative to the config file's folder (see Section::Path).
  void Path(std::string_view key, std::string& out);
  // An optional value: set only when the key is present, by `get(key, value)` (one of the
  // getters above, through a lambda).
  template <class T, class Get>
  void Optional(std::string_view key, std::optional<T>& out, Get get) {
    if (error_ || !section_.Has(key)) return;
    T value{};
    get(key, value);
    if (KeyRecord* record = section_.Recorded(key)) record->optional = true;
    if (!error_) out = std::move(value);
  }

  // Records `error` unless an earlier one is kept.
  void Fail(Error error) {
    if (!error_) error_ = std::move(error);
  }
  bool ok() const { return !error_.has_value(); }
  const std::optional<Error>& error() const { return error_; }
  // The first error, or the first unknown key of the table (Section::CheckNoUnknownKeys).
  Expected<void> Finish() const;
  const Section& section() const { return section_; }

 private:
  const Section& section_;
  std::optional<Error> error_;
};

}  // namespace revolve::config
