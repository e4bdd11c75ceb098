// revolve's plugins: MODULE libraries installed in <libdir>/revolve/ and loaded on first use, so
// that what only some commands need (OpenCV's image codecs, libcamera) is not loaded by every
// start of every command. Each plugin exports one function by name that returns its table.
#pragma once

#include <functional>
#include <string>

#include "base/error.h"

namespace revolve {

// Where a plugin's file is: `from_bindir` relative to the running executable's folder (an
// installed revolve), then `build_file` (the build tree's, for revolve run from there).
struct PluginFile {
  std::string name;         // for messages: "librevolve_imgcodecs.so"
  std::string from_bindir;  // "../lib/revolve/librevolve_imgcodecs.so"
  std::string build_file;   // absolute
};

// The address `entry_point` names in the first of the plugin's files that loads
// (dlopen RTLD_NOW | RTLD_LOCAL) and that `accept` takes (the caller's version check); the
// library stays loaded for the life of the process. Errors: io, naming every file tried and why
// it was not taken.
Expected<void*> LoadPluginEntry(const PluginFile& file, const char* entry_point,
                                const std::function<bool(void* entry)>& accept);

// The table a plugin's entry point (`const Table* entry()`) returns, taken when its `version` is
// `version` (both sides built together; another is a stale plugin from another build).
template <typename Table>
Expected<const Table*> LoadPluginTable(const PluginFile& file, const char* entry_point,
                                       int version) {
  const Table* table = nullptr;
  const Expected<void*> entry = LoadPluginEntry(file, entry_point, [&](void* address) {
    table = reinterpret_cast<const Table* (*)()>(address)();
    return table != nullptr && table->version == version;
  });
  if (!entry) return std::unexpected(entry.error());
  return table;
}

}  // namespace revolve
