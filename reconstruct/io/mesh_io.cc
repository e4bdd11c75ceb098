#include "reconstruct/io/mesh_io.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include <fmt/format.h>

#include "reconstruct/io/model_writer.h"
#include "reconstruct/io/writer_support.h"

namespace revolve::reconstruct {
namespace {

namespace fs = std::filesystem;

static_assert(std::endian::native == std::endian::little,
              "the PLY writer and reader assume a little-endian host");

using internal::BadFile;

// Validates face indices and appends fan triangles of `polygon`.
bool AddPolygon(const std::vector<int>& polygon, std::size_t vertex_count, Mesh* mesh) {
  if (polygon.size() < 3) {
    return false;
  }
  for (int index : polygon) {
    if (index < 0 || static_cast<std::size_t>(index) >= vertex_count) {
      return false;
    }
  }
  for (std::size_t i = 1; i + 1 < polygon.size(); ++i) {
    mesh->faces.emplace_back(polygon[0], polygon[i], polygon[i + 1]);
  }
  return true;
}

// ------------------------------------------------------------------------------------ PLY read

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

std::optional<PlyType> ParsePlyType(std::string_view name) {
  static const std::map<std::string, PlyType, std::less<>> kTypes = {
      {"char", PlyType::kInt8},      {"int8", PlyType::kInt8},       {"uchar", PlyType::kUint8},
      {"uint8", PlyType::kUint8},    {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUint16},  {"uint16", PlyType::kUint16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},    {"uint", PlyType::kUint32},     {"uint32", PlyType::kUint32},
      {"float", PlyType::kFloat32},  {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64}};
  const auto it = kTypes.find(name);
  if (it == kTypes.end()) {
    return std::nullopt;
  }
  return it->second;
}

std::size_t PlyTypeSize(PlyType type) {
  switch (type) {
    case PlyType::kInt8:
    case PlyType::kUint8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUint16:
      return 2;
    case PlyType::kInt32:
    case PlyType::kUint32:
    case PlyType::kFloat32:
      return 4;
    case PlyType::kFloat64:
      return 8;
  }
  return 0;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;
  bool is_list = false;
  PlyType count_type = PlyType::kUint8;
};

struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> properties;
};

// Reads values one at a time from the body of a PLY file, binary or ASCII.
class PlyBodyReader {
 public:
  PlyBodyReader(std::string_view body, bool ascii) : body_(body), ascii_(ascii) {}

  bool Read(PlyType type, double* value) {
    if (ascii_) {
      return ReadAscii(value);
    }
    const std::size_t size = PlyTypeSize(type);
    if (pos_ + size > body_.size()) {
      return false;
    }
    const char* p = body_.data() + pos_;
    pos_ += size;
    switch (type) {
      case PlyType::kInt8:
        *value = Load<std::int8_t>(p);
        break;
      case PlyType::kUint8:
        *value = Load<std::uint8_t>(p);
        break;
      case PlyType::kInt16:
        *value = Load<std::int16_t>(p);
        break;
      case PlyType::kUint16:
        *value = Load<std::uint16_t>(p);
        break;
      case PlyType::kInt32:
        *value = Load<std::int32_t>(p);
        break;
      case PlyType::kUint32:
        *value = Load<std::uint32_t>(p);
        break;
      case PlyType::kFloat32:
        *value = Load<float>(p);
        break;
      case PlyType::kFloat64:
        *value = Load<double>(p);
        break;
    }
    return true;
  }

 private:
  template <class T>
  static double Load(const char* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return static_cast<double>(v);
  }

  bool ReadAscii(double* value) {
    while (pos_ < body_.size() && std::isspace(static_cast<unsigned char>(body_[pos_]))) {
      ++pos_;
    }
    if (pos_ >= body_.size()) {
      return false;
    }
    const char* begin = body_.data() + pos_;
    const auto result = std::from_chars(begin, body_.data() + body_.size(), *value);
    if (result.ec != std::errc()) {
      return false;
    }
    pos_ += static_cast<std::size_t>(result.ptr - begin);
    return true;
  }

