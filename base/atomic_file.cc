#include "base/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "base/unique_fd.h"

namespace revolve {
namespace {

Error IoError(const std::filesystem::path& path, std::string_view what, int err) {
  return Error{ErrorCode::kIo, fmt::format("{}: {}: {}", path.string(), what, std::strerror(err))};
}

std::filesystem::path DirectoryOf(const std::filesystem::path& path) {
  std::filesystem::path dir = path.parent_path();
  return dir.empty() ? std::filesystem::path(".") : dir;
}

}  // namespace

void AtomicFile::FreeBuffer::operator()(char* p) const { std::free(p); }

AtomicFile::~AtomicFile() {
  if (!temp_.empty()) {
    fd_.Close();
    ::unlink(temp_.c_str());
  }
}

Expected<void> AtomicFile::Open() {
  std::string name =
      (DirectoryOf(path_) / ("." + path_.filename().string() + ".tmp-XXXXXX")).string();
  const int fd = ::mkostemp(name.data(), O_CLOEXEC);
  if (fd < 0) {
    return std::unexpected(IoError(path_, "cannot create the file", errno));
  }
  fd_ = UniqueFd(fd);
  temp_ = name;
  ::fchmod(fd, 0644);
  buffer_.reset(static_cast<char*>(std::aligned_alloc(kBlock, kBufferSize)));
  if (buffer_ == nullptr) {
    return std::unexpected(IoError(path_, "cannot allocate the write buffer", ENOMEM));
  }
  // Refused (EINVAL) by file systems without direct I/O: the page cache it is.
  const int flags = ::fcntl(fd, F_GETFL);
  direct_ = flags >= 0 && ::fcntl(fd, F_SETFL, flags | O_DIRECT) == 0;
  return {};
}

void AtomicFile::Append(std::string_view bytes) {
  if (!direct_ && bytes.size() >= kUncopiedSize) {
    // Large blocks (a PNG, a glTF buffer) go to the file without a copy.
    Flush();
    WriteAll(bytes);
    return;
  }
  while (!bytes.empty()) {
    const std::size_t n = std::min(bytes.size(), kBufferSize - end_);
    std::memcpy(buffer_.get() + end_, bytes.data(), n);
    end_ += n;
    bytes.remove_prefix(n);
    if (end_ == kBufferSize) {
      Flush();
    }
  }
}

void AtomicFile::WriteAt(std::size_t offset, std::string_view bytes) {
  WriteAt(offset, bytes.size(), [bytes](char* out, std::size_t from, std::size_t n) {
    std::memcpy(out, bytes.data() + from, n);
  });
}

void AtomicFile::WriteAt(std::size_t offset, std::size_t size, const FillBytes& fill) {
  // The whole blocks straight to the disk, made in the buffer (when no appended bytes wait in
  // it), as Flush writes them; the partial blocks at the edges through the page cache.
  const std::size_t first = std::min((offset + kBlock - 1) / kBlock * kBlock, offset + size);
  const std::size_t last = std::max((offset + size) / kBlock * kBlock, first);
  const bool direct = direct_ && end_ == 0 && first < last;
  // The edges (or all of it, through the page cache), a buffer at a time.
  std::string edge;
  const auto cached = [&](std::size_t from, std::size_t to) {
    for (std::size_t at = from; at < to && write_errno_ == 0;) {
      const std::size_t n = std::min(kBufferSize, to - at);
      edge.resize(n);
      fill(edge.data(), at - offset, n);
      PutAt(edge, at, /*cached=*/true);
      at += n;
    }
  };
  if (!direct) {
    cached(offset, offset + size);
    if (write_errno_ == 0 && !direct_ && size > 0) {
      // Best effort: without it the bytes are written back at Sync's fsync.
      (void)::sync_file_range(fd_.get(), static_cast<off_t>(offset), static_cast<off_t>(size),
                              SYNC_FILE_RANGE_WRITE);
    }
    return;
  }
  for (std::size_t at = first; at < last && write_errno_ == 0;) {
    const std::size_t n = std::min(kBufferSize, last - at);
    fill(buffer_.get(), at - offset, n);
    PutAt(std::string_view(buffer_.get(), n), at);
    at += n;
  }
  cached(offset, first);
  cached(last, offset + size);
}

void AtomicFile::PutAt(std::string_view bytes, std::size_t offset, bool cached) {
  if (bytes.empty()) return;
  // A direct file's partial blocks: O_DIRECT off for them alone.
  const bool toggle = cached && direct_;
  const int flags = toggle ? ::fcntl(fd_.get(), F_GETFL) : 0;
  if (toggle && (flags < 0 || ::fcntl(fd_.get(), F_SETFL, flags & ~O_DIRECT) != 0)) {
    if (write_errno_ == 0) write_errno_ = errno;
    return;
  }
  std::size_t done = 0;
  while (write_errno_ == 0 && done < bytes.size()) {
    const ssize_t n = ::pwrite(fd_.get(), bytes.data() + done, bytes.size() - done,
                               static_cast<off_t>(offset + done));
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EINVAL && direct_ && !cached) {
        StopDirect();  // direct I/O refused: again through the page cache
        continue;
      }
      write_errno_ = errno;
    } else {
      done += static_cast<std::size_t>(n);
    }
  }
  if (toggle && ::fcntl(fd_.get(), F_SETFL, flags) != 0 && write_errno_ == 0) write_errno_ = errno;
}

