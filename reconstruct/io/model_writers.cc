// OBJ + MTL + PNG, binary STL and glTF binary writers; OBJ and STL readers.
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unordered_map>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "base/png_encode.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/io/writer_support.h"

namespace revolve::reconstruct {
namespace {

namespace fs = std::filesystem;

static_assert(std::endian::native == std::endian::little,
              "the STL and glTF writers assume a little-endian host");
static_assert(sizeof(Eigen::Vector3f) == 12 && sizeof(Eigen::Vector3i) == 12,
              "the glTF writer copies packed triples of floats and of int indices");

using internal::BadFile;

constexpr const char* kMaterialName = "revolve";
// Text coordinates: 0.1 um in millimetres, far below any scan's accuracy.
constexpr int kMmDecimals = 4;
static_assert(kMmDecimals == 4, "the OBJ's vertices may be VertexTexts, which have 4 decimals");

Eigen::Vector3f FaceNormal(const Mesh& mesh, const Eigen::Vector3i& f) {
  const Eigen::Vector3f& a = mesh.vertices[f[0]];
  const Eigen::Vector3f n = (mesh.vertices[f[1]] - a).cross(mesh.vertices[f[2]] - a);
  const float length = n.norm();
  return length > 0.0f ? Eigen::Vector3f(n / length) : Eigen::Vector3f::Zero();
}

// A double that parses back to exactly `value` (glTF's min/max must equal the data's).
void AppendExact(std::string* out, float value) {
  char buffer[40];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), static_cast<double>(value));
  out->append(buffer, result.ptr);
}

// The bytes of a vector of packed values (floats, ints, Eigen vectors of them).
template <class T>
std::string_view BytesOf(const std::vector<T>& values) {
  return {reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T)};
}

void Pad4(std::string* bytes, char fill) {
  while (bytes->size() % 4 != 0) {
    bytes->push_back(fill);
  }
}

}  // namespace

namespace internal {

std::vector<Eigen::Vector3f> VertexNormals(const Mesh& mesh) {
  std::vector<Eigen::Vector3f> normals(mesh.vertices.size(), Eigen::Vector3f::Zero());
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3f& a = mesh.vertices[f[0]];
    // Twice the area times the unit normal.
    const Eigen::Vector3f n = (mesh.vertices[f[1]] - a).cross(mesh.vertices[f[2]] - a);
    for (int c = 0; c < 3; ++c) {
      normals[f[c]] += n;
    }
  }
  for (Eigen::Vector3f& n : normals) {
    const float length = n.norm();
    n = length > 0.0f && std::isfinite(length) ? Eigen::Vector3f(n / length)
                                               : Eigen::Vector3f::UnitZ();
  }
  return normals;
}

