#include "reconstruct/io/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>

#include <fmt/format.h>

namespace revolve::reconstruct::internal {
namespace {

namespace fs = std::filesystem;

Error IoError(const fs::path& path, std::string_view what, int err) {
  return Error{ErrorCode::kIo, fmt::format("{}: {}: {}", path.string(), what, std::strerror(err))};
}

fs::path DirectoryOf(const fs::path& path) {
  fs::path dir = path.parent_path();
  return dir.empty() ? fs::path(".") : dir;
}

}  // namespace

void UniqueFd::Reset(int fd) {
  if (fd_ >= 0) {
    ::close(fd_);
  }
  fd_ = fd;
}

int UniqueFd::Close() {
  int err = 0;
  if (fd_ >= 0 && ::close(fd_) != 0) {
    err = errno;
  }
  fd_ = -1;
  return err;
}

AtomicFile::~AtomicFile() {
  if (!temp_.empty()) {
    fd_.Close();
    ::unlink(temp_.c_str());
  }
}

Expected<void> AtomicFile::Open() {
  std::string name =
      (DirectoryOf(path_) / ("." + path_.filename().string() + ".tmp-XXXXXX")).string();
  const int fd = ::mkstemp(name.data());
  if (fd < 0) {
    return std::unexpected(IoError(path_, "cannot create the file", errno));
  }
  fd_.Reset(fd);
  temp_ = name;
  ::fchmod(fd, 0644);
  buffer_.reserve(kBufferSize);
  return {};
}

Expected<void> AtomicFile::Commit() {
  Flush();
  if (write_errno_ != 0) {
    return std::unexpected(IoError(path_, "cannot write", write_errno_));
  }
  if (::fsync(fd_.get()) != 0) {
    return std::unexpected(IoError(path_, "cannot sync", errno));
  }
  if (const int err = fd_.Close(); err != 0) {
    return std::unexpected(IoError(path_, "cannot close", err));
  }
  if (::rename(temp_.c_str(), path_.c_str()) != 0) {
    return std::unexpected(IoError(path_, "cannot rename the finished file into place", errno));
  }
  temp_.clear();
  // Make the rename itself durable.
  UniqueFd dir_fd(::open(DirectoryOf(path_).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir_fd.get() >= 0) {
    ::fsync(dir_fd.get());
  }
  return {};
}

void AtomicFile::Flush() {
  std::size_t done = 0;
  while (write_errno_ == 0 && done < buffer_.size()) {
    const ssize_t n = ::write(fd_.get(), buffer_.data() + done, buffer_.size() - done);
    if (n < 0) {
      if (errno == EINTR) {
        continue;
      }
      write_errno_ = errno;
    } else {
      done += static_cast<std::size_t>(n);
    }
  }
  buffer_.clear();
}

Expected<void> WriteFileAtomically(const fs::path& path, std::string_view bytes) {
  AtomicFile file(path);
  if (Expected<void> opened = file.Open(); !opened) {
    return opened;
  }
  file.Append(bytes);
  return file.Commit();
}

void AppendFloat(std::string* out, float value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out->append(buffer, result.ptr);
}

void AppendInt(std::string* out, long long value) {
  char buffer[24];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out->append(buffer, result.ptr);
}

void AppendFixed(std::string* out, float value, int decimals) {
  static constexpr long long kPow10[] = {1,      10,      100,      1000,      10000,
                                         100000, 1000000, 10000000, 100000000, 1000000000};
  decimals = std::clamp(decimals, 0, 9);
  const double scaled = std::round(static_cast<double>(value) * kPow10[decimals]);
  if (!std::isfinite(scaled) || std::abs(scaled) > 1e17) {
    AppendFloat(out, value);
    return;
  }
  long long q = static_cast<long long>(scaled);
  if (q < 0) {
    out->push_back('-');
    q = -q;
  }
  AppendInt(out, q / kPow10[decimals]);
  long long fraction = q % kPow10[decimals];
  if (fraction == 0) {
    return;
  }
  int digits = decimals;
  while (fraction % 10 == 0) {
    fraction /= 10;
    --digits;
  }
  char buffer[16];
  for (int d = digits - 1; d >= 0; --d) {
    buffer[d] = static_cast<char>('0' + fraction % 10);
    fraction /= 10;
  }
  out->push_back('.');
  out->append(buffer, static_cast<std::size_t>(digits));
}

}  // namespace revolve::reconstruct::internal
