// The libgpiod 1.6 (v1 C++ API, gpiod.hpp) plumbing shared by the GPIO backends: the turntable's
// step/dir lines (libgpiod_lines.cc) and the station's operator panel. Built only when this build
// has libgpiod (REVOLVE_HAVE_GPIO); users need gpiod.hpp on their include path.
#pragma once

#include <string>
#include <string_view>
#include <system_error>

#include <gpiod.hpp>

#include "base/error.h"
#include "turntable/gpio/gpio_options.h"

namespace revolve::turntable::gpio {

// The Error for a libgpiod failure while doing `what`, with a hint an operator can act on: busy
// (the line is used by another consumer), not_found (no such chip or line), io (permission) or
// no_device.
Error GpiodError(const std::system_error& e, std::string_view what);

// Opens `chip` (a /dev path, a gpiochipN name, or a label such as "pinctrl-bcm2711").
Expected<gpiod::chip> OpenGpiodChip(const std::string& chip);

// The line `spec` (offset or name) of `chip` (`chip_name` for messages); `role` names it in errors
// ("STEP", "start button").
Expected<gpiod::line> FindGpiodLine(gpiod::chip& chip, std::string_view chip_name,
                                    const GpioLineSpec& spec, std::string_view role);

// Finds and requests `spec` for `consumer` (the name gpioinfo shows) as an output driven
// inactive (logical 0), active low when the spec says.
Expected<gpiod::line> RequestGpiodOutput(gpiod::chip& chip, std::string_view chip_name,
                                         const GpioLineSpec& spec, std::string_view role,
                                         const std::string& consumer);

// Finds and requests `spec` for `consumer` as an input with events on both edges (of the logical
// level) and `bias`: "pull_up", "pull_down", "disable" or anything else for the line as it is.
Expected<gpiod::line> RequestGpiodInput(gpiod::chip& chip, std::string_view chip_name,
                                        const GpioLineSpec& spec, std::string_view role,
                                        std::string_view bias, const std::string& consumer);

}  // namespace revolve::turntable::gpio
