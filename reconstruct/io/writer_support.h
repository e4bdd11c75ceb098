// Internal to reconstruct/io: number formatting and the pieces the writers share (the files
// themselves are base/atomic_file.h's AtomicFile).
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "base/atomic_file.h"
#include "base/error.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct::internal {

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

// WriteObj with the texture already encoded: `png` is written beside it first; null when the
// caller writes the PNG (the .mtl names it all the same).
Expected<void> WriteObj(const Mesh& mesh, const std::filesystem::path& path,
                        const std::string* png);
// The texture's PNG for WriteGlb: called at most once, when a textured mesh's file is laid out
// up to the image, so the PNG may still be being encoded elsewhere (it may wait for it); null
// when it could not be encoded.
using PngSource = std::function<const std::string*()>;
// WriteGlb with the texture's PNG from `png` (unused without a texture). Error: internal when
// `png` gives null.
Expected<void> WriteGlb(const Mesh& mesh, const std::filesystem::path& path, const PngSource& png);

// Unit normal of each vertex: the area-weighted sum of its faces' normals; +z where that is zero.
std::vector<Eigen::Vector3f> VertexNormals(const Mesh& mesh);

}  // namespace revolve::reconstruct::internal
