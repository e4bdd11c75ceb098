// StepDirLines over libgpiod 1.6 (the v1 C++ API, gpiod.hpp).
#pragma once

#include <memory>

#include "base/error.h"
#include "turntable/gpio/gpio_options.h"
#include "turntable/gpio/step_dir_lines.h"

namespace revolve::turntable::gpio {

// Opens `options.chip` (a /dev path, a gpiochipN name, or a label such as "pinctrl-bcm2711"),
// requests STEP and DIR (and ENABLE) as outputs, driven inactive (motor not enabled), and the
// home switch as an input with edge events and the configured bias. Released lines revert to
// their hardware default when the process exits: wire ENABLE so that floating means disabled.
// Errors: not_found (no such chip or line name), busy (a line is used by another consumer,
// e.g. a running gpioset), no_device / io for other failures.
Expected<std::unique_ptr<StepDirLines>> OpenLibgpiodLines(const GpioOptions& options);

}  // namespace revolve::turntable::gpio
