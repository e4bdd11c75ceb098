#include "station/manifest.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace revolve::station {
namespace {

using Json = nlohmann::json;

std::string_view TypeName(const Json& value) {
  if (value.is_number_integer()) return "an integer";
  if (value.is_number_float()) return "a number";
  switch (value.type()) {
    case Json::value_t::null:
      return "null";
    case Json::value_t::boolean:
      return "a boolean";
    case Json::value_t::string:
      return "a string";
    case Json::value_t::array:
      return "an array";
    case Json::value_t::object:
      return "an object";
    default:
      return "an unusable value";
  }
}

class Checker {
 public:
  explicit Checker(std::string_view origin) : origin_(origin) {}

  Error Bad(std::string_view field, std::string_view what) const {
    return Error{ErrorCode::kBadInput, fmt::format("{}: {}: {} (a damaged manifest: restore "
                                                   "it, or fix this field)",
                                                   origin_, field, what)};
  }
  Error WrongType(std::string_view field, std::string_view expected, const Json& got) const {
    return Bad(field, fmt::format("expected {}, got {}", expected, TypeName(got)));
  }

  // An integer in [min, max].
  ::revolve::Expected<std::int64_t> Integer(const Json& value, std::string_view field,
                                            std::int64_t min, std::int64_t max) const {
    if (!value.is_number_integer()) return std::unexpected(WrongType(field, "an integer", value));
    std::int64_t v = 0;
    if (value.is_number_unsigned()) {
      const std::uint64_t u = value.get<std::uint64_t>();
      if (u > static_cast<std::uint64_t>(max)) {
        return std::unexpected(Bad(field, fmt::format("{} is out of range [{}, {}]", u, min, max)));
      }
      v = static_cast<std::int64_t>(u);
    } else {
      v = value.get<std::int64_t>();
    }
    if (v < min || v > max) {
      return std::unexpected(Bad(field, fmt::format("{} is out of range [{}, {}]", v, min, max)));
    }
    return v;
  }

  // A finite number in [min, max].
  ::revolve::Expected<double> Number(const Json& value, std::string_view field, double min,
                                     double max) const {
    if (!value.is_number()) return std::unexpected(WrongType(field, "a finite number", value));
    const double v = value.get<double>();
    if (!std::isfinite(v) || !(v >= min && v <= max)) {
      return std::unexpected(Bad(field, fmt::format("{} is out of range [{}, {}]", v, min, max)));
    }
    return v;
  }

  ::revolve::Expected<void> String(const Json& value, std::string_view field) const {
    if (!value.is_string()) return std::unexpected(WrongType(field, "a string", value));
    return {};
  }

  // A file of the scan folder: relative, without "..".
  ::revolve::Expected<void> FolderFile(const Json& value, std::string_view field) const {
    if (auto s = String(value, field); !s) return s;
    const std::filesystem::path path(value.get_ref<const std::string&>());
    if (path.is_absolute() ||
        std::any_of(path.begin(), path.end(), [](const auto& part) { return part == ".."; })) {
      return std::unexpected(
          Bad(field, fmt::format("\"{}\" is not a file inside the scan folder", path.string())));
    }
    return {};
  }

 private:
  std::string_view origin_;
};

// The angle between two directions, in [0, 180].
double AngleBetweenDeg(double a_deg, double b_deg) {
  const double d = std::fmod(std::abs(a_deg - b_deg), 360.0);
  return std::min(d, 360.0 - d);
}

Expected<void> CheckStop(const Checker& c, const Json& stop, std::size_t i, std::int64_t planned,
                         std::optional<double> step_deg,
                         std::vector<std::int64_t>& first_entry_of_index) {
  const std::string at = fmt::format("stops[{}]", i);
  if (!stop.is_object()) return std::unexpected(c.WrongType(at, "an object", stop));
  const auto field = [&at](std::string_view key) { return fmt::format("{}.{}", at, key); };
  const auto index_it = stop.find("index");
  if (index_it == stop.end()) return std::unexpected(c.Bad(field("index"), "missing"));
  auto index = c.Integer(*index_it, field("index"), 0, planned - 1);
  if (!index) return std::unexpected(index.error());
  std::int64_t& first = first_entry_of_index[static_cast<std::size_t>(*index)];
  if (first >= 0) {
    return std::unexpected(
        c.Bad(field("index"),
              fmt::format("stop {} is listed twice (also stops[{}]): which one holds the right "
                          "frame is unknown",
                          *index, first)));
  }
  first = static_cast<std::int64_t>(i);
  std::optional<double> commanded_deg;
  std::optional<double> readback_deg;
  if (auto it = stop.find("commanded_deg"); it != stop.end()) {
    auto value = c.Number(*it, field("commanded_deg"), -1e6, 1e6);
    if (!value) return std::unexpected(value.error());
    commanded_deg = *value;
  }
  if (auto it = stop.find("readback_deg"); it != stop.end()) {
    auto value = c.Number(*it, field("readback_deg"), -1e6, 1e6);
    if (!value) return std::unexpected(value.error());
    readback_deg = *value;
  }
  // The angles agree with the stop's place in the plan and with each other: the read-back angle
  // is where the table stopped, within any drive's tolerance.
  if (commanded_deg && step_deg) {
    const double planned_deg = static_cast<double>(*index) * *step_deg;
    if (AngleBetweenDeg(*commanded_deg, planned_deg) > 1e-6) {
      return std::unexpected(c.Bad(field("commanded_deg"),
                                   fmt::format("{} deg, but stop {} with step_deg {} is at {} deg",
                                               *commanded_deg, *index, *step_deg, planned_deg)));
    }
  }
  if (commanded_deg && readback_deg &&
      AngleBetweenDeg(*commanded_deg, *readback_deg) > kMaxReadbackErrorDeg) {
    return std::unexpected(c.Bad(field("readback_deg"),
                                 fmt::format("{} deg is more than {} deg from commanded_deg {}",
                                             *readback_deg, kMaxReadbackErrorDeg, *commanded_deg)));
  }
  for (const char* key : {"frame", "mask"}) {
    if (auto it = stop.find(key); it != stop.end())
      REVOLVE_RETURN_IF_ERROR(c.FolderFile(*it, field(key)));
  }
  // The quality gates' warnings: [{code, message}, ...].
  if (auto it = stop.find("quality"); it != stop.end()) {
    if (!it->is_array()) return std::unexpected(c.WrongType(field("quality"), "an array", *it));
    for (std::size_t w = 0; w < it->size(); ++w) {
      const Json& warning = (*it)[w];
      const std::string at_w = fmt::format("{}[{}]", field("quality"), w);
      if (!warning.is_object()) {
        return std::unexpected(c.WrongType(at_w, "an object", warning));
      }
      for (const char* key : {"code", "message"}) {
        const auto sub = warning.find(key);
        if (sub == warning.end()) return std::unexpected(c.Bad(at_w + "." + key, "missing"));
        REVOLVE_RETURN_IF_ERROR(c.String(*sub, at_w + "." + key));
      }
    }
  }
  return {};
}

}  // namespace

