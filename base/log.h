// One named spdlog logger per module ("turntable", "capture", "reconstruct", "station").
#pragma once

#include <memory>
#include <string>

#include <spdlog/spdlog.h>

namespace revolve {

// Returns the logger called `name`, creating it (stderr, shared format) on first use.
// Thread-safe.
std::shared_ptr<spdlog::logger> Logger(const std::string& name);

}  // namespace revolve
