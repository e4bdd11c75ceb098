#include "turntable/modbus/profile_library.h"

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace revolve::turntable::modbus {
namespace fs = std::filesystem;

std::vector<fs::path> ProfileSearchPath() {
  std::vector<fs::path> dirs;
  if (const char* env = std::getenv("REVOLVE_PROFILE_PATH"); env != nullptr) {
    std::string_view rest(env);
    while (!rest.empty()) {
      const std::size_t colon = rest.find(':');
      const std::string_view dir = rest.substr(0, colon);
      if (!dir.empty()) dirs.emplace_back(dir);
      if (colon == std::string_view::npos) break;
      rest.remove_prefix(colon + 1);
    }
  }
  if (const char* xdg = std::getenv("XDG_CONFIG_HOME"); xdg != nullptr && *xdg != '\0') {
    dirs.push_back(fs::path(xdg) / "revolve/profiles");
  } else if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    dirs.push_back(fs::path(home) / ".config/revolve/profiles");
  }
  dirs.emplace_back("/etc/revolve/profiles");
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) dirs.push_back(exe.parent_path().parent_path() / "share/revolve/profiles");
#ifdef REVOLVE_PROFILE_INSTALL_DIR
  dirs.emplace_back(REVOLVE_PROFILE_INSTALL_DIR);
#endif
#ifdef REVOLVE_PROFILE_SOURCE_DIR
  dirs.emplace_back(REVOLVE_PROFILE_SOURCE_DIR);
#endif
  return dirs;
}

Expected<fs::path> FindProfile(std::string_view name_or_path, const fs::path& config_dir) {
  std::error_code ec;
  if (name_or_path.find('/') != std::string_view::npos || name_or_path.ends_with(".toml")) {
    fs::path path(name_or_path);
    if (path.is_relative() && !config_dir.empty()) path = config_dir / path;
    if (!fs::is_regular_file(path, ec)) {
      return MakeError(ErrorCode::kNotFound,
                       fmt::format("profile file {} not found", path.string()));
    }
    return path;
  }
  std::vector<std::string> searched;
  for (const fs::path& dir : ProfileSearchPath()) {
    const fs::path candidate = dir / (std::string(name_or_path) + ".toml");
    if (fs::is_regular_file(candidate, ec)) return candidate;
    searched.push_back(dir.string());
  }
  return MakeError(ErrorCode::kNotFound,
                   fmt::format("no drive profile \"{}\" (known: {}; searched {}). Give a file "
                               "path, or put {}.toml in one of those directories",
                               name_or_path, fmt::join(ListProfiles(), ", "),
                               fmt::join(searched, ", "), name_or_path));
}

std::vector<std::string> ListProfiles() {
  std::set<std::string> names;
  for (const fs::path& dir : ProfileSearchPath()) {
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
      if (it->path().extension() == ".toml") names.insert(it->path().stem().string());
    }
  }
  return {names.begin(), names.end()};
}

}  // namespace revolve::turntable::modbus
