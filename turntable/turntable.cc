#include "turntable/turntable.h"

#include <fmt/format.h>

#include "turntable/mock/mock_turntable.h"

namespace revolve::turntable {
namespace {

// A number in (0, max]: Section::Number checks [0, max], the open lower bound is checked here.
Expected<double> PositiveNumber(const config::Section& section, std::string_view key,
                                double fallback, double max) {
  Expected<double> value = section.Number(key, fallback, 0.0, max);
  if (value && *value <= 0.0) {
    return std::unexpected(
        section.BadValue(key, fmt::format("must be greater than 0 (and at most {})", max)));
  }
  return value;
}

Error Unsupported(Error error) {
  error.code = ErrorCode::kUnsupported;
  return error;
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
  if (*backend != "mock") {
    return std::unexpected(Unsupported(section.BadValue(
        "backend",
        fmt::format("the {} backend is not built yet (this build has only \"mock\")", *backend))));
  }
  for (std::string_view other : {"modbus", "gpio"}) {
    if (section.Has(other)) {
      return std::unexpected(Unsupported(section.BadValue(
          other, fmt::format("the {} backend is not built yet: remove this table (this build "
                             "has only \"mock\")",
                             other))));
    }
  }
  options.backend = *backend;

  Expected<config::Section> mock_section = section.Child("mock");
  if (!mock_section) return std::unexpected(mock_section.error());
  Expected<MockOptions> mock = ParseMockOptions(*mock_section);
  if (!mock) return std::unexpected(mock.error());
  options.mock = std::move(*mock);

  if (Expected<void> known = section.CheckNoUnknownKeys(); !known) {
    return std::unexpected(known.error());
  }
  return options;
}

Expected<std::unique_ptr<Turntable>> Create(const TurntableOptions& options,
                                            std::shared_ptr<SimulatedPlate> plate) {
  if (options.backend == "mock") {
    if (Expected<void> valid = ValidateMockOptions(options.mock); !valid) {
      return std::unexpected(valid.error());
    }
    return std::make_unique<MockTurntable>(options.mock, std::move(plate));
  }
  if (options.backend == "modbus" || options.backend == "gpio") {
    return MakeError(ErrorCode::kUnsupported,
                     fmt::format("turntable backend \"{}\" is not built yet (this build has only "
                                 "\"mock\")",
                                 options.backend));
  }
  return MakeError(
      ErrorCode::kBadInput,
      fmt::format("unknown turntable backend \"{}\" (expected \"mock\")", options.backend));
}

}  // namespace revolve::turntable