Expected<void> PutObj(const Mesh& mesh, const StageGate& gate, AtomicFile* obj, AtomicFile* mtl,
                      VertexTexts* texts) {
  const fs::path& path = obj->path();
  if (!gate.Wait(MeshStage::kSurface)) return std::unexpected(AbandonedFile(path));
  const fs::path png_path = fs::path(path).replace_extension(".png");
  std::string text = fmt::format(
      "# revolve model: object frame, millimetres, z up; {} vertices, {} triangles\n"
      "mtllib {}\n",
      mesh.vertices.size(), mesh.faces.size(), mtl->path().filename().string());
  obj->Append(text);
  // Colour channels and vertex indices as text, once per value.
  const std::array<std::uint64_t, 256> channel = ChannelTexts(" ");
  const IndexTexts index(1, mesh.vertices.size());
  constexpr std::size_t kMaxLine = 8 * kMaxNumberChars;
  if (!gate.Wait(MeshStage::kColors)) return std::unexpected(AbandonedFile(path));
  const bool colors = mesh.HasColors();
  const VertexTexts* const points = texts != nullptr ? &texts->Of(mesh) : nullptr;
  obj->PutEach(mesh.vertices.size(), kMaxLine, [&](char* p, std::size_t i) {
    *p++ = 'v';
    if (points != nullptr) {
      *p++ = ' ';
      p = points->Write(p, i);
    } else {
      for (int k = 0; k < 3; ++k) {
        *p++ = ' ';
        p = WriteFixedN<kMmDecimals>(p, mesh.vertices[i][k]);
      }
    }
    if (colors) {
      for (int k = 0; k < 3; ++k) {
        p = WriteWordText(p, channel[mesh.colors[i][k]]);
      }
    }
    *p = '\n';
    return p + 1;
  });
  // The uvs, or the news that there are none.
  const std::optional<MeshStage> reached = gate.Wait(MeshStage::kUvs);
  if (!reached) return std::unexpected(AbandonedFile(path));
  const bool textured = TexturedAt(mesh, *reached);
  if (textured) {
    obj->PutEach(mesh.uvs.size(), kMaxLine, [&mesh](char* p, std::size_t i) {
      std::copy_n("vt ", 3, p);
      p = WriteFixedN<6>(p + 3, mesh.uvs[i].x());
      *p++ = ' ';
      p = WriteFixedN<6>(p, 1.0f - mesh.uvs[i].y());
      *p = '\n';
      return p + 1;
    });
  }
  obj->Append(fmt::format("usemtl {}\n", kMaterialName));
  if (textured) {
    const IndexTexts uv_index(1, mesh.uvs.size());
    obj->PutEach(mesh.faces.size(), kMaxLine, [&](char* p, std::size_t i) {
      *p++ = 'f';
      for (int c = 0; c < 3; ++c) {
        *p++ = ' ';
        p = index.Write(p, mesh.faces[i][c]);
        *p++ = '/';
        p = uv_index.Write(p, mesh.uv_faces[i][c]);
      }
      *p = '\n';
      return p + 1;
    });
  } else {
    obj->PutEach(mesh.faces.size(), kMaxLine, [&mesh, &index](char* p, std::size_t i) {
      *p++ = 'f';
      for (int c = 0; c < 3; ++c) {
        *p++ = ' ';
        p = index.Write(p, mesh.faces[i][c]);
      }
      *p = '\n';
      return p + 1;
    });
  }
  std::string material = fmt::format(
      "# revolve material\nnewmtl {}\nKa 0 0 0\nKs 0 0 0\nd 1\nillum 1\n", kMaterialName);
  material += textured ? fmt::format("Kd 1 1 1\nmap_Kd {}\n", png_path.filename().string())
                       : std::string("Kd 0.8 0.8 0.8\n");
  mtl->Append(material);
  return {};
}

namespace {

// The vertices as glTF sees them where the mesh is textured: one per (vertex, uv) pair a face
// corner uses, numbered in the order of first use.
struct GlbSplit {
  std::vector<int> source;             // glTF vertex -> mesh vertex
  std::vector<int> uv_of;              // glTF vertex -> uv index
  std::vector<std::uint32_t> indices;  // per face corner: its glTF vertex
};
GlbSplit SplitByUv(const Mesh& mesh) {
  GlbSplit out;
  std::vector<int>& source = out.source;
  out.indices.resize(mesh.faces.size() * 3);
  // Per uv: its first glTF vertex (-1: none yet) and that one's mesh vertex, side by side (one
  // load for the common case, a uv used with one vertex only).
  struct First {
    int index = -1;
    int vertex = -1;
  };
  std::vector<First> first(mesh.uvs.size());
  source.reserve(mesh.uvs.size());
  out.uv_of.reserve(mesh.uvs.size());
  std::unordered_map<std::uint64_t, int> others;
  for (std::size_t i = 0; i < mesh.faces.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const int v = mesh.faces[i][c];
      const int t = mesh.uv_faces[i][c];
      First& slot = first[t];
      int index = slot.index;
      if (index < 0 || slot.vertex != v) {
        const std::uint64_t key = (std::uint64_t(std::uint32_t(v)) << 32) | std::uint32_t(t);
        if (index >= 0) {
          const auto it = others.find(key);
          index = it == others.end() ? -1 : it->second;
        }
        if (index < 0) {
          index = static_cast<int>(source.size());
          source.push_back(v);
          out.uv_of.push_back(t);
          if (slot.index < 0) {
            slot = First{index, v};
          } else {
            others.emplace(key, index);
          }
        }
      }
      out.indices[3 * i + static_cast<std::size_t>(c)] = static_cast<std::uint32_t>(index);
    }
  }
  return out;
}

