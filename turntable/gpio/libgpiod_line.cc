#include "turntable/gpio/libgpiod_line.h"

#include <cerrno>

#include <fmt/format.h>

namespace revolve::turntable::gpio {

Error GpiodError(const std::system_error& e, std::string_view what) {
  const int code = e.code().value();
  ErrorCode error_code = ErrorCode::kNoDevice;
  std::string hint;
  if (code == EBUSY) {
    error_code = ErrorCode::kBusy;
    hint = " (the line is used by another program, e.g. a running gpioset or another revolve)";
  } else if (code == ENOENT || code == ENODEV) {
    error_code = ErrorCode::kNotFound;
    hint = " (check `gpiodetect` and `gpioinfo` for the chip and line names)";
  } else if (code == EACCES || code == EPERM) {
    error_code = ErrorCode::kIo;
    hint = " (permission: add the user to the gpio group, or install the udev rule)";
  }
  return Error{error_code, fmt::format("{}: {}{}", what, e.what(), hint)};
}

Expected<gpiod::chip> OpenGpiodChip(const std::string& chip) {
  gpiod::chip opened;
  try {
    opened.open(chip, gpiod::chip::OPEN_LOOKUP);
  } catch (const std::system_error& e) {
    return std::unexpected(GpiodError(e, fmt::format("GPIO chip \"{}\"", chip)));
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kNotFound, fmt::format("GPIO chip \"{}\": {}", chip, e.what()));
  }
  return opened;
}

Expected<gpiod::line> FindGpiodLine(gpiod::chip& chip, std::string_view chip_name,
                                    const GpioLineSpec& spec, std::string_view role) {
  try {
    gpiod::line line = spec.offset >= 0 ? chip.get_line(static_cast<unsigned>(spec.offset))
                                        : chip.find_line(spec.name);
    if (!line) {
      return MakeError(ErrorCode::kNotFound,
                       fmt::format("{} line {} not found on {} (see `gpioinfo {}`)", role,
                                   spec.Describe(), chip_name, chip_name));
    }
    return line;
  } catch (const std::system_error& e) {
    return std::unexpected(GpiodError(e, fmt::format("{} line {}", role, spec.Describe())));
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kNotFound,
                     fmt::format("{} line {}: {}", role, spec.Describe(), e.what()));
  }
}

Expected<gpiod::line> RequestGpiodOutput(gpiod::chip& chip, std::string_view chip_name,
                                         const GpioLineSpec& spec, std::string_view role,
                                         const std::string& consumer) {
  Expected<gpiod::line> line = FindGpiodLine(chip, chip_name, spec, role);
  if (!line) return line;
  try {
    gpiod::line_request request{consumer, gpiod::line_request::DIRECTION_OUTPUT, {}};
    if (spec.active_low) request.flags |= gpiod::line_request::FLAG_ACTIVE_LOW;
    line->request(request, 0);  // logical 0: inactive
    return line;
  } catch (const std::system_error& e) {
    return std::unexpected(
        GpiodError(e, fmt::format("requesting {} line {}", role, spec.Describe())));
  }
}

Expected<gpiod::line> RequestGpiodInput(gpiod::chip& chip, std::string_view chip_name,
                                        const GpioLineSpec& spec, std::string_view role,
                                        std::string_view bias, const std::string& consumer) {
  Expected<gpiod::line> line = FindGpiodLine(chip, chip_name, spec, role);
  if (!line) return line;
  try {
    gpiod::line_request request{consumer, gpiod::line_request::EVENT_BOTH_EDGES, {}};
    if (spec.active_low) request.flags |= gpiod::line_request::FLAG_ACTIVE_LOW;
    if (bias == "pull_up") request.flags |= gpiod::line_request::FLAG_BIAS_PULL_UP;
    if (bias == "pull_down") request.flags |= gpiod::line_request::FLAG_BIAS_PULL_DOWN;
    if (bias == "disable") request.flags |= gpiod::line_request::FLAG_BIAS_DISABLE;
    line->request(request);
    return line;
  } catch (const std::system_error& e) {
    return std::unexpected(
        GpiodError(e, fmt::format("requesting {} line {}", role, spec.Describe())));
  }
}

}  // namespace revolve::turntable::gpio
