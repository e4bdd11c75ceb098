// Reading a small file that revolve reads whole as text (a config, a calibration, a camera file,
// a manifest) without trusting what the path names: a device (/dev/zero, /dev/urandom), a FIFO
// or a socket given by mistake or malice is an error at once, never a read that does not end or
// fills memory.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "base/error.h"

namespace revolve {

// The whole of `path` when it is a regular file (a symbolic link to one is fine) of at most
// `max_bytes`. Errors, naming the path: not_found (nothing there), bad_input (a directory, a
// device, FIFO or socket, or larger than max_bytes), io (unreadable, with the system's reason).
Expected<std::string> ReadRegularFile(const std::filesystem::path& path, std::uintmax_t max_bytes);

}  // namespace revolve
