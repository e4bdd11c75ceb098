// Where drive profiles are found at run time.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"

namespace revolve::turntable::modbus {

// Directories searched for "<name>.toml", first match wins:
//   1. each directory of $REVOLVE_PROFILE_PATH (colon-separated), for users' own profiles;
//   2. $XDG_CONFIG_HOME/revolve/profiles (or ~/.config/revolve/profiles), /etc/revolve/profiles;
//   3. <prefix>/share/revolve/profiles next to the running executable (a relocated install)
//      and the install prefix given at build time (`cmake --install`);
//   4. the source tree's turntable/modbus/profiles (builds run from the build directory).
std::vector<std::filesystem::path> ProfileSearchPath();

// Resolves `name_or_path`: a value with a '/' or ending in ".toml" is a file path (relative ones
// are taken from `config_dir`); anything else is a profile name looked up in
// ProfileSearchPath(). Errors: not_found listing the directories searched and the profiles found.
Expected<std::filesystem::path> FindProfile(std::string_view name_or_path,
                                            const std::filesystem::path& config_dir);

// Names of every profile on the search path (sorted, unique), for messages and `--list`.
std::vector<std::string> ListProfiles();

}  // namespace revolve::turntable::modbus
