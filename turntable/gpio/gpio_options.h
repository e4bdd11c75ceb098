// Options of the GPIO step/dir turntable backend ([turntable.gpio]) and their parser. Always
// built, also without libgpiod, so that a config can be checked anywhere.
#pragma once

#include <string>

#include "base/error.h"
#include "config/config.h"

namespace revolve::turntable {

// A GPIO line: an offset on the chip, or a line name ("GPIO17") looked up on the chip.
struct GpioLineSpec {
  int offset = -1;   // >= 0 when given as a number
  std::string name;  // non-empty when given as a name
  bool active_low = false;

  bool present() const { return offset >= 0 || !name.empty(); }
  std::string Describe() const;
};

struct GpioOptions {
  std::string chip = "gpiochip0";     // name, /dev path, or label ("pinctrl-bcm2711")
  GpioLineSpec step;                  // key step (required), step_active_low
  GpioLineSpec dir;                   // key dir (required), dir_active_low
  GpioLineSpec enable;                // key enable (optional), enable_active_low
  GpioLineSpec home;                  // key home (optional), home_active_low (default true)
  std::string home_bias = "pull_up";  // pull_up | pull_down | disable | as_is

  // Kinematics.
  int full_steps_per_rev = 200;           // motor full steps per revolution, [1, 100000]
  int microsteps = 16;                    // driver microstepping, [1, 256]
  double gear_ratio = 1.0;                // motor revs per plate rev, (0, 1000]
  bool reverse = false;                   // direction = "forward" | "reverse"
  double speed_deg_per_s = 30.0;          // plate cruise speed, (0, 3600]
  double acceleration_deg_per_s2 = 90.0;  // (0, 100000]
  double max_step_rate_hz = 2000.0;       // step rate cap, (0, 100000]

  // Electrical timing (driver datasheet).
  double pulse_us = 5.0;           // STEP high time, [1, 10000]
  double dir_setup_us = 10.0;      // DIR stable before the first STEP edge, [0, 100000]
  double enable_settle_ms = 10.0;  // ENABLE asserted before the first step, [0, 10000]

  // Homing with the switch.
  double home_speed_deg_per_s = 10.0;  // (0, 3600]
  double home_debounce_ms = 5.0;       // [0, 1000]
  double home_max_deg = 400.0;         // search range before giving up, (0, 3600]
  bool home_reverse = false;           // search direction: false = toward increasing angle

  double idle_disable_s = 0.0;  // power the motor down after this idle time; 0 = never
  bool realtime = false;        // try SCHED_FIFO for step emission (needs LimitRTPRIO/CAP_SYS_NICE)

  double StepsPerPlateRev() const {
    return static_cast<double>(full_steps_per_rev) * microsteps * gear_ratio;
  }
};

// Parses [turntable.gpio] (`section`). Errors: bad_input with file:line:column and the key.
Expected<GpioOptions> ParseGpioOptions(const config::Section& section);

}  // namespace revolve::turntable
