#include "turntable/gpio/gpio_options.h"

#include <optional>

#include <fmt/format.h>

#include "config/reader.h"
#include "turntable/drive_options.h"

namespace revolve::turntable {
namespace {

// A line: an integer offset or a string name.
void ReadLine(config::Reader& r, std::string_view key, GpioLineSpec& out, bool required) {
  if (!r.ok()) return;
  const config::Section& section = r.section();
  if (!section.Has(key)) {
    (void)section.String(key, "");  // mark as known
    if (required) {
      r.Fail(section.BadValue(key, "is required: the line offset (17) or name (\"GPIO17\")"));
    }
    return;
  }
  Expected<std::int64_t> offset = section.Integer(key, -1, 0, 1023);
  if (offset) {
    out.offset = static_cast<int>(*offset);
    return;
  }
  Expected<std::string> name = section.String(key, "");
  if (!name || name->empty()) {
    r.Fail(section.BadValue(key, "expected a line offset 0..1023 or a line name"));
    return;
  }
  out.name = *name;
}

}  // namespace

std::string GpioLineSpec::Describe() const {
  std::string text = offset >= 0 ? std::to_string(offset) : "\"" + name + "\"";
  if (active_low) text += " (active low)";
  return text;
}

Expected<GpioOptions> ParseGpioOptions(const config::Section& section) {
  GpioOptions o;
  config::Reader r(section);
  r.String("chip", o.chip);
  if (!r.error() && o.chip.empty()) r.Fail(section.BadValue("chip", "must not be empty"));
  ReadLine(r, "step", o.step, true);
  r.Boolean("step_active_low", o.step.active_low);
  ReadLine(r, "dir", o.dir, true);
  r.Boolean("dir_active_low", o.dir.active_low);
  ReadLine(r, "enable", o.enable, false);
  r.Boolean("enable_active_low", o.enable.active_low);
  ReadLine(r, "home", o.home, false);
  o.home.active_low = true;
  r.Boolean("home_active_low", o.home.active_low);
  r.String("home_bias", o.home_bias, {"pull_up", "pull_down", "disable", "as_is"});
  r.Integer("full_steps_per_rev", o.full_steps_per_rev, 1, 100000);
  r.Integer("microsteps", o.microsteps, 1, 256);
  ReadDriveMotion(r, o);
  r.NumberAbove("max_step_rate_hz", o.max_step_rate_hz, 0.0, 100000.0);
  r.Number("pulse_us", o.pulse_us, 1.0, 10000.0);
  r.Number("dir_setup_us", o.dir_setup_us, 0.0, 100000.0);
  r.Number("enable_settle_ms", o.enable_settle_ms, 0.0, 10000.0);
  r.NumberAbove("home_speed_deg_per_s", o.home_speed_deg_per_s, 0.0, 3600.0);
  r.Number("home_debounce_ms", o.home_debounce_ms, 0.0, 1000.0);
  r.NumberAbove("home_max_deg", o.home_max_deg, 0.0, 3600.0);
  std::string home_direction = "forward";
  r.String("home_direction", home_direction, {"forward", "reverse"});
  o.home_reverse = home_direction == "reverse";
  r.Number("idle_disable_s", o.idle_disable_s, 0.0, 86400.0);
  r.Boolean("realtime", o.realtime);
  if (const auto& error = r.error()) return std::unexpected(*error);
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
