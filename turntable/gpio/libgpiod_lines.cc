#include "turntable/gpio/libgpiod_lines.h"

#include <cerrno>
#include <system_error>

#include <fmt/format.h>
#include <gpiod.hpp>

namespace revolve::turntable::gpio {
namespace {

constexpr char kConsumer[] = "revolve";

Error FromSystemError(const std::system_error& e, std::string_view what) {
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

class LibgpiodLines final : public StepDirLines {
 public:
  LibgpiodLines(const GpioOptions& options, gpiod::chip chip)
      : options_(options), chip_(std::move(chip)) {}

  Expected<void> Open() {
    auto line_of = [this](const GpioLineSpec& spec,
                          std::string_view role) -> Expected<gpiod::line> {
      try {
        gpiod::line line = spec.offset >= 0 ? chip_.get_line(static_cast<unsigned>(spec.offset))
                                            : chip_.find_line(spec.name);
        if (!line) {
          return MakeError(ErrorCode::kNotFound,
                           fmt::format("{} line {} not found on {} (see `gpioinfo {}`)", role,
                                       spec.Describe(), options_.chip, options_.chip));
        }
        return line;
      } catch (const std::system_error& e) {
        return std::unexpected(
            FromSystemError(e, fmt::format("{} line {}", role, spec.Describe())));
      } catch (const std::exception& e) {
        return MakeError(ErrorCode::kNotFound,
                         fmt::format("{} line {}: {}", role, spec.Describe(), e.what()));
      }
    };
    auto output = [&](const GpioLineSpec& spec, std::string_view role,
                      gpiod::line& out) -> Expected<void> {
      Expected<gpiod::line> line = line_of(spec, role);
      if (!line) return std::unexpected(line.error());
      try {
        gpiod::line_request request{kConsumer, gpiod::line_request::DIRECTION_OUTPUT, {}};
        if (spec.active_low) request.flags |= gpiod::line_request::FLAG_ACTIVE_LOW;
        line->request(request, 0);  // logical 0: inactive
        out = *line;
        return {};
      } catch (const std::system_error& e) {
        return std::unexpected(
            FromSystemError(e, fmt::format("requesting {} line {}", role, spec.Describe())));
      }
    };
    if (Expected<void> ok = output(options_.step, "STEP", step_); !ok) return ok;
    if (Expected<void> ok = output(options_.dir, "DIR", dir_); !ok) return ok;
    if (options_.enable.present()) {
      if (Expected<void> ok = output(options_.enable, "ENABLE", enable_); !ok) return ok;
    }
    if (options_.home.present()) {
      Expected<gpiod::line> line = line_of(options_.home, "home");
      if (!line) return std::unexpected(line.error());
      try {
        gpiod::line_request request{kConsumer, gpiod::line_request::EVENT_BOTH_EDGES, {}};
        if (options_.home.active_low) request.flags |= gpiod::line_request::FLAG_ACTIVE_LOW;
        if (options_.home_bias == "pull_up")
          request.flags |= gpiod::line_request::FLAG_BIAS_PULL_UP;
        if (options_.home_bias == "pull_down") {
          request.flags |= gpiod::line_request::FLAG_BIAS_PULL_DOWN;
        }
        if (options_.home_bias == "disable")
          request.flags |= gpiod::line_request::FLAG_BIAS_DISABLE;
        line->request(request);
        home_ = *line;
      } catch (const std::system_error& e) {
        return std::unexpected(
            FromSystemError(e, fmt::format("requesting home line {}", options_.home.Describe())));
      }
    }
    return {};
  }

  ~LibgpiodLines() override {
    try {
      if (enable_) enable_.set_value(0);
      for (gpiod::line* line : {&step_, &dir_, &enable_, &home_}) {
        if (*line) line->release();
      }
    } catch (...) {
      // Released lines revert to their defaults anyway.
    }
  }

  Expected<void> Set(Line which, bool active) override {
    gpiod::line* line = which == Line::kStep ? &step_ : which == Line::kDir ? &dir_ : &enable_;
    if (!*line) return {};
    try {
      line->set_value(active ? 1 : 0);
      return {};
    } catch (const std::system_error& e) {
      return std::unexpected(FromSystemError(e, "setting a GPIO line"));
    }
  }

  bool HasEnable() const override { return static_cast<bool>(enable_); }
  bool HasHome() const override { return static_cast<bool>(home_); }

  Expected<bool> HomeActive() override {
    if (!home_) return false;
    try {
      return home_.get_value() != 0;
    } catch (const std::system_error& e) {
      return std::unexpected(FromSystemError(e, "reading the home switch"));
    }
  }

  Expected<bool> TakeHomeEdge() override {
    if (!home_) return false;
    try {
      bool rising = false;
      while (home_.event_wait(std::chrono::nanoseconds(0))) {
        const gpiod::line_event event = home_.event_read();
        // With FLAG_ACTIVE_LOW the kernel reports edges of the logical level.
        rising = rising || event.event_type == gpiod::line_event::RISING_EDGE;
      }
      return rising;
    } catch (const std::system_error& e) {
      return std::unexpected(FromSystemError(e, "reading home switch events"));
    }
  }

  std::string Describe() const override {
    return fmt::format("{} STEP {} DIR {}{}{}", options_.chip, options_.step.Describe(),
                       options_.dir.Describe(),
                       options_.enable.present() ? " ENABLE " + options_.enable.Describe() : "",
                       options_.home.present() ? " HOME " + options_.home.Describe() : "");
  }

 private:
  const GpioOptions options_;
  gpiod::chip chip_;
  gpiod::line step_;
  gpiod::line dir_;
  gpiod::line enable_;
  gpiod::line home_;
};

}  // namespace

Expected<std::unique_ptr<StepDirLines>> OpenLibgpiodLines(const GpioOptions& options) {
  gpiod::chip chip;
  try {
    chip.open(options.chip, gpiod::chip::OPEN_LOOKUP);
  } catch (const std::system_error& e) {
    return std::unexpected(FromSystemError(e, fmt::format("GPIO chip \"{}\"", options.chip)));
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kNotFound,
                     fmt::format("GPIO chip \"{}\": {}", options.chip, e.what()));
  }
  auto lines = std::make_unique<LibgpiodLines>(options, std::move(chip));
  if (Expected<void> opened = lines->Open(); !opened) return std::unexpected(opened.error());
  return std::unique_ptr<StepDirLines>(std::move(lines));
}

}  // namespace revolve::turntable::gpio