// The binary chunk's layout (views 4-byte aligned), known before any of it is written: for n
// vertices, positions, normals, then uvs (textured) or colours (coloured), the indices and the
// texture's PNG (textured).
struct GlbLayout {
  struct View {
    std::size_t offset, length;
    int target;  // 0: none
  };
  std::vector<View> views;
  std::size_t bin_size = 0;
  int position_view = -1, normal_view = -1, extra_view = -1, index_view = -1, image_view = -1;

  GlbLayout(std::size_t n, std::size_t index_count, bool textured, bool colors,
            std::size_t png_size) {
    position_view = Add(n * 12, 34962);
    normal_view = Add(n * 12, 34962);
    if (textured) {
      extra_view = Add(n * 8, 34962);
    } else if (colors) {
      extra_view = Add(n * 4, 34962);
    }
    index_view = Add(index_count * 4, 34963);
    image_view = textured ? Add(png_size, 0) : -1;
  }
  int Add(std::size_t length, int target) {
    views.push_back({bin_size, length, target});
    bin_size += (length + 3) / 4 * 4;
    return static_cast<int>(views.size() - 1);
  }
};

// The JSON chunk (padded with spaces to 4 bytes) for a mesh of n glTF vertices (positions in
// [lo, hi]) and index_count indices laid out as `layout` says.
std::string GlbJson(const Mesh& mesh, const GlbLayout& layout, std::size_t n,
                    std::size_t index_count, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi,
                    bool textured, bool colors) {
  std::string json = R"({"asset":{"version":"2.0","generator":"revolve"},"scene":0,)";
  if (mesh.faces.empty()) {
    json += R"("scenes":[{}]})";
    Pad4(&json, ' ');
    return json;
  }
  json +=
      R"("scenes":[{"nodes":[0]}],"nodes":[{"name":"model","mesh":0,)"
      R"("rotation":[-0.7071067811865476,0,0,0.7071067811865476],"scale":[0.001,0.001,0.001]}],)";
  json += R"("meshes":[{"name":"model","primitives":[{"attributes":{"POSITION":0,"NORMAL":1)";
  if (textured) {
    json += R"(,"TEXCOORD_0":2)";
  } else if (colors) {
    json += R"(,"COLOR_0":2)";
  }
  json += fmt::format(R"(}},"indices":{},"material":0,"mode":4}}]}}],)",
                      layout.extra_view >= 0 ? 3 : 2);
  json += fmt::format(R"("materials":[{{"name":"{}","pbrMetallicRoughness":{{)", kMaterialName);
  json += textured ? R"("baseColorTexture":{"index":0},)"
                   : (colors ? "" : R"("baseColorFactor":[0.8,0.8,0.8,1],)");
  json += R"("metallicFactor":0,"roughnessFactor":1}}],)";
  if (textured) {
    json += fmt::format(
        R"("textures":[{{"sampler":0,"source":0}}],)"
        R"("samplers":[{{"magFilter":9729,"minFilter":9729,"wrapS":33071,"wrapT":33071}}],)"
        R"("images":[{{"bufferView":{},"mimeType":"image/png"}}],)",
        layout.image_view);
  }
  json += R"("accessors":[)";
  json += fmt::format(R"({{"bufferView":{},"componentType":5126,"count":{},"type":"VEC3","min":[)",
                      layout.position_view, n);
  for (int k = 0; k < 3; ++k) {
    if (k > 0) json += ',';
    AppendExact(&json, lo[k]);
  }
  json += R"(],"max":[)";
  for (int k = 0; k < 3; ++k) {
    if (k > 0) json += ',';
    AppendExact(&json, hi[k]);
  }
  json += "]},";
  json += fmt::format(R"({{"bufferView":{},"componentType":5126,"count":{},"type":"VEC3"}},)",
                      layout.normal_view, n);
  if (textured) {
    json += fmt::format(R"({{"bufferView":{},"componentType":5126,"count":{},"type":"VEC2"}},)",
                        layout.extra_view, n);
  } else if (colors) {
    json += fmt::format(
        R"({{"bufferView":{},"componentType":5121,"normalized":true,"count":{},"type":"VEC4"}},)",
        layout.extra_view, n);
  }
  json += fmt::format(R"({{"bufferView":{},"componentType":5125,"count":{},"type":"SCALAR"}}],)",
                      layout.index_view, index_count);
  json += R"("bufferViews":[)";
  for (std::size_t i = 0; i < layout.views.size(); ++i) {
    if (i > 0) json += ',';
    json += fmt::format(R"({{"buffer":0,"byteOffset":{},"byteLength":{})", layout.views[i].offset,
                        layout.views[i].length);
    if (layout.views[i].target != 0) json += fmt::format(R"(,"target":{})", layout.views[i].target);
    json += '}';
  }
  json += fmt::format(R"(],"buffers":[{{"byteLength":{}}}]}})", layout.bin_size);
  Pad4(&json, ' ');
  return json;
}

