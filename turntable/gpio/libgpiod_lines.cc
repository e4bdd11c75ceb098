#include "turntable/gpio/libgpiod_lines.h"

#include <string>
#include <system_error>

#include <fmt/format.h>
#include <gpiod.hpp>

#include "turntable/gpio/libgpiod_line.h"

namespace revolve::turntable::gpio {
namespace {

const std::string kConsumer = "revolve";

class LibgpiodLines final : public StepDirLines {
 public:
  LibgpiodLines(const GpioOptions& options, gpiod::chip chip)
      : options_(options), chip_(std::move(chip)) {}

  Expected<void> Open() {
    auto output = [&](const GpioLineSpec& spec, std::string_view role,
                      gpiod::line& out) -> Expected<void> {
      Expected<gpiod::line> line = RequestGpiodOutput(chip_, options_.chip, spec, role, kConsumer);
      if (!line) return std::unexpected(line.error());
      out = *line;
      return {};
    };
    if (Expected<void> ok = output(options_.step, "STEP", step_); !ok) return ok;
    if (Expected<void> ok = output(options_.dir, "DIR", dir_); !ok) return ok;
    if (options_.enable.present()) {
      if (Expected<void> ok = output(options_.enable, "ENABLE", enable_); !ok) return ok;
    }
    if (options_.home.present()) {
      Expected<gpiod::line> line = RequestGpiodInput(chip_, options_.chip, options_.home, "home",
                                                     options_.home_bias, kConsumer);
      if (!line) return std::unexpected(line.error());
      home_ = *line;
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
      return std::unexpected(GpiodError(e, "setting a GPIO line"));
    }
  }

  bool HasEnable() const override { return static_cast<bool>(enable_); }
  bool HasHome() const override { return static_cast<bool>(home_); }

  Expected<bool> HomeActive() override {
    if (!home_) return false;
    try {
      return home_.get_value() != 0;
    } catch (const std::system_error& e) {
      return std::unexpected(GpiodError(e, "reading the home switch"));
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
      return std::unexpected(GpiodError(e, "reading home switch events"));
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
  Expected<gpiod::chip> chip = OpenGpiodChip(options.chip);
  if (!chip) return std::unexpected(chip.error());
  auto lines = std::make_unique<LibgpiodLines>(options, std::move(*chip));
  if (Expected<void> opened = lines->Open(); !opened) return std::unexpected(opened.error());
  return std::unique_ptr<StepDirLines>(std::move(lines));
}

}  // namespace revolve::turntable::gpio
