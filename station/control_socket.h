// The daemon's control socket: a Unix stream socket with the configured owner group and mode.
#pragma once

#include <filesystem>

#include "base/error.h"
#include "base/unique_fd.h"
#include "station/station_config.h"

namespace revolve::station {

// Binds and listens on `path` (a stale socket file left by a dead daemon is replaced; a live
// one is refused), with `o`'s group and mode. Errors name the path and the system's reason.
Expected<UniqueFd> BindControlSocket(const std::filesystem::path& path, const DaemonOptions& o);

}  // namespace revolve::station
