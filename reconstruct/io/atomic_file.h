// Internal to reconstruct/io: the atomic file every writer goes through, number formatting, and
// the pieces the writers share.
#pragma once

#include <filesystem>
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
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path path) : path_(std::move(path)) {}
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  Expected<void> Open();
  void Append(std::string_view bytes) {
    if (bytes.size() >= kDirectSize) {
      // Large blocks (a text writer's full buffer, a PNG) go to the file without a copy.
      Flush();
      WriteAll(bytes);
      return;
    }
    buffer_.append(bytes);
    if (buffer_.size() >= kBufferSize) {
      Flush();
    }
  }
  template <class T>
  void AppendRaw(const T& value) {
    Append(std::string_view(reinterpret_cast<const char*>(&value), sizeof(T)));
  }
  Expected<void> Commit();

 private:
  static constexpr std::size_t kBufferSize = 1 << 20;
  static constexpr std::size_t kDirectSize = 1 << 16;
  void Flush();
  // Writes all of `bytes` at the file's end (records the first error).
  void WriteAll(std::string_view bytes);

  std::filesystem::path path_;
  std::string temp_;
  UniqueFd fd_;
  std::string buffer_;
  int write_errno_ = 0;
};

// The whole of `bytes` as `path`, atomically.
Expected<void> WriteFileAtomically(const std::filesystem::path& path, std::string_view bytes);

// The whole file, for the readers. Errors: not_found or io, naming the path.
Expected<std::string> ReadWholeFile(const std::filesystem::path& path);
// bad_input "<path>: <what>": a file that is not what its reader expects.
Error BadFile(const std::filesystem::path& path, std::string_view what);

// Shortest text that reads back as the same float.
void AppendFloat(std::string* out, float value);
void AppendInt(std::string* out, long long value);
// `value` rounded to `decimals` (0..9) decimal places, trailing zeros dropped ("12.5", "-3",
// "0.0001"): several times faster than the shortest round-trip text, exact to half a unit of
// the last place. Non-finite or huge values fall back to AppendFloat.
void AppendFixed(std::string* out, float value, int decimals);
// The same texts written at `out` (room for kMaxNumberChars bytes); return the end.
inline constexpr std::size_t kMaxNumberChars = 48;
char* WriteInt(char* out, long long value);
char* WriteFixed(char* out, float value, int decimals);

// Text assembled in a fixed buffer and handed to `file` in large blocks (no per-number
// allocation or size check).
class TextOut {
 public:
  explicit TextOut(AtomicFile* file) : file_(file), buffer_(kSize) {}
  TextOut(const TextOut&) = delete;
  TextOut& operator=(const TextOut&) = delete;
  // Where to write up to `n` (<= kRoomMax) more bytes; End(p) then marks p as the text's end.
  static constexpr std::size_t kRoomMax = 4096;
  char* Room(std::size_t n) {
    if (end_ + n > buffer_.size()) {
      Flush();
    }
    return buffer_.data() + end_;
  }
  void End(const char* p) { end_ = static_cast<std::size_t>(p - buffer_.data()); }
  void Put(std::string_view text);
  // Hands the text so far to the file (done before the file commits).
  void Flush();

 private:
  static constexpr std::size_t kSize = 1 << 18;
  AtomicFile* file_;
  std::vector<char> buffer_;
  std::size_t end_ = 0;
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