// The GLB header, the JSON chunk and the binary chunk's header (when bin_size > 0).
std::string GlbHead(const std::string& json, std::size_t bin_size) {
  const bool has_bin = bin_size > 0;
  std::string header;
  auto add_word = [&header](std::uint32_t word) {
    header.append(reinterpret_cast<const char*>(&word), 4);
  };
  add_word(0x46546C67);  // "glTF"
  add_word(2);
  add_word(static_cast<std::uint32_t>(12 + 8 + json.size() + (has_bin ? 8 + bin_size : 0)));
  add_word(static_cast<std::uint32_t>(json.size()));
  add_word(0x4E4F534A);  // "JSON"
  header += json;
  if (has_bin) {
    add_word(static_cast<std::uint32_t>(bin_size));
    add_word(0x004E4942);  // "BIN\0"
  }
  return header;
}

// Bytes [from, from + n) of `count` items of kItemBytes each, item i made by put(i, out), at
// `out` (items cut by the range's ends made aside).
template <std::size_t kItemBytes, class Put>
void ItemBytes(std::size_t from, std::size_t n, const Put& put, char* out) {
  std::size_t i = from / kItemBytes;
  std::size_t skip = from % kItemBytes;
  while (n > 0) {
    if (skip == 0 && n >= kItemBytes) {
      put(i++, out);
      out += kItemBytes;
      n -= kItemBytes;
      continue;
    }
    char item[kItemBytes];
    put(i++, item);
    const std::size_t take = std::min(kItemBytes - skip, n);
    std::memcpy(out, item + skip, take);
    out += take;
    n -= take;
    skip = 0;
  }
}

