// Files that are never half-written: write to a temporary name in the same directory, fsync,
// rename over the destination, fsync the directory.
#pragma once

#include <filesystem>
#include <functional>
#include <ostream>
#include <span>
#include <string_view>

#include "base/error.h"

namespace revolve {

// Writes `bytes` to `path` atomically. Errors (kIo / kNotFound) name the path and the reason
// (e.g. "No space left on device"); on error no temporary file is left behind and an existing
// file at `path` is untouched.
Expected<void> WriteFileAtomically(const std::filesystem::path& path, std::span<const char> bytes);
inline Expected<void> WriteFileAtomically(const std::filesystem::path& path,
                                          std::string_view text) {
  return WriteFileAtomically(path, std::span<const char>(text.data(), text.size()));
}

// Same, for content produced by a stream writer (large binary meshes). `write` returns false
// (or leaves the stream failed) to abandon the file.
Expected<void> WriteFileAtomically(const std::filesystem::path& path,
                                   const std::function<bool(std::ostream&)>& write);

}  // namespace revolve
