// OperatorLines over libgpiod 1.6 (gpiod.hpp), when this build has it.
#include <poll.h>

#include <string>
#include <system_error>

#include <fmt/format.h>

#include "station/operator_panel.h"

#ifdef REVOLVE_HAVE_PANEL_GPIO
#include <gpiod.hpp>

#include "turntable/gpio/libgpiod_line.h"
#endif

namespace revolve::station {

#ifdef REVOLVE_HAVE_PANEL_GPIO
namespace {

using turntable::gpio::GpiodError;

const std::string kConsumer = "revolved";

class LibgpiodPanelLines final : public OperatorLines {
 public:
  explicit LibgpiodPanelLines(const OperatorOptions& options) : options_(options) {}

  Expected<void> Open() {
    Expected<gpiod::chip> chip = turntable::gpio::OpenGpiodChip(options_.chip);
    if (!chip) return std::unexpected(chip.error());
    chip_ = std::move(*chip);
    auto input = [&](const PanelLine& spec, std::string_view role,
                     std::optional<gpiod::line>& out) -> Expected<void> {
      if (!spec.present()) return {};
      Expected<gpiod::line> line = turntable::gpio::RequestGpiodInput(
          chip_, options_.chip, spec, role, options_.bias, kConsumer);
      if (!line) return std::unexpected(line.error());
      out = *line;
      return {};
    };
    auto output = [&](const PanelLine& spec, std::string_view role,
                      std::optional<gpiod::line>& out) -> Expected<void> {
      if (!spec.present()) return {};
      Expected<gpiod::line> line =
          turntable::gpio::RequestGpiodOutput(chip_, options_.chip, spec, role, kConsumer);
      if (!line) return std::unexpected(line.error());
      out = *line;
      return {};
    };
    if (auto r = input(options_.start_button, "start button", start_); !r) return r;
    if (auto r = input(options_.abort_button, "abort button", abort_); !r) return r;
    if (auto r = output(options_.led, "status LED", led_); !r) return r;
    if (auto r = output(options_.lamp, "lamp", lamp_); !r) return r;
    return {};
  }

  bool Has(PanelButton button) const override { return Line(button).has_value(); }
  bool Has(PanelOutput output) const override {
    return (output == PanelOutput::kLed ? led_ : lamp_).has_value();
  }

  std::vector<int> EventFds() const override {
    std::vector<int> fds;
    try {
      if (start_) fds.push_back(start_->event_get_fd());
      if (abort_) fds.push_back(abort_->event_get_fd());
    } catch (const std::exception&) {
    }
    return fds;
  }

  Expected<std::vector<ButtonEdge>> ReadEdges() override {
    std::vector<ButtonEdge> edges;
    for (PanelButton button : {PanelButton::kStart, PanelButton::kAbort}) {
      const std::optional<gpiod::line>& line = Line(button);
      if (!line) continue;
      try {
        pollfd p{line->event_get_fd(), POLLIN, 0};
        while (::poll(&p, 1, 0) > 0 && (p.revents & POLLIN)) {
          const gpiod::line_event event = line->event_read();
          edges.push_back(ButtonEdge{button, event.event_type == gpiod::line_event::RISING_EDGE,
                                     event.timestamp});
        }
      } catch (const std::system_error& e) {
        return std::unexpected(GpiodError(e, "reading button events"));
      }
    }
    return edges;
  }

  Expected<bool> Active(PanelButton button) override {
    const std::optional<gpiod::line>& line = Line(button);
    if (!line) return false;
    try {
      return line->get_value() != 0;
    } catch (const std::system_error& e) {
      return std::unexpected(GpiodError(e, "reading a button"));
    }
  }

  Expected<void> Set(PanelOutput output, bool on) override {
    std::optional<gpiod::line>& line = output == PanelOutput::kLed ? led_ : lamp_;
    if (!line) return {};
    try {
      line->set_value(on ? 1 : 0);
      return {};
    } catch (const std::system_error& e) {
      return std::unexpected(
          GpiodError(e, output == PanelOutput::kLed ? "setting the LED" : "setting the lamp"));
    }
  }

  std::string Describe() const override {
    std::string s = "gpio " + options_.chip;
    if (start_) s += " start " + options_.start_button.Describe();
    if (abort_) s += " abort " + options_.abort_button.Describe();
    if (led_) s += " led " + options_.led.Describe();
    if (lamp_) s += " lamp " + options_.lamp.Describe();
    return s;
  }

 private:
  const std::optional<gpiod::line>& Line(PanelButton button) const {
    return button == PanelButton::kStart ? start_ : abort_;
  }

  OperatorOptions options_;
  gpiod::chip chip_;
  std::optional<gpiod::line> start_, abort_, led_, lamp_;
};

}  // namespace

Expected<std::unique_ptr<OperatorLines>> OpenPanelLines(const OperatorOptions& options) {
  if (!options.Any()) return std::unique_ptr<OperatorLines>();
  auto lines = std::make_unique<LibgpiodPanelLines>(options);
  if (auto opened = lines->Open(); !opened) return std::unexpected(opened.error());
  return std::unique_ptr<OperatorLines>(std::move(lines));
}

#else

Expected<std::unique_ptr<OperatorLines>> OpenPanelLines(const OperatorOptions& options) {
  if (!options.Any()) return std::unique_ptr<OperatorLines>();
  return MakeError(ErrorCode::kUnsupported,
                   "[operator] lines are configured but this build has no libgpiod: install "
                   "libgpiod-dev and rebuild (REVOLVE_WITH_GPIO=ON)");
}

#endif

}  // namespace revolve::station
