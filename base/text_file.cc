#include "base/text_file.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>

#include <fmt/format.h>

namespace revolve {

Expected<std::string> ReadRegularFile(const std::filesystem::path& path, std::uintmax_t max_bytes) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status)) {
    return MakeError(ErrorCode::kNotFound, fmt::format("{}: no such file", path.string()));
  }
  if (fs::is_directory(status)) {
    return MakeError(ErrorCode::kBadInput, fmt::format("{}: is a directory", path.string()));
  }
  if (!fs::is_regular_file(status)) {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("{}: not a regular file (a device, FIFO or socket)", path.string()));
  }
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) {
    return MakeError(ErrorCode::kIo,
                     fmt::format("{}: cannot read: {}", path.string(), ec.message()));
  }
  if (size > max_bytes) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("{}: {} bytes is too large for this file (at most {})",
                                 path.string(), size, max_bytes));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return MakeError(ErrorCode::kIo,
                     fmt::format("{}: cannot open: {}", path.string(), std::strerror(errno)));
  }
  std::string text;
  text.reserve(static_cast<std::size_t>(size));
  text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (in.bad()) return MakeError(ErrorCode::kIo, fmt::format("{}: cannot read", path.string()));
  return text;
}

}  // namespace revolve