  std::string_view body_;
  bool ascii_;
  std::size_t pos_ = 0;
};

// ----------------------------------------------------------------------------------- VRML read

// Tokens of a VRML file: words and numbers, with '[', ']', '{', '}' as their own tokens; commas
// and comments are whitespace.
std::vector<std::string_view> TokenizeVrml(std::string_view text) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < text.size()) {
    const char c = text[i];
    if (c == '#') {
      while (i < text.size() && text[i] != '\n') {
        ++i;
      }
    } else if (std::isspace(static_cast<unsigned char>(c)) || c == ',') {
      ++i;
    } else if (c == '[' || c == ']' || c == '{' || c == '}') {
      tokens.push_back(text.substr(i, 1));
      ++i;
    } else if (c == '"') {
      std::size_t j = i + 1;
      while (j < text.size() && text[j] != '"') {
        j += text[j] == '\\' ? 2 : 1;
      }
      j = std::min(j + 1, text.size());
      tokens.push_back(text.substr(i, j - i));
      i = j;
    } else {
      std::size_t j = i;
      while (j < text.size() && !std::isspace(static_cast<unsigned char>(text[j])) &&
             text[j] != ',' && text[j] != '[' && text[j] != ']' && text[j] != '{' &&
             text[j] != '}' && text[j] != '#') {
        ++j;
      }
      tokens.push_back(text.substr(i, j - i));
      i = j;
    }
  }
  return tokens;
}

// Numbers from tokens[*pos] (just past a '[') up to the matching ']'.
template <class T>
bool ReadNumberList(const std::vector<std::string_view>& tokens, std::size_t* pos,
                    std::vector<T>* out) {
  for (; *pos < tokens.size(); ++*pos) {
    const std::string_view t = tokens[*pos];
    if (t == "]") {
      ++*pos;
      return true;
    }
    T value{};
    const auto result = std::from_chars(t.data(), t.data() + t.size(), value);
    if (result.ec != std::errc() || result.ptr != t.data() + t.size()) {
      return false;
    }
    out->push_back(value);
  }
  return false;
}

// Finds `field` '[' after tokens[from] and reads its numbers; false when the field is absent.
template <class T>
Expected<bool> ReadField(const std::vector<std::string_view>& tokens, std::size_t from,
                         std::string_view field, const fs::path& path, std::vector<T>* out) {
  for (std::size_t i = from; i + 1 < tokens.size(); ++i) {
    if (tokens[i] != field || tokens[i + 1] != "[") {
      continue;
    }
    std::size_t pos = i + 2;
    if (!ReadNumberList(tokens, &pos, out)) {
      return std::unexpected(BadFile(path, fmt::format("malformed {} list", field)));
    }
    return true;
  }
  return false;
}

std::size_t FindToken(const std::vector<std::string_view>& tokens, std::string_view token,
                      std::size_t from = 0) {
  for (std::size_t i = from; i < tokens.size(); ++i) {
    if (tokens[i] == token) {
      return i;
    }
  }
  return tokens.size();
}

std::uint8_t ToByte(double channel01) {
  return static_cast<std::uint8_t>(std::clamp(std::lround(channel01 * 255.0), 0L, 255L));
}

}  // namespace

Expected<void> internal::PutPly(const Mesh& mesh, const StageGate& gate, AtomicFile* file) {
  if (!gate.Wait(MeshStage::kColors)) return std::unexpected(AbandonedFile(file->path()));
  const bool colors = mesh.HasColors();
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment revolve: object frame, mm\n";
  header += fmt::format("element vertex {}\n", mesh.vertices.size());
  header += "property float x\nproperty float y\nproperty float z\n";
  if (colors) {
    header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  }
  header += fmt::format("element face {}\n", mesh.faces.size());
  header += "property list uchar int vertex_indices\nend_header\n";
  file->Append(header);
  if (colors) {
    file->PutEach(mesh.vertices.size(), 15, [&mesh](char* p, std::size_t i) {
      std::memcpy(p, mesh.vertices[i].data(), 12);
      std::memcpy(p + 12, mesh.colors[i].data(), 3);
      return p + 15;
    });
  } else {
    file->PutEach(mesh.vertices.size(), 12, [&mesh](char* p, std::size_t i) {
      std::memcpy(p, mesh.vertices[i].data(), 12);
      return p + 12;
    });
  }
  static_assert(sizeof(Eigen::Vector3i) == 12, "three packed int32 indices");
  file->PutEach(mesh.faces.size(), 13, [&mesh](char* p, std::size_t i) {
    *p = 3;
    std::memcpy(p + 1, mesh.faces[i].data(), 12);
    return p + 13;
  });
  return {};
}