// The textured glTF's binary chunk but the PNG, as AtomicFile::FillBytes: its vertices'
// positions, normals and uvs, then the indices (each view's length a multiple of 4: no padding
// between them).
class GlbBulk {
 public:
  GlbBulk(const Mesh& mesh, const GlbSplit& split, const std::vector<Eigen::Vector3f>& normals)
      : mesh_(mesh), split_(split), normals_(normals), n_(split.source.size()) {}
  std::size_t size() const { return n_ * 32 + split_.indices.size() * 4; }
  void operator()(char* out, std::size_t from, std::size_t n) const {
    // Each part's share of [from, from + n): fn(offset in the part, bytes, where they go).
    const auto part = [&](std::size_t begin, std::size_t length, const auto& fn) {
      const std::size_t lo = std::max(from, begin);
      const std::size_t hi = std::min(from + n, begin + length);
      if (lo < hi) fn(lo - begin, hi - lo, out + (lo - from));
    };
    part(0, n_ * 12, [this](std::size_t at, std::size_t bytes, char* to) {
      ItemBytes<12>(
          at, bytes,
          [this](std::size_t i, char* p) {
            std::memcpy(p, mesh_.vertices[split_.source[i]].data(), 12);
          },
          to);
    });
    part(n_ * 12, n_ * 12, [this](std::size_t at, std::size_t bytes, char* to) {
      ItemBytes<12>(
          at, bytes,
          [this](std::size_t i, char* p) { std::memcpy(p, normals_[split_.source[i]].data(), 12); },
          to);
    });
    part(n_ * 24, n_ * 8, [this](std::size_t at, std::size_t bytes, char* to) {
      ItemBytes<8>(
          at, bytes,
          [this](std::size_t i, char* p) { std::memcpy(p, mesh_.uvs[split_.uv_of[i]].data(), 8); },
          to);
    });
    part(n_ * 32, split_.indices.size() * 4, [this](std::size_t at, std::size_t bytes, char* to) {
      std::memcpy(to, reinterpret_cast<const char*>(split_.indices.data()) + at, bytes);
    });
  }

 private:
  const Mesh& mesh_;
  const GlbSplit& split_;
  const std::vector<Eigen::Vector3f>& normals_;
  std::size_t n_;
};

// The textured glTF: the PNG may still be being encoded, and the head (the JSON) holds its size,
// but the head's length depends only on how many digits that size and the buffer's have. So the
// bulk (GlbBulk) is written first (AtomicFile::WriteAt) where it lies if the PNG is
// `png_size_guess` bytes, and on its way to the disk while the PNG is made; then the head and the
// PNG. Where the guess put it elsewhere, the bulk is written again at its place (the file's
// bytes are the same either way: a head shorter than guessed leaves bytes of the first bulk past
// the second only within the few bytes of the difference, which the PNG, at least 57 bytes,
// covers).
Expected<void> PutTexturedGlb(const Mesh& mesh, const GlbSplit& split,
                              const std::vector<Eigen::Vector3f>& normals,
                              const PngSource& png_source, std::size_t png_size_guess,
                              AtomicFile* file) {
  const std::size_t n = split.source.size();
  const std::size_t index_count = 3 * mesh.faces.size();
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
  Eigen::Vector3f hi = -lo;
  for (const int v : split.source) {
    lo = lo.cwiseMin(mesh.vertices[v]);
    hi = hi.cwiseMax(mesh.vertices[v]);
  }
  const auto head_for = [&](std::size_t png_size) {
    const GlbLayout layout(n, index_count, true, false, png_size);
    return GlbHead(GlbJson(mesh, layout, n, index_count, lo, hi, true, false), layout.bin_size);
  };
  const GlbBulk bulk(mesh, split, normals);
  const std::size_t bulk_size = bulk.size();
  const std::size_t guessed_at = head_for(png_size_guess).size();
  file->WriteAt(guessed_at, bulk_size, bulk);
  const std::string* png = png_source();
  if (png == nullptr) {
    return MakeError(ErrorCode::kInternal,
                     fmt::format("{}: the texture could not be encoded", file->path().string()));
  }
  const std::string head = head_for(png->size());
  file->WriteAt(0, head);
  if (head.size() != guessed_at) file->WriteAt(head.size(), bulk_size, bulk);
  file->WriteAt(head.size() + bulk_size, *png);
  file->WriteAt(head.size() + bulk_size + png->size(),
                std::string_view("\0\0\0", (4 - png->size() % 4) % 4));
  return {};
}

}  // namespace