Expected<void> AtomicFile::Commit() {
  if (Expected<void> synced = Sync(); !synced) return synced;
  if (Expected<void> published = Publish(); !published) return published;
  // Make the rename itself durable (best effort, as before: the file is in place either way).
  (void)SyncDirectory(DirectoryOf(path_));
  return {};
}

Expected<void> AtomicFile::Sync() {
  Flush();
  if (end_ > 0) {  // a direct file's last partial block: through the page cache
    StopDirect();
    Flush();
  }
  if (write_errno_ != 0) {
    return std::unexpected(IoError(path_, "cannot write", write_errno_));
  }
  if (::fsync(fd_.get()) != 0) {
    return std::unexpected(IoError(path_, "cannot sync", errno));
  }
  if (const int err = fd_.Close(); err != 0) {
    return std::unexpected(IoError(path_, "cannot close", err));
  }
  buffer_.reset();
  return {};
}

Expected<void> AtomicFile::Publish() {
  if (::rename(temp_.c_str(), path_.c_str()) != 0) {
    return std::unexpected(IoError(path_, "cannot rename the finished file into place", errno));
  }
  temp_.clear();
  return {};
}

Expected<void> SyncDirectory(const std::filesystem::path& dir) {
  UniqueFd dir_fd(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir_fd.get() < 0) {
    return std::unexpected(IoError(dir, "cannot open the folder to sync it", errno));
  }
  if (::fsync(dir_fd.get()) != 0) {
    return std::unexpected(IoError(dir, "cannot sync the folder", errno));
  }
  return {};
}

void AtomicFile::Flush() {
  const std::size_t size = direct_ ? end_ / kBlock * kBlock : end_;
  WriteAll(std::string_view(buffer_.get(), size));
  if (size > 0) {
    std::memmove(buffer_.get(), buffer_.get() + size, end_ - size);
    end_ -= size;
  }
}

void AtomicFile::StopDirect() {
  const int flags = ::fcntl(fd_.get(), F_GETFL);
  if (flags < 0 || ::fcntl(fd_.get(), F_SETFL, flags & ~O_DIRECT) != 0) {
    if (write_errno_ == 0) {
      write_errno_ = errno;
    }
  }
  direct_ = false;
}

void AtomicFile::WriteAll(std::string_view bytes) {
  std::size_t done = 0;
  while (write_errno_ == 0 && done < bytes.size()) {
    const ssize_t n = ::write(fd_.get(), bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) {
        continue;
      }
      if (errno == EINVAL && direct_) {
        StopDirect();  // alignment or direct I/O refused: again through the page cache
        continue;
      }
      write_errno_ = errno;
    } else {
      done += static_cast<std::size_t>(n);
    }
  }
}

Expected<void> WriteFileAtomically(const std::filesystem::path& path, std::span<const char> bytes) {
  AtomicFile file(path);
  if (Expected<void> opened = file.Open(); !opened) {
    return opened;
  }
  file.Append(std::string_view(bytes.data(), bytes.size()));
  return file.Commit();
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

Expected<std::string> ReadWholeFile(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return MakeError(ErrorCode::kNotFound, fmt::format("{}: no such file", path.string()));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return MakeError(ErrorCode::kIo, fmt::format("{}: cannot open", path.string()));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

Expected<void> CreateOutputFolder(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    const std::string reason = ec.message();
    // Name the deepest folder that exists: where the system refused.
    std::filesystem::path parent = dir.parent_path();
    while (!parent.empty() && !std::filesystem::exists(parent, ec) &&
           parent != parent.parent_path()) {
      parent = parent.parent_path();
    }
    return MakeError(ErrorCode::kIo,
                     fmt::format("{}: cannot create the output folder: {} (in {}; choose an "
                                 "--out on a writable disk)",
                                 dir.string(), reason, parent.empty() ? "." : parent.string()));
  }
  if (!std::filesystem::is_directory(dir, ec)) {
    return MakeError(
        ErrorCode::kIo,
        fmt::format("{}: exists and is not a folder (choose another --out)", dir.string()));
  }
  if (::access(dir.c_str(), W_OK) != 0) {
    return MakeError(ErrorCode::kIo, fmt::format("{}: cannot write in the output folder: {} "
                                                 "(choose an --out on a writable disk)",
                                                 dir.string(), std::strerror(errno)));
  }
  return {};
}

}  // namespace revolve
