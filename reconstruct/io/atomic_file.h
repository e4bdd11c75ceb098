// Internal to reconstruct/io: the atomic file every writer goes through, number formatting, and
// the pieces the writers share.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct::internal {

// An open file descriptor (RAII).
class UniqueFd {
 public:
  explicit UniqueFd(int fd = -1) : fd_(fd) {}
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;
  ~UniqueFd() { Reset(); }
  int get() const { return fd_; }
  void Reset(int fd = -1);
  // Closes now and reports close(2)'s errno (0 on success).
  int Close();

 private:
  int fd_;
};

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
  void Flush();

  std::filesystem::path path_;
  std::string temp_;
  UniqueFd fd_;
  std::string buffer_;
  int write_errno_ = 0;
};

// The whole of `bytes` as `path`, atomically.
Expected<void> WriteFileAtomically(const std::filesystem::path& path, std::string_view bytes);

// Shortest text that reads back as the same float.
void AppendFloat(std::string* out, float value);
void AppendInt(std::string* out, long long value);
// `value` rounded to `decimals` (0..9) decimal places, trailing zeros dropped ("12.5", "-3",
// "0.0001"): several times faster than the shortest round-trip text, exact to half a unit of
// the last place. Non-finite or huge values fall back to AppendFloat.
void AppendFixed(std::string* out, float value, int decimals);

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