Expected<void> PutGlb(const Mesh& mesh, const StageGate& gate, const PngSource& png_source,
                      AtomicFile* file, std::size_t png_size_guess) {
  const fs::path& path = file->path();
  // The uvs (or the news that there are none), and with them the normals and colours.
  const std::optional<MeshStage> reached = gate.Wait(MeshStage::kUvs);
  if (!reached) return std::unexpected(AbandonedFile(path));
  const bool textured = TexturedAt(mesh, *reached);
  const bool colors = !textured && mesh.HasColors();
  // The mesh's own normals (TextureMesh's) where it has them: the same values.
  std::vector<Eigen::Vector3f> computed_normals;
  if (!mesh.HasNormals()) computed_normals = VertexNormals(mesh);
  const std::vector<Eigen::Vector3f>& vertex_normals =
      mesh.HasNormals() ? mesh.normals : computed_normals;
  if (textured) {
    return PutTexturedGlb(mesh, SplitByUv(mesh), vertex_normals, png_source, png_size_guess, file);
  }

  // The mesh's own vertices, written straight from its arrays.
  const std::size_t n = mesh.vertices.size();
  const std::size_t index_count = 3 * mesh.faces.size();
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
  Eigen::Vector3f hi = -lo;
  for (const Eigen::Vector3f& p : mesh.vertices) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const GlbLayout layout(n, index_count, false, colors, 0);
  const std::string json = GlbJson(mesh, layout, n, index_count, lo, hi, false, colors);
  file->Append(GlbHead(json, layout.bin_size));
  if (layout.bin_size > 0) {
    file->Append(BytesOf(mesh.vertices));
    file->Append(BytesOf(vertex_normals));
    if (colors) {
      file->PutEach(n, 4, [&mesh](char* p, std::size_t i) {
        std::memcpy(p, mesh.colors[i].data(), 3);
        p[3] = static_cast<char>(255);
        return p + 4;
      });
    }
    file->Append(BytesOf(mesh.faces));  // non-negative int indices: their unsigned int bytes
  }
  return {};
}

}  // namespace internal

namespace {

// Opens `path`'s temporary file, fills it with `put` and commits it.
template <class Put>
Expected<void> WriteFile(const fs::path& path, Put put) {
  AtomicFile file(path);
  if (Expected<void> opened = file.Open(); !opened) return opened;
  if (Expected<void> filled = put(&file); !filled) return filled;
  return file.Commit();
}

const internal::StageGate& FinishedMesh() {
  static const internal::StageGate gate(MeshStage::kDone);
  return gate;
}

}  // namespace

Expected<void> WriteObj(const Mesh& mesh, const fs::path& path) {
  if (mesh.HasTexture()) {
    Expected<std::string> png = EncodePng(mesh.texture);
    if (!png) return std::unexpected(png.error());
    Expected<void> written = WriteFileAtomically(fs::path(path).replace_extension(".png"), *png);
    if (!written) return written;
  }
  AtomicFile mtl(fs::path(path).replace_extension(".mtl"));
  if (Expected<void> opened = mtl.Open(); !opened) return opened;
  AtomicFile obj(path);
  if (Expected<void> opened = obj.Open(); !opened) return opened;
  if (Expected<void> put = internal::PutObj(mesh, FinishedMesh(), &obj, &mtl); !put) return put;
  if (Expected<void> committed = mtl.Commit(); !committed) return committed;
  return obj.Commit();
}

Expected<void> WriteGlb(const Mesh& mesh, const fs::path& path) {
  std::string png;
  if (mesh.HasTexture()) {
    Expected<std::string> encoded = EncodePng(mesh.texture);
    if (!encoded) return std::unexpected(encoded.error());
    png = std::move(*encoded);
  }
  return WriteFile(path, [&](AtomicFile* file) {
    return internal::PutGlb(
        mesh, FinishedMesh(), [&png] { return &png; }, file);
  });
}

