#include "base/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "base/unique_fd.h"

namespace revolve {
namespace {

Error IoError(const std::filesystem::path& path, std::string_view what, int err) {
  return Error{err == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIo,
               fmt::format("{}: {}: {}", path.string(), what, std::strerror(err))};
}

std::filesystem::path TempPathFor(const std::filesystem::path& path) {
  return path.parent_path() /
         fmt::format(".{}.tmp-{}", path.filename().string(), static_cast<long>(::getpid()));
}

}  // namespace

Expected<void> WriteFileAtomically(const std::filesystem::path& path, std::span<const char> bytes) {
  const std::filesystem::path tmp = TempPathFor(path);
  UniqueFd fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
  if (fd.get() < 0) return std::unexpected(IoError(path, "cannot create file", errno));
  const char* data = bytes.data();
  std::size_t left = bytes.size();
  while (left > 0) {
    const ssize_t n = ::write(fd.get(), data, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::unlink(tmp.c_str());
      return std::unexpected(IoError(path, "write failed", err));
    }
    data += n;
    left -= static_cast<std::size_t>(n);
  }
  if (::fsync(fd.get()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    return std::unexpected(IoError(path, "fsync failed", err));
  }
  if (::close(fd.Release()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    return std::unexpected(IoError(path, "close failed", err));
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    return std::unexpected(IoError(path, "rename failed", err));
  }
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : ".";
  UniqueFd dir_fd(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir_fd.get() >= 0) ::fsync(dir_fd.get());
  return {};
}

Expected<void> WriteFileAtomically(const std::filesystem::path& path,
                                   const std::function<bool(std::ostream&)>& write) {
  std::ostringstream buffer(std::ios::binary);
  if (!write(buffer) || !buffer) {
    return MakeError(ErrorCode::kInternal,
                     fmt::format("{}: could not serialise the content", path.string()));
  }
  const std::string bytes = std::move(buffer).str();
  return WriteFileAtomically(path, std::span<const char>(bytes.data(), bytes.size()));
}

}  // namespace revolve