Expected<void> CheckManifest(const nlohmann::json& manifest, std::string_view origin) {
  const Checker c(origin);
  if (!manifest.is_object()) {
    return std::unexpected(c.WrongType("the manifest", "a JSON object", manifest));
  }
  std::int64_t planned = kMaxManifestStops;
  if (auto it = manifest.find("stops_planned"); it != manifest.end()) {
    auto value = c.Integer(*it, "stops_planned", 1, kMaxManifestStops);
    if (!value) return std::unexpected(value.error());
    planned = *value;
  }
  std::optional<double> step_deg;
  if (auto it = manifest.find("step_deg"); it != manifest.end()) {
    auto value = c.Number(*it, "step_deg", 0.0, 360.0);
    if (!value) return std::unexpected(value.error());
    if (*value <= 0.0) return std::unexpected(c.Bad("step_deg", "must be greater than 0"));
    step_deg = *value;
  }
  if (auto it = manifest.find("stops_done"); it != manifest.end()) {
    REVOLVE_RETURN_IF_ERROR(c.Integer(*it, "stops_done", 0, kMaxManifestStops));
  }
  if (auto it = manifest.find("version"); it != manifest.end()) {
    REVOLVE_RETURN_IF_ERROR(c.Integer(*it, "version", 1, 1));
  }
  for (const char* key :
       {"scan_id", "recipe", "started", "finished", "config", "turntable", "camera"}) {
    if (auto it = manifest.find(key); it != manifest.end())
      REVOLVE_RETURN_IF_ERROR(c.String(*it, key));
  }
  if (auto it = manifest.find("state"); it != manifest.end()) {
    REVOLVE_RETURN_IF_ERROR(c.String(*it, "state"));
    const std::string& state = it->get_ref<const std::string&>();
    if (std::find(std::begin(kManifestStates), std::end(kManifestStates), state) ==
        std::end(kManifestStates)) {
      return std::unexpected(c.Bad(
          "state", fmt::format("\"{}\" is not one of running, complete, failed, aborted", state)));
    }
  }
  if (auto it = manifest.find("resumed"); it != manifest.end() && !it->is_array()) {
    return std::unexpected(c.WrongType("resumed", "an array", *it));
  }
  if (auto it = manifest.find("error"); it != manifest.end()) {
    if (!it->is_object()) return std::unexpected(c.WrongType("error", "an object", *it));
    for (const char* key : {"message", "code"}) {
      if (auto sub = it->find(key); sub != it->end()) {
        REVOLVE_RETURN_IF_ERROR(c.String(*sub, fmt::format("error.{}", key)));
      }
    }
  }
  const auto stops = manifest.find("stops");
  if (stops == manifest.end()) return std::unexpected(c.Bad("stops", "missing"));
  if (!stops->is_array()) return std::unexpected(c.WrongType("stops", "an array", *stops));
  if (stops->size() > static_cast<std::size_t>(planned)) {
    return std::unexpected(
        c.Bad("stops", fmt::format("lists {} stops, more than the {} {}", stops->size(), planned,
                                   manifest.contains("stops_planned") ? "planned (stops_planned)"
                                                                      : "a scan can have")));
  }
  std::vector<std::int64_t> first_entry_of_index(static_cast<std::size_t>(planned), -1);
  for (std::size_t i = 0; i < stops->size(); ++i) {
    REVOLVE_RETURN_IF_ERROR(CheckStop(c, (*stops)[i], i, planned, step_deg, first_entry_of_index));
  }
  return {};
}

}  // namespace revolve::station
