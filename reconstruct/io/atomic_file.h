// Internal to reconstruct/io: the atomic file every writer goes through, number formatting, and
// the pieces the writers share.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"
#include "base/unique_fd.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct::internal {

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
  template <class T>
  void AppendRaw(const T& value) {
    Append(std::string_view(reinterpret_cast<const char*>(&value), sizeof(T)));
  }
  Expected<void> Commit();

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

// The whole of `bytes` as `path`, atomically.
Expected<void> WriteFileAtomically(const std::filesystem::path& path, std::string_view bytes);

// The whole file, for the readers. Errors: not_found or io, naming the path.
Expected<std::string> ReadWholeFile(const std::filesystem::path& path);
// bad_input "<path>: <what>": a file that is not what its reader expects.
Error BadFile(const std::filesystem::path& path, std::string_view what);

// Numbers as text, written at `out` (room for kMaxNumberChars bytes: they may store a few bytes
// past their text); they return the text's end.
inline constexpr std::size_t kMaxNumberChars = 48;
char* WriteInt(char* out, long long value);
// `value` rounded to `decimals` (0..9) decimal places, trailing zeros dropped ("12.5", "-3",
// "0.0001"): several times faster than the shortest round-trip text, exact to half a unit of
// the last place. Non-finite or huge values: the shortest text that reads back as the same
// float.
char* WriteFixed(char* out, float value, int decimals);

// A text of up to 7 bytes and its length held in one word (the text from the lowest byte, the
// length in the highest), so that it is written with one store and no search for its end: the
// short texts a writer repeats (vertex indices, colour channels).
std::uint64_t WordText(std::string_view text);
// Writes `word`'s text at `out` (stores 8 bytes); returns the text's end.
inline char* WriteWordText(char* out, std::uint64_t word) {
  std::memcpy(out, &word, 8);
  return out + (word >> 56);
}

// `prefix` (at most 1 byte) and c for each 8-bit colour channel value, as WordText:
// c = value / 255 with 4 decimals (trailing zeros dropped), which reads back as the same byte.
std::array<std::uint64_t, 256> ChannelTexts(std::string_view prefix);

// The decimal texts of first, first + 1, ..., first + count - 1, each made once: a mesh writer's
// vertex indices, each written several times.
class IndexTexts {
 public:
  IndexTexts(int first, std::size_t count);
  // Writes the text of `first + i` at `out` (room for kMaxNumberChars bytes); returns its end.
  // Any i works; one outside [0, count) is formatted on the spot, as are all when a text would
  // not fit in a WordText (first < 0 or first + count > 10^7).
  char* Write(char* out, int i) const {
    if (static_cast<std::size_t>(i) < words_.size()) {
      return WriteWordText(out, words_[static_cast<std::size_t>(i)]);
    }
    return WriteInt(out, static_cast<long long>(first_) + i);
  }

 private:
  int first_;
  std::vector<std::uint64_t> words_;  // WordText; empty when a text would not fit
};

// The texture as PNG bytes (fast compression). Errors: internal when OpenCV cannot encode it.
Expected<std::string> EncodePng(const cv::Mat& bgr);

// WriteObj / WriteGlb with the texture already encoded (`png`: null to encode it here).
Expected<void> WriteObj(const Mesh& mesh, const std::filesystem::path& path,
                        const std::string* png);
Expected<void> WriteGlb(const Mesh& mesh, const std::filesystem::path& path,
                        const std::string* png);

// Unit normal of each vertex: the area-weighted sum of its faces' normals; +z where that is zero.
std::vector<Eigen::Vector3f> VertexNormals(const Mesh& mesh);

}  // namespace revolve::reconstruct::internal
