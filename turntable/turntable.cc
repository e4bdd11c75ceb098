#include "turntable/turntable.h"

#include <fmt/format.h>

#include "turntable/mock/mock_turntable.h"
#include "turntable/modbus/modbus_turntable.h"
#ifdef REVOLVE_HAVE_MODBUS
#include "turntable/modbus/libmodbus_transport.h"
#endif
#ifdef REVOLVE_HAVE_GPIO
#include "turntable/gpio/libgpiod_lines.h"
#endif
#include "turntable/gpio/step_dir_turntable.h"

namespace revolve::turntable {
namespace {

// A number in (0, max]: Section::Number checks [0, max], the open lower bound is checked here.
Expected<double> PositiveNumber(const config::Section& section, std::string_view key,
                                double fallback, double max) {
  Expected<double> value = section.Number(key, fallback, 0.0, max);
  if (config::KeyRecord* record = section.Recorded(key)) record->above_min = true;
  if (value && *value <= 0.0) {
    return std::unexpected(
        section.BadValue(key, fmt::format("must be greater than 0 (and at most {})", max)));
  }
  return value;
}

Expected<MockOptions> ParseMockOptions(const config::Section& section) {
  MockOptions options;
  Expected<double> speed =
      PositiveNumber(section, "speed_deg_per_s", options.speed_deg_per_s, kMockMaxSpeedDegPerS);
  if (!speed) return std::unexpected(speed.error());
  Expected<double> acceleration =
      PositiveNumber(section, "acceleration_deg_per_s2", options.acceleration_deg_per_s2,
                     kMockMaxAccelerationDegPerS2);
  if (!acceleration) return std::unexpected(acceleration.error());
  Expected<double> settle = section.Number("settle_ms", options.settle_ms, 0.0, kMockMaxSettleMs);
  if (!settle) return std::unexpected(settle.error());
  Expected<double> time_scale =
      PositiveNumber(section, "time_scale", options.time_scale, kMockMaxTimeScale);
  if (!time_scale) return std::unexpected(time_scale.error());
  Expected<double> tolerance =
      section.Number("tolerance_deg", options.tolerance_deg, 0.0, kMockMaxToleranceDeg);
  if (!tolerance) return std::unexpected(tolerance.error());
  if (Expected<void> known = section.CheckNoUnknownKeys(); !known) {
    return std::unexpected(known.error());
  }
  options.speed_deg_per_s = *speed;
  options.acceleration_deg_per_s2 = *acceleration;
  options.settle_ms = *settle;
  options.time_scale = *time_scale;
  options.tolerance_deg = *tolerance;
  return options;
}

}  // namespace

Expected<TurntableOptions> ParseOptions(const config::Section& section) {
  TurntableOptions options;
  Expected<std::string> backend =
      section.String("backend", options.backend, {"mock", "modbus", "gpio"});
  if (!backend) return std::unexpected(backend.error());
  options.backend = *backend;
  Expected<bool> disable_at_end = section.Boolean("disable_at_end", options.disable_at_end);
  if (!disable_at_end) return std::unexpected(disable_at_end.error());
  options.disable_at_end = *disable_at_end;

  Expected<config::Section> mock_section = section.Child("mock");
  if (!mock_section) return std::unexpected(mock_section.error());
  Expected<MockOptions> mock = ParseMockOptions(*mock_section);
  if (!mock) return std::unexpected(mock.error());
  options.mock = std::move(*mock);

  if (options.backend == "modbus" || section.Has("modbus")) {
    Expected<config::Section> modbus_section = section.Child("modbus");
    if (!modbus_section) return std::unexpected(modbus_section.error());
    Expected<ModbusOptions> modbus = ParseModbusOptions(*modbus_section);
    if (!modbus) return std::unexpected(modbus.error());
    options.modbus = std::move(*modbus);
  }
  if (options.backend == "gpio" || section.Has("gpio")) {
    Expected<config::Section> gpio_section = section.Child("gpio");
    if (!gpio_section) return std::unexpected(gpio_section.error());
    Expected<GpioOptions> gpio = ParseGpioOptions(*gpio_section);
    if (!gpio) return std::unexpected(gpio.error());
    options.gpio = std::move(*gpio);
  }

  if (Expected<void> known = section.CheckNoUnknownKeys(); !known) {
    return std::unexpected(known.error());
  }
  return options;
}

namespace {

Expected<std::unique_ptr<Turntable>> CreateModbus(const TurntableOptions& options,
                                                  std::shared_ptr<SimulatedPlate> plate) {
#ifdef REVOLVE_HAVE_MODBUS
  Expected<modbus::DriveProfile> profile = modbus::LoadProfileFile(options.modbus.profile_path);
  if (!profile) return std::unexpected(profile.error());
  Expected<std::unique_ptr<modbus::LibmodbusTransport>> transport =
      modbus::LibmodbusTransport::Open(options.modbus);
  if (!transport) return std::unexpected(transport.error());
  return std::make_unique<modbus::ModbusTurntable>(options.modbus, std::move(*profile),
                                                   std::move(*transport), std::move(plate),
                                                   options.disable_at_end);
#else
  (void)options;
  (void)plate;
  return MakeError(ErrorCode::kUnsupported,
                   "turntable backend \"modbus\" is not in this build: rebuild with "
                   "-DREVOLVE_WITH_MODBUS=ON and libmodbus-dev installed");
#endif
}

Expected<std::unique_ptr<Turntable>> CreateGpio(const TurntableOptions& options,
                                                std::shared_ptr<SimulatedPlate> plate) {
#ifdef REVOLVE_HAVE_GPIO
  Expected<std::unique_ptr<gpio::StepDirLines>> lines = gpio::OpenLibgpiodLines(options.gpio);
  if (!lines) return std::unexpected(lines.error());
  return std::make_unique<gpio::StepDirTurntable>(options.gpio, std::move(*lines),
                                                  gpio::SystemStepClock(), std::move(plate),
                                                  options.disable_at_end);
#else
  (void)options;
  (void)plate;
  return MakeError(ErrorCode::kUnsupported,
                   "turntable backend \"gpio\" is not in this build: rebuild with "
                   "-DREVOLVE_WITH_GPIO=ON and libgpiod-dev installed");
#endif
}

}  // namespace

Expected<std::unique_ptr<Turntable>> Create(const TurntableOptions& options,
                                            std::shared_ptr<SimulatedPlate> plate) {
  if (options.backend == "mock") {
    if (Expected<void> valid = ValidateMockOptions(options.mock); !valid) {
      return std::unexpected(valid.error());
    }
    return std::make_unique<MockTurntable>(options.mock, std::move(plate));
  }
  if (options.backend == "modbus") return CreateModbus(options, std::move(plate));
  if (options.backend == "gpio") return CreateGpio(options, std::move(plate));
  return MakeError(ErrorCode::kBadInput,
                   fmt::format("unknown turntable backend \"{}\" (expected mock, modbus or gpio)",
                               options.backend));
}

}  // namespace revolve::turntable
