// Files that are never half-written: write to a temporary name in the same directory, fsync,
// rename over the destination, fsync the directory. The one atomic writer of the project: the
// scan folder, the calibration, the configs and the model writers all go through it.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <ostream>
#include <span>
#include <string>
#include <string_view>

#include "base/error.h"
#include "base/unique_fd.h"

namespace revolve {

// Buffered writer to a temporary file (".<name>.tmp-XXXXXX" beside `path`) that becomes `path`
// on Commit (fsync, rename, fsync of the directory). Destroyed before Commit, or after a failed
// one, it removes the temporary file. Errors name `path`.
//
// The writers build their bytes in place in the file's buffer (Room/End, PutEach) or hand them
// over (Append). Where the file system allows it, whole blocks of the buffer go to the file with
// O_DIRECT, without the kernel copying them into the page cache and writing them back at fsync
// (the larger part of a model file's CPU time otherwise); the last partial block, and every
// byte on a file system without O_DIRECT, go through the page cache. Durability is the same.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path path) : path_(std::move(path)) {}
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  // Creates the temporary file; the calls below need it open.
  Expected<void> Open();

  // Where to write up to `n` (<= kRoomMax) more bytes; End(p) then marks p as the file's end.
  static constexpr std::size_t kRoomMax = 4096;
  char* Room(std::size_t n) {
    if (end_ + n > kBufferSize) {
      Flush();
    }
    return buffer_.get() + end_;
  }
  void End(const char* p) { end_ = static_cast<std::size_t>(p - buffer_.get()); }
  // Writes items 0 .. count - 1 in order: `write_item(p, i)` writes item i at p, at most
  // `max_bytes` (<= kRoomMax) of it, and returns its end. The room is checked once per block of
  // items rather than once per item.
  template <class WriteItem>
  void PutEach(std::size_t count, std::size_t max_bytes, WriteItem write_item) {
    for (std::size_t i = 0; i < count;) {
      char* p = Room(kRoomMax);
      const char* const last_start = p + (kRoomMax - max_bytes);
      for (; i < count && p <= last_start; ++i) {
        p = write_item(p, i);
      }
      End(p);
    }
  }
  void Append(std::string_view bytes);
  // Writes `bytes` at byte `offset` of the file, apart from the appended bytes (which go on at
  // their own end; the caller keeps the two from overlapping): for a file whose bulk is known
  // before its head (the glTF's buffer before its JSON). Whole blocks go straight to the disk
  // where the appends do (and no appended bytes wait in the buffer), the rest through the page
  // cache. Errors are reported by Sync, as the appends' are.
  void WriteAt(std::size_t offset, std::string_view bytes);
  // The same for `size` bytes made as they are written: fill(out, from, n) writes bytes
  // [from, from + n) of them at `out` (a buffer's worth at a time; any range may be asked again).
  using FillBytes = std::function<void(char* out, std::size_t from, std::size_t n)>;
  void WriteAt(std::size_t offset, std::size_t size, const FillBytes& fill);
  template <class T>
  void AppendRaw(const T& value) {
    Append(std::string_view(reinterpret_cast<const char*>(&value), sizeof(T)));
  }
  // Commit = Sync, Publish, then SyncDirectory of the path's folder.
  Expected<void> Commit();
  // The two halves of Commit, for files put in place together (one directory sync for all):
  // Sync writes what is buffered, fsyncs and closes the temporary file (the calls above may not
  // follow); Publish, after a successful Sync, renames it over `path` (the rename is durable once
  // the folder is synced). Errors name `path`; after an error the temporary file is still removed
  // by the destructor.
  Expected<void> Sync();
  Expected<void> Publish();
  const std::filesystem::path& path() const { return path_; }

 private:
  // The buffer: a multiple of kBlock, aligned to it.
  static constexpr std::size_t kBufferSize = 1 << 20;
  // O_DIRECT's unit: buffer address, file offset and length are multiples of it.
  static constexpr std::size_t kBlock = 4096;
  // Appended blocks at least this large skip the buffer when the file is not direct.
  static constexpr std::size_t kUncopiedSize = 1 << 16;
  struct FreeBuffer {
    void operator()(char* p) const;
  };
  // Writes the buffer to the file: its whole blocks when direct (the rest moves to the buffer's
  // start), else all of it.
  void Flush();
  // Writes all of `bytes` at the file's end (records the first error). A direct write the file
  // system refuses turns O_DIRECT off and is written again.
  void WriteAll(std::string_view bytes);
  // pwrite of all of `bytes` at `offset` (records the first error); `cached`: through the page
  // cache even when the file is direct.
  void PutAt(std::string_view bytes, std::size_t offset, bool cached = false);
  // Turns O_DIRECT off: what follows goes through the page cache.
  void StopDirect();

  std::filesystem::path path_;
  std::string temp_;
  UniqueFd fd_;
  std::unique_ptr<char[], FreeBuffer> buffer_;
  std::size_t end_ = 0;
  bool direct_ = false;
  int write_errno_ = 0;
};

// fsyncs the folder `dir`, making the renames into it durable. Errors: io naming `dir`.
Expected<void> SyncDirectory(const std::filesystem::path& dir);

// Writes `bytes` to `path` atomically. Errors (kIo) name the path and the reason
// (e.g. "No space left on device"); on error no temporary file is left behind and an existing
// file at `path` is untouched.
Expected<void> WriteFileAtomically(const std::filesystem::path& path, std::span<const char> bytes);
inline Expected<void> WriteFileAtomically(const std::filesystem::path& path,
                                          std::string_view text) {
  return WriteFileAtomically(path, std::span<const char>(text.data(), text.size()));
}
inline Expected<void> WriteFileAtomically(const std::filesystem::path& path,
                                          const std::string& text) {
  return WriteFileAtomically(path, std::string_view(text));
}

// Same, for content produced by a stream writer (large binary meshes). `write` returns false
// (or leaves the stream failed) to abandon the file.
Expected<void> WriteFileAtomically(const std::filesystem::path& path,
                                   const std::function<bool(std::ostream&)>& write);

// The whole file. Errors: kNotFound or kIo, naming the path.
Expected<std::string> ReadWholeFile(const std::filesystem::path& path);

// Creates the folder `dir` (and its parents) for output and checks it can be written. Errors:
// io naming `dir` (or the parent that could not be made) and the system's reason, e.g. "Read-only
// file system" or "Permission denied", with what to do.
Expected<void> CreateOutputFolder(const std::filesystem::path& dir);

}  // namespace revolve