Expected<void> internal::PutVrml(const Mesh& mesh, const StageGate& gate, AtomicFile* file,
                                 VertexTexts* texts) {
  if (!gate.Wait(MeshStage::kSurface)) return std::unexpected(AbandonedFile(file->path()));
  std::string text =
      "#VRML V2.0 utf8\n"
      "# revolve model. Points are object-frame millimetres (z up); the Transform shows them\n"
      "# upright (y up) in metres.\n"
      "NavigationInfo {\n  type [ \"EXAMINE\", \"ANY\" ]\n}\n"
      "Transform {\n"
      "  scale 0.001 0.001 0.001\n"
      "  rotation 1 0 0 -1.5707963267948966\n"
      "  children [\n"
      "Shape {\n"
      "  appearance Appearance {\n"
      "    material Material {\n"
      "      diffuseColor 0.8 0.8 0.8\n"
      "    }\n"
      "  }\n"
      "  geometry IndexedFaceSet {\n"
      "    solid TRUE\n"
      "    ccw TRUE\n"
      "    coord Coordinate {\n"
      "      point [\n";
  // One point, colour or triangle per line, not indented: the lists are most of the file->
  file->Append(text);
  constexpr std::size_t kMaxLine = 4 * internal::kMaxNumberChars;
  if (texts != nullptr) {
    const VertexTexts& points = texts->Of(mesh);
    file->PutEach(mesh.vertices.size(), kMaxLine, [&points](char* p, std::size_t i) {
      p = points.Write(p, i);
      std::copy_n(",\n", 2, p);
      return p + 2;
    });
  } else {
    file->PutEach(mesh.vertices.size(), kMaxLine, [&mesh](char* p, std::size_t i) {
      for (int k = 0; k < 3; ++k) {
        p = internal::WriteFixedN<4>(p, mesh.vertices[i][k]);
        *p++ = ' ';
      }
      p[-1] = ',';
      *p = '\n';
      return p + 1;
    });
  }
  file->Append("      ]\n    }\n");
  if (!gate.Wait(MeshStage::kColors)) return std::unexpected(AbandonedFile(file->path()));
  if (mesh.HasColors()) {
    file->Append("    colorPerVertex TRUE\n    color Color {\n      color [\n");
    // The channels' texts once per byte value: "c" for the first, " c" for the others.
    const std::array<std::uint64_t, 256> first = internal::ChannelTexts("");
    const std::array<std::uint64_t, 256> other = internal::ChannelTexts(" ");
    file->PutEach(mesh.colors.size(), kMaxLine, [&](char* p, std::size_t i) {
      const Color& c = mesh.colors[i];
      p = internal::WriteWordText(p, first[c[0]]);
      p = internal::WriteWordText(p, other[c[1]]);
      p = internal::WriteWordText(p, other[c[2]]);
      std::copy_n(",\n", 2, p);
      return p + 2;
    });
    file->Append("      ]\n    }\n");
  }
  file->Append("    coordIndex [\n");
  const internal::IndexTexts index(0, mesh.vertices.size());
  file->PutEach(mesh.faces.size(), kMaxLine, [&mesh, &index](char* p, std::size_t i) {
    for (int k = 0; k < 3; ++k) {
      p = index.Write(p, mesh.faces[i][k]);
      *p++ = ' ';
    }
    std::copy_n("-1,\n", 4, p);
    return p + 4;
  });
  file->Append("    ]\n  }\n}\n  ]\n}\n");
  return {};
}

namespace {

// Opens `path`'s temporary file, fills it with `put` from a finished mesh and commits it.
Expected<void> WriteFinished(const Mesh& mesh, const fs::path& path,
                             Expected<void> (*put)(const Mesh&, const internal::StageGate&,
                                                   AtomicFile*)) {
  static const internal::StageGate finished(MeshStage::kDone);
  AtomicFile file(path);
  if (Expected<void> opened = file.Open(); !opened) return opened;
  if (Expected<void> filled = put(mesh, finished, &file); !filled) return filled;
  return file.Commit();
}

}  // namespace

Expected<void> WritePly(const Mesh& mesh, const fs::path& path) {
  return WriteFinished(mesh, path, internal::PutPly);
}

