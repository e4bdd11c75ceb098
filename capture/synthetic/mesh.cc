#include "capture/synthetic/mesh.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "base/atomic_file.h"

namespace revolve::capture {
namespace {

Error Bad(const std::filesystem::path& path, std::string what) {
  return Error{ErrorCode::kBadInput, fmt::format("{}: {}", path.string(), what)};
}

Expected<void> CheckIndices(const TriangleMesh& mesh, const std::filesystem::path& path) {
  const int n = static_cast<int>(mesh.vertices.size());
  for (const auto& t : mesh.triangles) {
    for (int i = 0; i < 3; ++i) {
      if (t[i] < 0 || t[i] >= n) {
        return std::unexpected(Bad(path, fmt::format("a face refers to vertex {} of {}", t[i], n)));
      }
    }
  }
  if (mesh.triangles.empty()) return std::unexpected(Bad(path, "the mesh has no faces"));
  return {};
}

Expected<TriangleMesh> ReadObj(const std::filesystem::path& path, std::istream& in) {
  TriangleMesh mesh;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    std::istringstream words(line);
    std::string tag;
    words >> tag;
    if (tag == "v") {
      Eigen::Vector3d v;
      if (!(words >> v.x() >> v.y() >> v.z())) {
        return std::unexpected(
            Bad(path, fmt::format("line {}: a vertex needs x y z", line_number)));
      }
      mesh.vertices.push_back(v);
    } else if (tag == "f") {
      std::vector<int> polygon;
      std::string corner;
      while (words >> corner) {
        // "i", "i/t", "i//n", "i/t/n"; negative indices count back from the last vertex.
        const int index = std::atoi(corner.c_str());
        if (index == 0) {
          return std::unexpected(
              Bad(path, fmt::format("line {}: bad face index \"{}\"", line_number, corner)));
        }
        polygon.push_back(index > 0 ? index - 1 : static_cast<int>(mesh.vertices.size()) + index);
      }
      for (std::size_t i = 2; i < polygon.size(); ++i) {
        mesh.triangles.emplace_back(polygon[0], polygon[i - 1], polygon[i]);
      }
    }
  }
  if (auto ok = CheckIndices(mesh, path); !ok) return std::unexpected(ok.error());
  return mesh;
}

enum class PlyFormat { kAscii, kBinaryLittle, kBinaryBig };

struct PlyProperty {
  std::string name;
  std::string type;        // scalar type, or the list's item type
  std::string count_type;  // list count type; empty for scalars
};

struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> properties;
};

int TypeSize(const std::string& type) {
  if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
  if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
  if (type == "int" || type == "uint" || type == "int32" || type == "uint32" || type == "float" ||
      type == "float32") {
    return 4;
  }
  if (type == "double" || type == "float64") return 8;
  return 0;
}

// Reads one binary value of `type` as a double.
bool ReadBinary(std::istream& in, const std::string& type, bool big_endian, double* out) {
  const int size = TypeSize(type);
  unsigned char bytes[8];
  if (size == 0 || !in.read(reinterpret_cast<char*>(bytes), size)) return false;
  if (big_endian != (std::endian::native == std::endian::big)) std::reverse(bytes, bytes + size);
  auto as = [&](auto value) {
    std::memcpy(&value, bytes, sizeof(value));
    *out = static_cast<double>(value);
    return true;
  };
  if (type == "char" || type == "int8") return as(std::int8_t{});
  if (type == "uchar" || type == "uint8") return as(std::uint8_t{});
  if (type == "short" || type == "int16") return as(std::int16_t{});
  if (type == "ushort" || type == "uint16") return as(std::uint16_t{});
  if (type == "int" || type == "int32") return as(std::int32_t{});
  if (type == "uint" || type == "uint32") return as(std::uint32_t{});
  if (type == "float" || type == "float32") return as(float{});
  return as(double{});
}