std::size_t GlbVertexCount(const Mesh& mesh) {
  if (!mesh.HasTexture()) {
    return mesh.vertices.size();
  }
  std::vector<std::uint64_t> pairs;
  pairs.reserve(mesh.faces.size() * 3);
  for (std::size_t i = 0; i < mesh.faces.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      pairs.push_back((std::uint64_t(std::uint32_t(mesh.faces[i][c])) << 32) |
                      std::uint32_t(mesh.uv_faces[i][c]));
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return static_cast<std::size_t>(std::unique(pairs.begin(), pairs.end()) - pairs.begin());
}

Expected<void> internal::PutStl(const Mesh& mesh, const StageGate& gate, AtomicFile* file) {
  if (!gate.Wait(MeshStage::kSurface)) return std::unexpected(AbandonedFile(file->path()));
  std::string header = "revolve binary STL: object frame, millimetres, z up";
  header.resize(80, ' ');
  const auto count = static_cast<std::uint32_t>(mesh.faces.size());
  header.append(reinterpret_cast<const char*>(&count), 4);
  file->Append(header);
  file->PutEach(mesh.faces.size(), 50, [&mesh](char* p, std::size_t i) {
    const Eigen::Vector3i& f = mesh.faces[i];
    const Eigen::Vector3f normal = FaceNormal(mesh, f);
    std::memcpy(p, normal.data(), 12);
    for (int c = 0; c < 3; ++c) {
      std::memcpy(p + 12 + std::ptrdiff_t{12} * c, mesh.vertices[f[c]].data(), 12);
    }
    p[48] = 0;  // attribute byte count
    p[49] = 0;
    return p + 50;
  });
  return {};
}

Expected<void> WriteStl(const Mesh& mesh, const fs::path& path) {
  return WriteFile(path,
                   [&](AtomicFile* file) { return internal::PutStl(mesh, FinishedMesh(), file); });
}

Expected<Mesh> ReadStl(const fs::path& path) {
  Expected<std::string> content = ReadWholeFile(path);
  if (!content) {
    return std::unexpected(content.error());
  }
  const std::string& bytes = *content;
  if (bytes.size() < 84) {
    return std::unexpected(BadFile(path, "too short for a binary STL"));
  }
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  if (bytes.size() != 84 + std::size_t{count} * 50) {
    return std::unexpected(
        BadFile(path, fmt::format("binary STL of {} triangles must be {} bytes, not {}", count,
                                  84 + std::size_t{count} * 50, bytes.size())));
  }
  Mesh mesh;
  mesh.vertices.reserve(std::size_t{count} * 3);
  mesh.faces.reserve(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    const char* record = bytes.data() + 84 + std::size_t{i} * 50;
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3f v;
      std::memcpy(v.data(), record + 12 + std::ptrdiff_t{12} * c, 12);
      mesh.vertices.push_back(v);
    }
    const int base = static_cast<int>(3 * i);
    mesh.faces.emplace_back(base, base + 1, base + 2);
  }
  return mesh;
}

