#include "reconstruct/meridian/meridian_vrml.h"

#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "base/atomic_file.h"
#include "base/image_codecs.h"

namespace revolve::reconstruct {
namespace {

constexpr int kJpegQuality = 92;

void WriteShape(std::string& out, const Mesh& mesh, int texture, const std::string& texture_url,
                bool define_coords, const std::string& coords_name) {
  out += "    Shape {\n      appearance Appearance {\n";
  out += "        material Material { diffuseColor 0.8 0.8 0.8 }\n";
  if (texture >= 0) {
    out += fmt::format("        texture ImageTexture {{ url \"{}\" }}\n", texture_url);
  }
  out += "      }\n      geometry IndexedFaceSet {\n        solid TRUE\n";
  if (define_coords) {
    out += fmt::format("        coord DEF {} Coordinate {{\n          point [\n", coords_name);
    for (const Eigen::Vector3f& p : mesh.vertices) {
      out += fmt::format("            {:.7g} {:.7g} {:.7g},\n", p.x(), p.y(), p.z());
    }
    out += "          ]\n        }\n";
  } else {
    out += fmt::format("        coord USE {}\n", coords_name);
  }
  out += "        coordIndex [\n";
  const bool textured = texture >= 0 && mesh.HasViewTexture();
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const int face_texture = mesh.HasViewTexture() ? mesh.view_texture.face_image[f] : -1;
    if (face_texture != texture) continue;
    const Eigen::Vector3i& face = mesh.faces[f];
    out += fmt::format("          {}, {}, {}, -1,\n", face[0], face[1], face[2]);
  }
  out += "        ]\n";
  if (textured) {
    // Only the texture coordinates this Shape uses, renumbered.
    std::vector<int> local(mesh.view_texture.uvs.size(), -1);
    std::vector<int> order;
    for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
      if (mesh.view_texture.face_image[f] != texture) continue;
      for (int k = 0; k < 3; ++k) {
        const int i = mesh.view_texture.uv_faces[f][k];
        if (local[static_cast<std::size_t>(i)] < 0) {
          local[static_cast<std::size_t>(i)] = static_cast<int>(order.size());
          order.push_back(i);
        }
      }
    }
    out += "        texCoord TextureCoordinate {\n          point [\n";
    for (const int i : order) {
      const Eigen::Vector2f& uv = mesh.view_texture.uvs[static_cast<std::size_t>(i)];
      out += fmt::format("            {:.6f} {:.6f},\n", uv.x(), uv.y());
    }
    out += "          ]\n        }\n        texCoordIndex [\n";
    for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
      if (mesh.view_texture.face_image[f] != texture) continue;
      const Eigen::Vector3i& t = mesh.view_texture.uv_faces[f];
      out +=
          fmt::format("          {}, {}, {}, -1,\n", local[static_cast<std::size_t>(t[0])],
                      local[static_cast<std::size_t>(t[1])], local[static_cast<std::size_t>(t[2])]);
    }
    out += "        ]\n";
  }
  out += "      }\n    }\n";
}

}  // namespace

Expected<std::vector<std::filesystem::path>> WriteTexturedVrml(const Mesh& mesh,
                                                               const std::filesystem::path& path,
                                                               double metres_per_unit) {
  std::vector<std::filesystem::path> written;
  const std::string stem = path.stem().string();
  std::vector<std::string> urls;
  if (mesh.HasViewTexture()) {
    for (std::size_t t = 0; t < mesh.view_texture.images.size(); ++t) {
      const std::string name = fmt::format("{}_tex{:02d}.jpg", stem, t);
      const std::filesystem::path image_path = path.parent_path() / name;
      if (Expected<void> w = WriteImageFile(image_path, mesh.view_texture.images[t],
                                            {cv::IMWRITE_JPEG_QUALITY, kJpegQuality});
          !w) {
        return std::unexpected(w.error());
      }
      written.push_back(image_path);
      urls.push_back(name);
    }
  }
  std::string out = "#VRML V2.0 utf8\n# revolve: meridian method (thesis 4.3), textured strips\n";
  out += fmt::format(
      "Transform {{\n  scale {0:.9g} {0:.9g} {0:.9g}\n  rotation 1 0 0 -1.5707963\n  children [\n",
      metres_per_unit);
  const std::string coords_name = "model_coords";
  bool defined = false;
  for (std::size_t t = 0; t < urls.size(); ++t) {
    WriteShape(out, mesh, static_cast<int>(t), urls[t], !defined, coords_name);
    defined = true;
  }
  const bool any_untextured =
      !mesh.HasViewTexture() ||
      std::find(mesh.view_texture.face_image.begin(), mesh.view_texture.face_image.end(), -1) !=
          mesh.view_texture.face_image.end();
  if (any_untextured) WriteShape(out, mesh, -1, "", !defined, coords_name);
  out += "  ]\n}\nNavigationInfo {\n  type \"EXAMINE\"\n}\n";
  if (Expected<void> w = WriteFileAtomically(path, std::string_view(out)); !w) {
    return std::unexpected(w.error());
  }
  written.push_back(path);
  return written;
}

Expected<std::vector<std::string>> ReadVrmlTextureUrls(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) {
    return MakeError(ErrorCode::kNotFound, fmt::format("{}: cannot be opened", path.string()));
  }
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  if (s.rfind("#VRML V2.0", 0) != 0) {
    return MakeError(ErrorCode::kBadInput, fmt::format("{}: not a VRML 2.0 file", path.string()));
  }
  std::vector<std::string> urls;
  std::size_t pos = 0;
  while ((pos = s.find("ImageTexture", pos)) != std::string::npos) {
    const std::size_t open = s.find('"', s.find("url", pos));
    const std::size_t close = s.find('"', open + 1);
    if (open == std::string::npos || close == std::string::npos) {
      return MakeError(ErrorCode::kBadInput,
                       fmt::format("{}: an ImageTexture without a url", path.string()));
    }
    urls.push_back(s.substr(open + 1, close - open - 1));
    pos = close;
  }
  return urls;
}

}  // namespace revolve::reconstruct
