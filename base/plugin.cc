#include "base/plugin.h"

#include <dlfcn.h>

#include <filesystem>
#include <system_error>
#include <vector>

#include <fmt/format.h>

namespace revolve {

Expected<void*> LoadPluginEntry(const PluginFile& file, const char* entry_point,
                                const std::function<bool(void* entry)>& accept) {
  namespace fs = std::filesystem;
  std::vector<fs::path> candidates;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) candidates.push_back((exe.parent_path() / file.from_bindir).lexically_normal());
  candidates.emplace_back(file.build_file);
  std::string tried;
  for (const fs::path& path : candidates) {
    if (!fs::exists(path, ec)) {
      tried += fmt::format("\n  {}: no such file", path.string());
      continue;
    }
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) {
      tried += fmt::format("\n  {}: {}", path.string(), dlerror());
      continue;
    }
    void* entry = dlsym(handle, entry_point);
    if (entry == nullptr || !accept(entry)) {
      tried += fmt::format("\n  {}: not this build's plugin (rebuild or reinstall revolve)",
                           path.string());
      continue;
    }
    return entry;
  }
  return MakeError(ErrorCode::kIo,
                   fmt::format("cannot load {}; install revolve whole (cmake --install) or run it "
                               "from its build tree. Tried:{}",
                               file.name, tried));
}

}  // namespace revolve
