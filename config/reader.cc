#include "config/reader.h"

#include <fmt/format.h>

namespace revolve::config {

void Reader::Number(std::string_view key, double& out, double min, double max) {
  if (error_) return;
  if (Expected<double> v = section_.Number(key, out, min, max); v) {
    out = *v;
  } else {
    error_ = v.error();
  }
}

void Reader::NumberAbove(std::string_view key, double& out, double min, double max) {
  if (error_) return;
  Expected<double> v = section_.Number(key, out, min, max);
  if (KeyRecord* record = section_.Recorded(key)) record->above_min = true;
  if (!v) {
    error_ = v.error();
  } else if (*v <= min) {
    error_ =
        section_.BadValue(key, fmt::format("must be greater than {} (and at most {})", min, max));
  } else {
    out = *v;
  }
}

void Reader::Boolean(std::string_view key, bool& out) {
  if (error_) return;
  if (Expected<bool> v = section_.Boolean(key, out); v) {
    out = *v;
  } else {
    error_ = v.error();
  }
}

void Reader::String(std::string_view key, std::string& out,
                    std::initializer_list<std::string_view> allowed) {
  if (error_) return;
  if (Expected<std::string> v = section_.String(key, out, allowed); v) {
    out = *v;
  } else {
    error_ = v.error();
  }
}

void Reader::Strings(std::string_view key, std::vector<std::string>& out) {
  if (error_) return;
  if (Expected<std::vector<std::string>> v = section_.Strings(key, out); v) {
    out = *v;
  } else {
    error_ = v.error();
  }
}

void Reader::Numbers(std::string_view key, std::vector<double>& out, double min, double max,
                     std::size_t group, std::size_t exact) {
  if (error_) return;
  Expected<std::vector<double>> value = section_.Numbers(key, out);
  if (KeyRecord* record = section_.Recorded(key)) {
    record->min = min;
    record->max = max;
    if (exact > 0) record->count = fmt::format("{} or none", exact);
    if (group > 0) record->count = fmt::format("groups of {}", group);
  }
  if (!value) {
    error_ = value.error();
    return;
  }
  if (exact > 0 && !value->empty() && value->size() != exact) {
    error_ = section_.BadValue(key, fmt::format("needs {} numbers, got {}", exact, value->size()));
    return;
  }
  if (group > 0 && value->size() % group != 0) {
    error_ = section_.BadValue(
        key, fmt::format("needs groups of {} numbers, got {}", group, value->size()));
    return;
  }
  for (double v : *value) {
    if (!(v >= min && v <= max)) {
      error_ = section_.BadValue(key, fmt::format("{} is out of range [{}, {}]", v, min, max));
      return;
    }
  }
  out = *value;
}

void Reader::Path(std::string_view key, std::string& out) {
  if (error_) return;
  if (Expected<std::filesystem::path> v = section_.Path(key, out); v) {
    out = v->string();
  } else {
    error_ = v.error();
  }
}

Expected<void> Reader::Finish() const {
  if (error_) return std::unexpected(*error_);
  return section_.CheckNoUnknownKeys();
}

}  // namespace revolve::config