Expected<TriangleMesh> ReadPly(const std::filesystem::path& path, std::istream& in) {
  std::string line;
  if (!std::getline(in, line) || line.rfind("ply", 0) != 0) {
    return std::unexpected(Bad(path, "not a PLY file (no \"ply\" magic)"));
  }
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  bool header_done = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string tag;
    words >> tag;
    if (tag == "format") {
      std::string name;
      words >> name;
      if (name == "ascii") {
        format = PlyFormat::kAscii;
      } else if (name == "binary_little_endian") {
        format = PlyFormat::kBinaryLittle;
      } else if (name == "binary_big_endian") {
        format = PlyFormat::kBinaryBig;
      } else {
        return std::unexpected(Bad(path, fmt::format("unknown PLY format \"{}\"", name)));
      }
    } else if (tag == "element") {
      PlyElement element;
      words >> element.name >> element.count;
      elements.push_back(element);
    } else if (tag == "property") {
      if (elements.empty()) return std::unexpected(Bad(path, "a property before any element"));
      PlyProperty property;
      std::string type;
      words >> type;
      if (type == "list") {
        words >> property.count_type >> property.type >> property.name;
      } else {
        property.type = type;
        words >> property.name;
      }
      if (TypeSize(property.type) == 0 ||
          (!property.count_type.empty() && TypeSize(property.count_type) == 0)) {
        return std::unexpected(Bad(path, fmt::format("unknown PLY type in \"{}\"", line)));
      }
      elements.back().properties.push_back(property);
    } else if (tag == "end_header") {
      header_done = true;
      break;
    }
  }
  if (!header_done) return std::unexpected(Bad(path, "the PLY header has no end_header"));

  TriangleMesh mesh;
  const bool big = format == PlyFormat::kBinaryBig;
  auto read_value = [&](const std::string& type, double* value) {
    if (format == PlyFormat::kAscii) return static_cast<bool>(in >> *value);
    return ReadBinary(in, type, big, value);
  };
  for (const PlyElement& element : elements) {
    for (std::size_t i = 0; i < element.count; ++i) {
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      std::vector<int> polygon;
      for (const PlyProperty& property : element.properties) {
        if (property.count_type.empty()) {
          double value;
          if (!read_value(property.type, &value)) {
            return std::unexpected(Bad(path, fmt::format("truncated {} data", element.name)));
          }
          if (element.name == "vertex") {
            if (property.name == "x") v.x() = value;
            if (property.name == "y") v.y() = value;
            if (property.name == "z") v.z() = value;
          }
        } else {
          double count;
          if (!read_value(property.count_type, &count) || count < 0) {
            return std::unexpected(Bad(path, fmt::format("truncated {} data", element.name)));
          }
          for (int k = 0; k < static_cast<int>(count); ++k) {
            double index;
            if (!read_value(property.type, &index)) {
              return std::unexpected(Bad(path, fmt::format("truncated {} data", element.name)));
            }
            if (element.name == "face" &&
                (property.name == "vertex_indices" || property.name == "vertex_index")) {
              polygon.push_back(static_cast<int>(index));
            }
          }
        }
      }
      if (element.name == "vertex") mesh.vertices.push_back(v);
      for (std::size_t k = 2; k < polygon.size(); ++k) {
        mesh.triangles.emplace_back(polygon[0], polygon[k - 1], polygon[k]);
      }
    }
  }
  if (auto ok = CheckIndices(mesh, path); !ok) return std::unexpected(ok.error());
  return mesh;
}

}  // namespace

Expected<TriangleMesh> ReadMesh(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return MakeError(ErrorCode::kNotFound, fmt::format("{}: cannot open the mesh", path.string()));
  }
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (extension == ".obj") return ReadObj(path, in);
  if (extension == ".ply") return ReadPly(path, in);
  return std::unexpected(Bad(path, "unknown mesh format (.obj or .ply expected)"));
}

Expected<void> WritePlyAscii(const TriangleMesh& mesh, const std::filesystem::path& path) {
  std::string text = fmt::format(
      "ply\nformat ascii 1.0\ncomment revolve ground truth (object frame, mm)\nelement vertex "
      "{}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty "
      "list uchar int vertex_indices\nend_header\n",
      mesh.vertices.size(), mesh.triangles.size());
  for (const auto& v : mesh.vertices) text += fmt::format("{} {} {}\n", v.x(), v.y(), v.z());
  for (const auto& t : mesh.triangles) text += fmt::format("3 {} {} {}\n", t[0], t[1], t[2]);
  return WriteFileAtomically(path, std::string_view(text));
}

double MeshVolume(const TriangleMesh& mesh) {
  double six_volume = 0.0;
  for (const auto& t : mesh.triangles) {
    six_volume += mesh.vertices[t[0]].dot(mesh.vertices[t[1]].cross(mesh.vertices[t[2]]));
  }
  return six_volume / 6.0;
}

double PointTriangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Closest point by Voronoi regions (Ericson, Real-Time Collision Detection, 5.1.5).
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return ap.norm();
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return bp.norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return cp.norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  }
  const double denominator = 1.0 / (va + vb + vc);
  return (p - (a + ab * (vb * denominator) + ac * (vc * denominator))).norm();
}

std::optional<double> RayTriangle(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                  const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  const Eigen::Vector3d& c) {
  // Moller-Trumbore, both faces.
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const Eigen::Vector3d pv = d.cross(e2);
  const double det = e1.dot(pv);
  if (std::abs(det) < 1e-300) return std::nullopt;
  const double inv = 1.0 / det;
  const Eigen::Vector3d tv = o - a;
  const double u = tv.dot(pv) * inv;
  if (u < 0.0 || u > 1.0) return std::nullopt;
  const Eigen::Vector3d qv = tv.cross(e1);
  const double v = d.dot(qv) * inv;
  if (v < 0.0 || u + v > 1.0) return std::nullopt;
  const double t = e2.dot(qv) * inv;
  if (t <= 1e-12) return std::nullopt;
  return t;
}

MeshGrid::MeshGrid(std::shared_ptr<const TriangleMesh> mesh, int cells_per_side)
    : mesh_(std::move(mesh)), n_(std::max(1, cells_per_side)) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& v : mesh_->vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  const Eigen::Vector3d pad = Eigen::Vector3d::Constant(1e-6 * (hi - lo).norm() + 1e-9);
  min_ = lo - pad;
  cell_size_ = (hi + pad - min_) / n_;
  cells_.resize(static_cast<std::size_t>(n_) * n_ * n_);
  for (int t = 0; t < static_cast<int>(mesh_->triangles.size()); ++t) {
    const auto& tri = mesh_->triangles[t];
    Eigen::Vector3d tlo = mesh_->vertices[tri[0]], thi = tlo;
    for (int k = 1; k < 3; ++k) {
      tlo = tlo.cwiseMin(mesh_->vertices[tri[k]]);
      thi = thi.cwiseMax(mesh_->vertices[tri[k]]);
    }
    Eigen::Vector3i c0, c1;
    for (int a = 0; a < 3; ++a) {
      c0[a] = std::clamp(static_cast<int>((tlo[a] - min_[a]) / cell_size_[a]), 0, n_ - 1);
      c1[a] = std::clamp(static_cast<int>((thi[a] - min_[a]) / cell_size_[a]), 0, n_ - 1);
    }
    for (int z = c0.z(); z <= c1.z(); ++z) {
      for (int y = c0.y(); y <= c1.y(); ++y) {
        for (int x = c0.x(); x <= c1.x(); ++x) cells_[(z * n_ + y) * n_ + x].push_back(t);
      }
    }
  }
}

double MeshGrid::Distance(const Eigen::Vector3d& p) const {
  Eigen::Vector3i c;
  for (int a = 0; a < 3; ++a) {
    c[a] = std::clamp(static_cast<int>(std::floor((p[a] - min_[a]) / cell_size_[a])), 0, n_ - 1);
  }
  double best = std::numeric_limits<double>::infinity();
  auto visit = [&](int x, int y, int z) {
    for (int t : cells_[(z * n_ + y) * n_ + x]) {
      const auto& tri = mesh_->triangles[t];
      best =
          std::min(best, PointTriangleDistance(p, mesh_->vertices[tri[0]], mesh_->vertices[tri[1]],
                                               mesh_->vertices[tri[2]]));
    }
  };
  for (int k = 0; k < n_; ++k) {
    const Eigen::Vector3i lo = (c.array() - k).max(0);
    const Eigen::Vector3i hi = (c.array() + k).min(n_ - 1);
    for (int z = lo.z(); z <= hi.z(); ++z) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int x = lo.x(); x <= hi.x(); ++x) {
          const int shell =
              std::max({std::abs(x - c.x()), std::abs(y - c.y()), std::abs(z - c.z())});
          if (shell == k) visit(x, y, z);
        }
      }
    }
    // Cells not yet visited lie beyond a face of the visited block that is not the grid's.
    double bound = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
      if (lo[a] > 0)
        bound = std::min(bound, std::max(0.0, p[a] - (min_[a] + lo[a] * cell_size_[a])));
      if (hi[a] < n_ - 1) {
        bound = std::min(bound, std::max(0.0, min_[a] + (hi[a] + 1) * cell_size_[a] - p[a]));
      }
    }
    if (best <= bound) break;
  }
  return best;
}

}  // namespace revolve::capture