Expected<void> WriteVrml(const Mesh& mesh, const fs::path& path) {
  return WriteFinished(mesh, path,
                       [](const Mesh& m, const internal::StageGate& gate, AtomicFile* file) {
                         return internal::PutVrml(m, gate, file);
                       });
}

bool IsModelFormat(std::string_view format) {
  return std::find(std::begin(kModelFormats), std::end(kModelFormats), format) !=
         std::end(kModelFormats);
}

Expected<std::vector<fs::path>> WriteModel(const Mesh& mesh, const fs::path& dir,
                                           std::string_view basename,
                                           const std::vector<std::string>& formats) {
  Expected<std::unique_ptr<ModelWriter>> writer = ModelWriter::Start(mesh, dir, basename, formats);
  if (!writer) return std::unexpected(writer.error());
  return (*writer)->Finish();
}

Expected<Mesh> ReadPly(const fs::path& path) {
  Expected<std::string> content = ReadWholeFile(path);
  if (!content) {
    return std::unexpected(content.error());
  }
  const std::string_view text = *content;
  const std::size_t header_end = text.find("end_header");
  if (!text.starts_with("ply") || header_end == std::string_view::npos) {
    return std::unexpected(BadFile(path, "not a PLY file (no \"ply\" magic or no end_header)"));
  }
  std::size_t body_start = text.find('\n', header_end);
  if (body_start == std::string_view::npos) {
    return std::unexpected(BadFile(path, "no body"));
  }
  ++body_start;

  std::istringstream header{std::string(text.substr(0, header_end))};
  std::string line;
  std::vector<PlyElement> elements;
  bool ascii = false;
  bool have_format = false;
  while (std::getline(header, line)) {
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "format") {
      std::string format;
      words >> format;
      if (format == "ascii") {
        ascii = true;
      } else if (format != "binary_little_endian") {
        return std::unexpected(BadFile(path, fmt::format("unsupported PLY format \"{}\"", format)));
      }
      have_format = true;
    } else if (keyword == "element") {
      PlyElement element;
      words >> element.name >> element.count;
      if (!words) {
        return std::unexpected(BadFile(path, "malformed element line: " + line));
      }
      elements.push_back(element);
    } else if (keyword == "property") {
      if (elements.empty()) {
        return std::unexpected(BadFile(path, "property before element"));
      }
      PlyProperty property;
      std::string type;
      words >> type;
      if (type == "list") {
        std::string count_type;
        words >> count_type >> type;
        const auto ct = ParsePlyType(count_type);
        if (!ct) {
          return std::unexpected(BadFile(path, "unknown PLY type in: " + line));
        }
        property.is_list = true;
        property.count_type = *ct;
      }
      const auto t = ParsePlyType(type);
      words >> property.name;
      if (!t || !words) {
        return std::unexpected(BadFile(path, "malformed property: " + line));
      }
      property.type = *t;
      elements.back().properties.push_back(property);
    }
  }
  if (!have_format) {
    return std::unexpected(BadFile(path, "no format line"));
  }

  Mesh mesh;
  PlyBodyReader body(text.substr(body_start), ascii);
  for (const PlyElement& element : elements) {
    const bool is_vertex = element.name == "vertex";
    const bool is_face = element.name == "face";
    int x = -1, y = -1, z = -1, r = -1, g = -1, b = -1, list = -1;
    for (std::size_t p = 0; p < element.properties.size(); ++p) {
      const std::string& n = element.properties[p].name;
      const int idx = static_cast<int>(p);
      if (n == "x") {
        x = idx;
      }
      if (n == "y") {
        y = idx;
      }
      if (n == "z") {
        z = idx;
      }
      if (n == "red") {
        r = idx;
      }
      if (n == "green") {
        g = idx;
      }
      if (n == "blue") {
        b = idx;
      }
      if ((n == "vertex_indices" || n == "vertex_index") && element.properties[p].is_list) {
        list = idx;
      }
    }
    if (is_vertex && (x < 0 || y < 0 || z < 0)) {
      return std::unexpected(BadFile(path, "vertex element lacks x, y or z"));
    }
    const bool has_color = is_vertex && r >= 0 && g >= 0 && b >= 0;
    if (is_face && list < 0) {
      return std::unexpected(BadFile(path, "face element lacks a vertex_indices list"));
    }
    std::vector<double> values(element.properties.size());
    std::vector<int> polygon;
    for (std::size_t i = 0; i < element.count; ++i) {
      for (std::size_t p = 0; p < element.properties.size(); ++p) {
        const PlyProperty& property = element.properties[p];
        if (!property.is_list) {
          if (!body.Read(property.type, &values[p])) {
            return std::unexpected(BadFile(path, "truncated or malformed body"));
          }
          continue;
        }
        double count = 0;
        if (!body.Read(property.count_type, &count) || count < 0) {
          return std::unexpected(BadFile(path, "truncated or malformed body"));
        }
        polygon.clear();
        for (int k = 0; k < static_cast<int>(count); ++k) {
          double v = 0;
          if (!body.Read(property.type, &v)) {
            return std::unexpected(BadFile(path, "truncated or malformed body"));
          }
          polygon.push_back(static_cast<int>(v));
        }
        if (is_face && static_cast<int>(p) == list &&
            !AddPolygon(polygon, mesh.vertices.size(), &mesh)) {
          return std::unexpected(
              BadFile(path, fmt::format("face {} has a bad vertex index or fewer than 3", i)));
        }
      }
      if (is_vertex) {
        mesh.vertices.emplace_back(static_cast<float>(values[x]), static_cast<float>(values[y]),
                                   static_cast<float>(values[z]));
        if (has_color) {
          mesh.colors.emplace_back(static_cast<std::uint8_t>(values[r]),
                                   static_cast<std::uint8_t>(values[g]),
                                   static_cast<std::uint8_t>(values[b]));
        }
      }
    }
  }
  return mesh;
}

