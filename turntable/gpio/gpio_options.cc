#include "turntable/gpio/gpio_options.h"

#include <optional>

#include <fmt/format.h>

namespace revolve::turntable {
namespace {

// Collects the first error of a series of getters.
class Reader {
 public:
  explicit Reader(const config::Section& section) : section_(section) {}

  void Number(std::string_view key, double& out, double min, double max, bool exclusive_min) {
    if (error_) return;
    Expected<double> v = section_.Number(key, out, min, max);
    if (!v) {
      error_ = v.error();
    } else if (exclusive_min && *v <= min) {
      error_ =
          section_.BadValue(key, fmt::format("must be greater than {} (and at most {})", min, max));
    } else {
      out = *v;
    }
  }
  void Integer(std::string_view key, int& out, int min, int max) {
    if (error_) return;
    Expected<std::int64_t> v = section_.Integer(key, out, min, max);
    if (!v) {
      error_ = v.error();
    } else {
      out = static_cast<int>(*v);
    }
  }
  void Boolean(std::string_view key, bool& out) {
    if (error_) return;
    Expected<bool> v = section_.Boolean(key, out);
    if (!v) {
      error_ = v.error();
    } else {
      out = *v;
    }
  }
  void String(std::string_view key, std::string& out,
              std::initializer_list<std::string_view> allowed = {}) {
    if (error_) return;
    Expected<std::string> v = section_.String(key, out, allowed);
    if (!v) {
      error_ = v.error();
    } else {
      out = *v;
    }
  }
  // A line: an integer offset or a string name.
  void Line(std::string_view key, GpioLineSpec& out, bool required) {
    if (error_) return;
    if (!section_.Has(key)) {
      (void)section_.String(key, "");  // mark as known
      if (required) {
        error_ = section_.BadValue(key, "is required: the line offset (17) or name (\"GPIO17\")");
      }
      return;
    }
    Expected<std::int64_t> offset = section_.Integer(key, -1, 0, 1023);
    if (offset) {
      out.offset = static_cast<int>(*offset);
      return;
    }
    Expected<std::string> name = section_.String(key, "");
    if (!name || name->empty()) {
      error_ = section_.BadValue(key, "expected a line offset 0..1023 or a line name");
      return;
    }
    out.name = *name;
  }
  void Fail(Error error) {
    if (!error_) error_ = std::move(error);
  }
  const std::optional<Error>& error() const { return error_; }

 private:
  const config::Section& section_;
  std::optional<Error> error_;
};

}  // namespace

std::string GpioLineSpec::Describe() const {
  std::string text = offset >= 0 ? std::to_string(offset) : "\"" + name + "\"";
  if (active_low) text += " (active low)";
  return text;
}

Expected<GpioOptions> ParseGpioOptions(const config::Section& section) {
  GpioOptions o;
  Reader r(section);
  r.String("chip", o.chip);
  if (!r.error() && o.chip.empty()) r.Fail(section.BadValue("chip", "must not be empty"));
  r.Line("step", o.step, true);
  r.Boolean("step_active_low", o.step.active_low);
  r.Line("dir", o.dir, true);
  r.Boolean("dir_active_low", o.dir.active_low);
  r.Line("enable", o.enable, false);
  r.Boolean("enable_active_low", o.enable.active_low);
  r.Line("home", o.home, false);
  o.home.active_low = true;
  r.Boolean("home_active_low", o.home.active_low);
  r.String("home_bias", o.home_bias, {"pull_up", "pull_down", "disable", "as_is"});
  r.Integer("full_steps_per_rev", o.full_steps_per_rev, 1, 100000);
  r.Integer("microsteps", o.microsteps, 1, 256);
  r.Number("gear_ratio", o.gear_ratio, 0.0, 1000.0, true);
  std::string direction = "forward";
  r.String("direction", direction, {"forward", "reverse"});
  o.reverse = direction == "reverse";
  r.Number("speed_deg_per_s", o.speed_deg_per_s, 0.0, 3600.0, true);
  r.Number("acceleration_deg_per_s2", o.acceleration_deg_per_s2, 0.0, 100000.0, true);
  r.Number("max_step_rate_hz", o.max_step_rate_hz, 0.0, 100000.0, true);
  r.Number("pulse_us", o.pulse_us, 1.0, 10000.0, false);
  r.Number("dir_setup_us", o.dir_setup_us, 0.0, 100000.0, false);
  r.Number("enable_settle_ms", o.enable_settle_ms, 0.0, 10000.0, false);
  r.Number("home_speed_deg_per_s", o.home_speed_deg_per_s, 0.0, 3600.0, true);
  r.Number("home_debounce_ms", o.home_debounce_ms, 0.0, 1000.0, false);
  r.Number("home_max_deg", o.home_max_deg, 0.0, 3600.0, true);
  std::string home_direction = "forward";
  r.String("home_direction", home_direction, {"forward", "reverse"});
  o.home_reverse = home_direction == "reverse";
  r.Number("idle_disable_s", o.idle_disable_s, 0.0, 86400.0, false);
  r.Boolean("realtime", o.realtime);
  if (r.error()) return std::unexpected(*r.error());
  // A step period must leave room for the pulse.
  if (o.pulse_us * 2e-6 * o.max_step_rate_hz > 1.0) {
    return std::unexpected(section.BadValue(
        "max_step_rate_hz", fmt::format("{} Hz leaves no room for {} us pulses (at most {:.0f} Hz)",
                                        o.max_step_rate_hz, o.pulse_us, 1e6 / (2 * o.pulse_us))));
  }
  if (o.step.present() && o.dir.present() && o.step.offset == o.dir.offset &&
      o.step.name == o.dir.name) {
    return std::unexpected(section.BadValue("dir", "must be another line than step"));
  }
  if (Expected<void> known = section.CheckNoUnknownKeys(); !known) {
    return std::unexpected(known.error());
  }
  return o;
}

}  // namespace revolve::turntable
