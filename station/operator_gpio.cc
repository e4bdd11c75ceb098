// OperatorLines over libgpiod 1.6 (gpiod.hpp), when this build has it.
#include <poll.h>

#include <cerrno>
#include <system_error>

#include <fmt/format.h>

#include "station/operator_panel.h"

#ifdef REVOLVE_HAVE_PANEL_GPIO
#include <gpiod.hpp>
#endif

namespace revolve::station {

#ifdef REVOLVE_HAVE_PANEL_GPIO
namespace {

constexpr char kConsumer[] = "revolved";

Error FromSystemError(const std::system_error& e, std::string_view what) {
  const int code = e.code().value();
  if (code == EBUSY) {
    return Error{
        ErrorCode::kBusy,
        fmt::format("{}: {} (used by another program, e.g. a running gpioset)", what, e.what())};
  }
  if (code == ENOENT || code == ENODEV) {
    return Error{ErrorCode::kNotFound,
                 fmt::format("{}: {} (see `gpiodetect` and `gpioinfo`)", what, e.what())};
  }
  if (code == EACCES || code == EPERM) {
    return Error{
        ErrorCode::kIo,
        fmt::format("{}: {} (permission: the gpio group and its udev rule)", what, e.what())};
  }
  return Error{ErrorCode::kNoDevice, fmt::format("{}: {}", what, e.what())};
}

class LibgpiodPanelLines final : public OperatorLines {
 public:
  explicit LibgpiodPanelLines(const OperatorOptions& options) : options_(options) {}

  Expected<void> Open() {
    try {
      chip_.open(options_.chip, gpiod::chip::OPEN_LOOKUP);
    } catch (const std::system_error& e) {
      return std::unexpected(FromSystemError(e, fmt::format("GPIO chip {}", options_.chip)));
    } catch (const std::exception& e) {
      return MakeError(ErrorCode::kNotFound,
                       fmt::format("GPIO chip {}: {}", options_.chip, e.what()));
    }
    auto find = [this](const PanelLine& spec, std::string_view role) -> Expected<gpiod::line> {
      try {
        gpiod::line line = spec.offset >= 0 ? chip_.get_line(static_cast<unsigned>(spec.offset))
                                            : chip_.find_line(spec.name);
        if (!line) {
          return MakeError(ErrorCode::kNotFound, fmt::format("{} line {} not found on {}", role,
                                                             spec.Describe(), options_.chip));
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
    auto input = [&](const PanelLine& spec, std::string_view role,
                     std::optional<gpiod::line>& out) -> Expected<void> {
      if (!spec.present()) return {};
      Expected<gpiod::line> line = find(spec, role);
      if (!line) return std::unexpected(line.error());
      try {
        gpiod::line_request request{kConsumer, gpiod::line_request::EVENT_BOTH_EDGES, {}};
        if (spec.active_low) request.flags |= gpiod::line_request::FLAG_ACTIVE_LOW;
        if (options_.bias == "pull_up") request.flags |= gpiod::line_request::FLAG_BIAS_PULL_UP;
        if (options_.bias == "pull_down") {
          request.flags |= gpiod::line_request::FLAG_BIAS_PULL_DOWN;
        }
        if (options_.bias == "disable") request.flags |= gpiod::line_request::FLAG_BIAS_DISABLE;
        line->request(request);
        out = *line;
        return {};
      } catch (const std::system_error& e) {
        return std::unexpected(
            FromSystemError(e, fmt::format("requesting {} line {}", role, spec.Describe())));
      }
    };
    auto output = [&](const PanelLine& spec, std::string_view role,
                      std::optional<gpiod::line>& out) -> Expected<void> {
      if (!spec.present()) return {};
      Expected<gpiod::line> line = find(spec, role);
      if (!line) return std::unexpected(line.error());
      try {
        gpiod::line_request request{kConsumer, gpiod::line_request::DIRECTION_OUTPUT, {}};
        if (spec.active_low) request.flags |= gpiod::line_request::FLAG_ACTIVE_LOW;
        line->request(request, 0);
        out = *line;
        return {};
      } catch (const std::system_error& e) {
        return std::unexpected(
            FromSystemError(e, fmt::format("requesting {} line {}", role, spec.Describe())));
      }
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
        return std::unexpected(FromSystemError(e, "reading button events"));
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
      return std::unexpected(FromSystemError(e, "reading a button"));
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
          FromSystemError(e, output == PanelOutput::kLed ? "setting the LED" : "setting the lamp"));
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