Expected<Mesh> ReadVrml(const fs::path& path) {
  Expected<std::string> content = ReadWholeFile(path);
  if (!content) {
    return std::unexpected(content.error());
  }
  if (!std::string_view(*content).starts_with("#VRML V2.0")) {
    return std::unexpected(BadFile(path, "not a VRML 2.0 file (no \"#VRML V2.0\" header)"));
  }
  const std::vector<std::string_view> tokens = TokenizeVrml(*content);
  const std::size_t face_set = FindToken(tokens, "IndexedFaceSet");
  if (face_set == tokens.size()) {
    return std::unexpected(BadFile(path, "no IndexedFaceSet"));
  }
  const std::size_t coordinate = FindToken(tokens, "Coordinate", face_set);
  std::vector<float> points;
  Expected<bool> found = ReadField(tokens, coordinate, "point", path, &points);
  if (!found) {
    return std::unexpected(found.error());
  }
  if (coordinate == tokens.size() || !*found || points.size() % 3 != 0) {
    return std::unexpected(BadFile(path, "no Coordinate point list of x y z triples"));
  }
  Mesh mesh;
  for (std::size_t i = 0; i < points.size(); i += 3) {
    mesh.vertices.emplace_back(points[i], points[i + 1], points[i + 2]);
  }
  std::vector<int> indices;
  found = ReadField(tokens, face_set, "coordIndex", path, &indices);
  if (!found) {
    return std::unexpected(found.error());
  }
  if (!*found) {
    return std::unexpected(BadFile(path, "no coordIndex"));
  }
  std::vector<int> polygon;
  for (std::size_t i = 0; i <= indices.size(); ++i) {
    if (i == indices.size() || indices[i] == -1) {
      if (!polygon.empty() && !AddPolygon(polygon, mesh.vertices.size(), &mesh)) {
        return std::unexpected(BadFile(path, "coordIndex has a bad index or a short polygon"));
      }
      polygon.clear();
    } else {
      polygon.push_back(indices[i]);
    }
  }
  const std::size_t color_node = FindToken(tokens, "Color", face_set);
  if (color_node < tokens.size()) {
    std::vector<float> channels;
    found = ReadField(tokens, color_node, "color", path, &channels);
    if (!found) {
      return std::unexpected(found.error());
    }
    if (channels.size() != 3 * mesh.vertices.size()) {
      return std::unexpected(BadFile(path, "Color must hold one r g b triple per point"));
    }
    for (std::size_t i = 0; i < channels.size(); i += 3) {
      mesh.colors.emplace_back(ToByte(channels[i]), ToByte(channels[i + 1]),
                               ToByte(channels[i + 2]));
    }
  }
  return mesh;
}

}  // namespace revolve::reconstruct
