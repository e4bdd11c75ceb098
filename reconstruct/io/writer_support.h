// Internal to reconstruct/io: number formatting and the pieces the writers share (the files
// themselves are base/atomic_file.h's AtomicFile).
#pragma once

#include <array>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "base/atomic_file.h"
#include "base/error.h"
#include "reconstruct/io/fixed_text.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct::internal {

// bad_input "<path>: <what>": a file that is not what its reader expects.
Error BadFile(const std::filesystem::path& path, std::string_view what);

// Numbers as text, written at `out` (room for kMaxNumberChars bytes: they may store a few bytes
// past their text); they return the text's end.
char* WriteInt(char* out, long long value);
// `value` rounded to `decimals` (0..9) decimal places, trailing zeros dropped ("12.5", "-3",
// "0.0001"): several times faster than the shortest round-trip text, exact to half a unit of
// the last place. Non-finite or huge values: the shortest text that reads back as the same
// float. (fixed_text.h's WriteFixedN<decimals>, inlined, where the count is a constant.)
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

// How far the mesh a writer reads is final (reconstruct/mesh.h's MeshStage): the writers of a
// ModelWriter run while the mesh is made and wait here before reading each field.
class StageGate {
 public:
  // A gate already at `reached` (kDone: a finished mesh, where no writer waits), or at none.
  explicit StageGate(std::optional<MeshStage> reached = std::nullopt)
      : reached_(reached ? static_cast<int>(*reached) : -1) {}
  // The mesh reached `stage` (an earlier stage than one reached before: nothing changes).
  void Reach(MeshStage stage);
  // The mesh will not be finished: every Wait, now and later, returns nullopt.
  void Abandon();
  // Blocks until the mesh has reached `stage` or a later one, and returns the stage reached;
  // nullopt once the gate is abandoned.
  std::optional<MeshStage> Wait(MeshStage stage) const;

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  int reached_;
  bool abandoned_ = false;
};

// Whether a mesh that reached `stage` (kUvs or later) is written with its texture: kUvs promises
// one, kDone has it or not.
inline bool TexturedAt(const Mesh& mesh, MeshStage stage) {
  return stage == MeshStage::kUvs || (stage == MeshStage::kDone && mesh.HasTexture());
}

// aborted "<path>: ...": the gate was abandoned before the writer of `path` could finish.
Error AbandonedFile(const std::filesystem::path& path);

// The texture's PNG for the glTF writer: called at most once, when a textured mesh's file is laid
// out up to the image, so the PNG may still be being encoded elsewhere (it may wait for it); null
// when it could not be encoded.
using PngSource = std::function<const std::string*()>;

// The bytes of each format (mesh_io.h says what they hold) into `file`, opened and not yet
// synced, each field of `mesh` read only once `gate` has it final; the caller syncs and publishes
// the file. Errors: aborted (AbandonedFile) when the gate is abandoned first (the file is then
// incomplete); internal when `png` gives null.
Expected<void> PutPly(const Mesh& mesh, const StageGate& gate, AtomicFile* file);
Expected<void> PutStl(const Mesh& mesh, const StageGate& gate, AtomicFile* file);
// The vertices' coordinates as text, "x y z" in millimetres to 4 decimals (WriteFixedN<4>), made
// once for the writers that both write them (the VRML's points, the OBJ's vertices): by the first
// that asks, once the surface is final.
class VertexTexts {
 public:
  // The texts of `mesh`'s vertices (made on the first call; `mesh` must be the same each time).
  // Thread-safe.
  const VertexTexts& Of(const Mesh& mesh);
  // Writes vertex i's text at `out` (stores kCopyBytes; the text is at most kMaxText) and returns
  // its end.
  static constexpr std::size_t kMaxText = 3 * kMaxNumberChars;
  char* Write(char* out, std::size_t i) const {
    std::memcpy(out, text_.data() + start_[i], kCopyBytes);
    if (start_[i + 1] - start_[i] > kCopyBytes) {
      std::memcpy(out, text_.data() + start_[i], start_[i + 1] - start_[i]);
    }
    return out + (start_[i + 1] - start_[i]);
  }

 private:
  static constexpr std::size_t kCopyBytes = 32;
  std::once_flag made_;
  std::string text_;  // kCopyBytes of slack at the end
  std::vector<std::size_t> start_;
};

// Plain VRML only (not the meridian's view-dependent one). `texts` (may be null): the points'
// texts shared with the OBJ's writer.
Expected<void> PutVrml(const Mesh& mesh, const StageGate& gate, AtomicFile* file,
                       VertexTexts* texts = nullptr);
// The .obj into `obj` and its material library into `mtl` (both opened); the PNG the .mtl names
// is the caller's to write.
// `texts` (may be null): the vertices' texts shared with the VRML's writer.
Expected<void> PutObj(const Mesh& mesh, const StageGate& gate, AtomicFile* obj, AtomicFile* mtl,
                      VertexTexts* texts = nullptr);
// Textured, its bulk is written before the PNG is had, where it lies if the PNG is
// `png_size_guess` bytes (the bytes are the same for any guess; a right one writes the bulk once,
// while the PNG is being encoded).
inline constexpr std::size_t kPngSizeGuess = std::size_t{1} << 20;
Expected<void> PutGlb(const Mesh& mesh, const StageGate& gate, const PngSource& png,
                      AtomicFile* file, std::size_t png_size_guess = kPngSizeGuess);

// Unit normal of each vertex: the area-weighted sum of its faces' normals; +z where that is zero.
std::vector<Eigen::Vector3f> VertexNormals(const Mesh& mesh);

}  // namespace revolve::reconstruct::internal