Expected<Mesh> ReadObj(const fs::path& path) {
  Expected<std::string> content = ReadWholeFile(path);
  if (!content) {
    return std::unexpected(content.error());
  }
  Mesh mesh;
  std::vector<Eigen::Vector3f> colors;
  std::string_view text = *content;
  int line_number = 0;
  std::vector<int> polygon;
  std::vector<int> uv_polygon;
  auto bad = [&](std::string_view what) {
    return std::unexpected(BadFile(path, fmt::format("line {}: {}", line_number, what)));
  };
  while (!text.empty()) {
    const std::size_t end = std::min(text.find('\n'), text.size());
    std::string_view line = text.substr(0, end);
    text.remove_prefix(std::min(end + 1, text.size()));
    ++line_number;
    auto next_word = [&line]() {
      while (!line.empty() &&
             (line.front() == ' ' || line.front() == '\t' || line.front() == '\r')) {
        line.remove_prefix(1);
      }
      std::size_t n = 0;
      while (n < line.size() && line[n] != ' ' && line[n] != '\t' && line[n] != '\r') {
        ++n;
      }
      const std::string_view word = line.substr(0, n);
      line.remove_prefix(n);
      return word;
    };
    auto read_floats = [&](float* out, int count) {
      for (int i = 0; i < count; ++i) {
        const std::string_view w = next_word();
        if (w.empty() || std::from_chars(w.data(), w.data() + w.size(), out[i]).ec != std::errc()) {
          return i;
        }
      }
      return count;
    };
    const std::string_view keyword = next_word();
    if (keyword == "v") {
      float values[6];
      const int got = read_floats(values, 6);
      if (got < 3) {
        return bad("a vertex needs x y z");
      }
      mesh.vertices.emplace_back(values[0], values[1], values[2]);
      if (got == 6) {
        colors.emplace_back(values[3], values[4], values[5]);
      }
    } else if (keyword == "vt") {
      float values[2];
      if (read_floats(values, 2) < 2) {
        return bad("a texture coordinate needs u v");
      }
      mesh.uvs.emplace_back(values[0], 1.0f - values[1]);
    } else if (keyword == "f") {
      polygon.clear();
      uv_polygon.clear();
      for (std::string_view corner = next_word(); !corner.empty(); corner = next_word()) {
        int indices[2] = {0, 0};
        for (int part = 0; part < 2 && !corner.empty(); ++part) {
          const std::size_t slash = std::min(corner.find('/'), corner.size());
          const std::string_view number = corner.substr(0, slash);
          if (!number.empty() &&
              std::from_chars(number.data(), number.data() + number.size(), indices[part]).ec !=
                  std::errc()) {
            return bad("malformed face corner");
          }
          corner.remove_prefix(std::min(slash + 1, corner.size()));
        }
        const int count[2] = {static_cast<int>(mesh.vertices.size()),
                              static_cast<int>(mesh.uvs.size())};
        for (int part = 0; part < 2; ++part) {
          indices[part] = indices[part] < 0 ? count[part] + indices[part] : indices[part] - 1;
        }
        if (indices[0] < 0 || indices[0] >= count[0]) {
          return bad("face vertex index out of range");
        }
        polygon.push_back(indices[0]);
        if (indices[1] >= 0 && indices[1] < count[1]) {
          uv_polygon.push_back(indices[1]);
        }
      }
      if (polygon.size() < 3) {
        return bad("a face needs 3 corners");
      }
      const bool with_uv = uv_polygon.size() == polygon.size();
      for (std::size_t i = 1; i + 1 < polygon.size(); ++i) {
        mesh.faces.emplace_back(polygon[0], polygon[i], polygon[i + 1]);
        if (with_uv) {
          mesh.uv_faces.emplace_back(uv_polygon[0], uv_polygon[i], uv_polygon[i + 1]);
        }
      }
    }
  }
  if (mesh.uv_faces.size() != mesh.faces.size()) {
    mesh.uv_faces.clear();
  }
  if (colors.size() == mesh.vertices.size()) {
    for (const Eigen::Vector3f& c : colors) {
      mesh.colors.emplace_back(
          static_cast<std::uint8_t>(std::clamp(std::lround(c.x() * 255.0f), 0L, 255L)),
          static_cast<std::uint8_t>(std::clamp(std::lround(c.y() * 255.0f), 0L, 255L)),
          static_cast<std::uint8_t>(std::clamp(std::lround(c.z() * 255.0f), 0L, 255L)));
    }
  }
  return mesh;
}

}  // namespace revolve::reconstruct
