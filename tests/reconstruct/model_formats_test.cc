// The model writers (OBJ + MTL + PNG, STL, glTF binary; PLY and VRML are in mesh_io_test),
// checked by our readers and by code no one here wrote: `assimp info` (Debian assimp-utils) must
// load each file with the same vertex and face counts, and the Khronos glTF validator (npm
// gltf-validator, installed into tests/tools by ./run) must find no error in the .glb.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <random>
#include <regex>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "reconstruct/cameras/views.h"
#include "reconstruct/hull/marching_cubes.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/meridian/meridian.h"
#include "reconstruct/metrics/metrics.h"

namespace revolve::reconstruct {
namespace {

namespace fs = std::filesystem;

struct CommandResult {
  int status = -1;  // exit status, -1 when it did not run or exit
  std::string output;
};

CommandResult RunCommand(const std::string& command) {
  CommandResult result;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) {
    return result;
  }
  char buffer[4096];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0) {
    result.output.append(buffer, n);
  }
  const int status = ::pclose(pipe);
  result.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

bool HaveCommand(const std::string& name) {
  return RunCommand("command -v " + name + " >/dev/null").status == 0;
}

// A closed mesh with irregular coordinates (a blob from random edge crossings).
Mesh Blob() {
  BitVolume field({7, 6, 5});
  std::mt19937 rng(5);
  for (int k = 0; k < 5; ++k) {
    for (int j = 0; j < 6; ++j) {
      for (int i = 0; i < 7; ++i) field.Set(i, j, k, (rng() % 3) != 0);
    }
  }
  std::uniform_real_distribution<double> t(0.05, 0.95);
  return MarchingCubes(field, Eigen::Vector3d(-12.345, 6.789, 0.1), 0.731,
                       [&](const std::vector<GridEdge>& edges) {
                         std::vector<double> ts;
                         for (std::size_t i = 0; i < edges.size(); ++i) ts.push_back(t(rng));
                         return ts;
                       });
}

Mesh WithColours(Mesh mesh) {
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    mesh.colors.emplace_back(static_cast<std::uint8_t>(i * 7), static_cast<std::uint8_t>(255 - i),
                             static_cast<std::uint8_t>(i * 13 + 1));
  }
  return mesh;
}

// Two charts: faces facing up (+z) and the others, each with its own uvs (a planar map in its
// own half of the atlas), so the vertices on the border between them carry two uvs.
Mesh WithTexture(Mesh mesh) {
  Eigen::Vector3f lo = mesh.vertices[0];
  Eigen::Vector3f hi = lo;
  for (const Eigen::Vector3f& v : mesh.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  std::vector<int> uv_of[2] = {std::vector<int>(mesh.vertices.size(), -1),
                               std::vector<int>(mesh.vertices.size(), -1)};
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3f& a = mesh.vertices[f[0]];
    const int chart = (mesh.vertices[f[1]] - a).cross(mesh.vertices[f[2]] - a).z() > 0.0f ? 1 : 0;
    Eigen::Vector3i uv_face;
    for (int c = 0; c < 3; ++c) {
      int& uv = uv_of[chart][f[c]];
      if (uv < 0) {
        const Eigen::Vector3f p = (mesh.vertices[f[c]] - lo).cwiseQuotient(hi - lo);
        uv = static_cast<int>(mesh.uvs.size());
        mesh.uvs.emplace_back(0.5f * chart + 0.5f * (0.02f + 0.96f * p.x()), 0.02f + 0.96f * p.y());
      }
      uv_face[c] = uv;
    }
    mesh.uv_faces.push_back(uv_face);
  }
  mesh.texture.create(64, 128, CV_8UC3);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 128; ++x) mesh.texture.at<cv::Vec3b>(y, x) = cv::Vec3b(x * 2, y * 4, 99);
  }
  return mesh;
}

// The meridian method's mesh of a cylinder in 12 thesis views, each photo a gradient in its own
// colour: its view-dependent texture packed into an atlas (reconstruct/texture/view_atlas.h),
// with the caps (seen edge-on) on the atlas's grey patch.
Mesh MeridianCylinder() {
  MeridianReconstructor reconstructor(MeridianOptions{9, false, 512});
  for (int k = 0; k < 12; ++k) {
    cv::Mat mask(240, 200, CV_8UC1, cv::Scalar(0));
    cv::rectangle(mask, cv::Point(60, 40), cv::Point(139, 209), cv::Scalar(255), cv::FILLED);
    cv::Mat photo(mask.size(), CV_8UC3, cv::Scalar(0, 0, 0));
    for (int y = 0; y < photo.rows; ++y) {
      for (int x = 0; x < photo.cols; ++x) {
        if (mask.at<std::uint8_t>(y, x) != 0) photo.at<cv::Vec3b>(y, x) = cv::Vec3b(20 * k, x, y);
      }
    }
    EXPECT_TRUE(reconstructor.Integrate(mask, photo, ThesisView(200, 240, 30.0 * k)).has_value());
  }
  Expected<Mesh> mesh = reconstructor.Finish();
  EXPECT_TRUE(mesh.has_value());
  EXPECT_TRUE(mesh->HasTexture());
  EXPECT_TRUE(mesh->HasViewTexture());
  return mesh ? *mesh : Mesh{};
}

class ModelFormatsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / (std::string("revolve_model_formats_") + info->name() + "_" +
                                        std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  std::vector<std::string> Listing() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_)) {
      names.push_back(entry.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }

  fs::path dir_;
};

TEST_F(ModelFormatsTest, StlRoundTrip) {
  const Mesh mesh = Blob();
  ASSERT_GT(mesh.faces.size(), 50u);
  ASSERT_TRUE(WriteStl(mesh, dir_ / "m.stl").has_value());
  EXPECT_EQ(fs::file_size(dir_ / "m.stl"), 84 + 50 * mesh.faces.size());
  std::ifstream in(dir_ / "m.stl", std::ios::binary);
  std::string header(80, '\0');
  in.read(header.data(), 80);
  EXPECT_FALSE(header.starts_with("solid"));  // readers take "solid" for ASCII STL
  const Expected<Mesh> back = ReadStl(dir_ / "m.stl");
  ASSERT_TRUE(back.has_value()) << back.error().ToString();
  ASSERT_EQ(back->faces.size(), mesh.faces.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(back->vertices[back->faces[f][c]], mesh.vertices[mesh.faces[f][c]]);
    }
  }
  const MeshStats a = ComputeStats(mesh);
  const MeshStats b = ComputeStats(*back);
  EXPECT_NEAR(a.volume_mm3, b.volume_mm3, 1e-9 * std::abs(a.volume_mm3));
  EXPECT_EQ(Listing(), std::vector<std::string>{"m.stl"});
}

TEST_F(ModelFormatsTest, ObjRoundTripWithoutTexture) {
  for (bool colours : {false, true}) {
    SCOPED_TRACE(colours ? "colours" : "plain");
    const Mesh mesh = colours ? WithColours(Blob()) : Blob();
    ASSERT_TRUE(WriteObj(mesh, dir_ / "m.obj").has_value());
    EXPECT_EQ(Listing(), (std::vector<std::string>{"m.mtl", "m.obj"}));
    const Expected<Mesh> back = ReadObj(dir_ / "m.obj");
    ASSERT_TRUE(back.has_value()) << back.error().ToString();
    ASSERT_EQ(back->vertices.size(), mesh.vertices.size());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
      // 4 decimals: within half of 0.1 um (plus float rounding).
      ASSERT_LE((back->vertices[i] - mesh.vertices[i]).cwiseAbs().maxCoeff(), 5.1e-5f);
    }
    EXPECT_EQ(back->faces, mesh.faces);
    EXPECT_EQ(back->colors, mesh.colors);
    EXPECT_TRUE(back->uv_faces.empty());
    std::ifstream mtl(dir_ / "m.mtl");
    const std::string text((std::istreambuf_iterator<char>(mtl)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("newmtl revolve"), std::string::npos);
    EXPECT_EQ(text.find("map_Kd"), std::string::npos);
  }
}

TEST_F(ModelFormatsTest, ObjRoundTripWithTexture) {
  const Mesh mesh = WithTexture(Blob());
  ASSERT_TRUE(mesh.HasTexture());
  ASSERT_TRUE(WriteObj(mesh, dir_ / "m.obj").has_value());
  EXPECT_EQ(Listing(), (std::vector<std::string>{"m.mtl", "m.obj", "m.png"}));
  const Expected<Mesh> back = ReadObj(dir_ / "m.obj");
  ASSERT_TRUE(back.has_value()) << back.error().ToString();
  EXPECT_EQ(back->faces, mesh.faces);
  EXPECT_EQ(back->uv_faces, mesh.uv_faces);
  ASSERT_EQ(back->uvs.size(), mesh.uvs.size());
  for (std::size_t i = 0; i < mesh.uvs.size(); ++i) {
    EXPECT_NEAR(back->uvs[i].x(), mesh.uvs[i].x(), 6e-7);  // 6 decimals
    EXPECT_NEAR(back->uvs[i].y(), mesh.uvs[i].y(), 6e-7);
  }
  const cv::Mat png = cv::imread((dir_ / "m.png").string(), cv::IMREAD_COLOR);
  ASSERT_EQ(png.size(), mesh.texture.size());
  EXPECT_EQ(cv::norm(png, mesh.texture, cv::NORM_INF), 0.0);
  std::ifstream mtl(dir_ / "m.mtl");
  const std::string text((std::istreambuf_iterator<char>(mtl)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("map_Kd m.png"), std::string::npos);
}

// The .glb's chunks and JSON, checked against the mesh.
TEST_F(ModelFormatsTest, GlbStructure) {
  for (int variant = 0; variant < 3; ++variant) {
    SCOPED_TRACE(variant);
    const Mesh mesh = variant == 0   ? Blob()
                      : variant == 1 ? WithColours(Blob())
                                     : WithTexture(Blob());
    ASSERT_TRUE(WriteGlb(mesh, dir_ / "m.glb").has_value());
    std::ifstream in(dir_ / "m.glb", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_GE(bytes.size(), 28u);
    auto u32 = [&](std::size_t at) {
      std::uint32_t v;
      std::memcpy(&v, bytes.data() + at, 4);
      return v;
    };
    EXPECT_EQ(bytes.substr(0, 4), "glTF");
    EXPECT_EQ(u32(4), 2u);
    EXPECT_EQ(u32(8), bytes.size());
    const std::uint32_t json_length = u32(12);
    EXPECT_EQ(u32(16), 0x4E4F534Au);
    EXPECT_EQ(json_length % 4, 0u);
    const nlohmann::json json = nlohmann::json::parse(bytes.substr(20, json_length));
    const std::size_t bin_at = 20 + json_length;
    EXPECT_EQ(u32(bin_at + 4), 0x004E4942u);
    EXPECT_EQ(u32(bin_at), json["buffers"][0]["byteLength"].get<std::size_t>());
    const auto& primitive = json["meshes"][0]["primitives"][0];
    const auto& accessors = json["accessors"];
    const std::size_t vertices = accessors[primitive["attributes"]["POSITION"].get<int>()]["count"];
    EXPECT_EQ(vertices, GlbVertexCount(mesh));
    EXPECT_EQ(accessors[primitive["indices"].get<int>()]["count"].get<std::size_t>(),
              3 * mesh.faces.size());
    EXPECT_EQ(primitive["attributes"].contains("COLOR_0"), variant == 1);
    EXPECT_EQ(primitive["attributes"].contains("TEXCOORD_0"), variant == 2);
    EXPECT_EQ(json.contains("images"), variant == 2);
    if (variant == 2) {
      EXPECT_GT(GlbVertexCount(mesh), mesh.vertices.size());  // split along the seam
    }
  }
}

// Parses "Vertices: N" and "Faces: N" of `assimp info FILE`.
struct AssimpCounts {
  long vertices = -1;
  long faces = -1;
};
AssimpCounts AssimpInfo(const fs::path& file, bool raw, std::string* output) {
  const CommandResult result =
      RunCommand("assimp info '" + file.string() + "'" + (raw ? " -r" : ""));
  *output = result.output;
  AssimpCounts counts;
  if (result.status != 0) {
    return counts;
  }
  std::smatch match;
  if (std::regex_search(result.output, match, std::regex(R"(\nVertices:\s+(\d+))"))) {
    counts.vertices = std::stol(match[1]);
  }
  if (std::regex_search(result.output, match, std::regex(R"(\nFaces:\s+(\d+))"))) {
    counts.faces = std::stol(match[1]);
  }
  return counts;
}

TEST_F(ModelFormatsTest, AssimpLoadsEveryFormatWithTheSameCounts) {
  if (!HaveCommand("assimp")) {
    GTEST_SKIP() << "assimp (Debian assimp-utils) is not installed; ./run installs it";
  }
  for (int variant = 0; variant < 3; ++variant) {
    const Mesh mesh = variant == 0   ? WithColours(Blob())
                      : variant == 1 ? WithTexture(WithColours(Blob()))
                                     : MeridianCylinder();
    SCOPED_TRACE(variant == 0 ? "vertex colours" : variant == 1 ? "texture" : "meridian texture");
    const Expected<std::vector<fs::path>> files =
        WriteModel(mesh, dir_, "model", {"ply", "obj", "stl", "glb"});
    ASSERT_TRUE(files.has_value()) << files.error().ToString();
    for (const char* extension : {"ply", "obj", "stl", "glb"}) {
      const fs::path file = dir_ / (std::string("model.") + extension);
      for (bool raw : {true, false}) {
        std::string output;
        const AssimpCounts counts = AssimpInfo(file, raw, &output);
        SCOPED_TRACE(std::string(extension) + (raw ? " raw" : " post-processed") + "\n" + output);
        EXPECT_EQ(counts.faces, static_cast<long>(mesh.faces.size()));
        // What each file holds: PLY the mesh's vertices; glTF one per (vertex, uv) pair; STL 3
        // per triangle. assimp's OBJ importer unrolls every corner (raw); its post-processing
        // welds them back to the mesh's vertices, but with uvs it first computes a tangent per
        // corner, which keeps corners apart across sharp edges: then only bounds hold.
        const std::string format = extension;
        const long faces = static_cast<long>(mesh.faces.size());
        long expected = static_cast<long>(mesh.vertices.size());
        if (format == "glb") {
          expected = static_cast<long>(GlbVertexCount(mesh));
        }
        if (format == "stl" || (format == "obj" && raw)) {
          expected = 3 * faces;
        }
        if ((format == "obj" && !raw && mesh.HasTexture()) || (format == "stl" && !raw)) {
          // Post-processing welds equal corners: STL corners share a position and a facet
          // normal only across coplanar neighbours.
          EXPECT_GE(counts.vertices, static_cast<long>(GlbVertexCount(mesh)));
          EXPECT_LE(counts.vertices, 3 * faces);
        } else {
          EXPECT_EQ(counts.vertices, expected);
        }
        std::printf("%s %s: assimp %ld vertices %ld faces (mesh %zu vertices, glb %zu)\n",
                    extension, raw ? "raw" : "pp", counts.vertices, counts.faces,
                    mesh.vertices.size(), GlbVertexCount(mesh));
      }
    }
  }
}

TEST_F(ModelFormatsTest, KhronosValidatorFindsNoErrorInTheGlb) {
  const fs::path script = fs::path(REVOLVE_SOURCE_DIR) / "tests" / "tools" / "validate_gltf.js";
  if (!HaveCommand("node") ||
      !fs::exists(fs::path(REVOLVE_SOURCE_DIR) / "tests/tools/node_modules/gltf-validator")) {
    GTEST_SKIP() << "the glTF validator is not installed (node and npm ci in tests/tools; "
                    "./run test installs it)";
  }
  for (int variant = 0; variant < 4; ++variant) {
    SCOPED_TRACE(variant);
    const Mesh mesh = variant == 0   ? Blob()
                      : variant == 1 ? WithColours(Blob())
                      : variant == 2 ? WithTexture(Blob())
                                     : MeridianCylinder();
    ASSERT_TRUE(WriteGlb(mesh, dir_ / "m.glb").has_value());
    const CommandResult result =
        RunCommand("node '" + script.string() + "' '" + (dir_ / "m.glb").string() + "'");
    ASSERT_NE(result.status, 2) << result.output;
    const nlohmann::json report = nlohmann::json::parse(result.output, nullptr, false);
    ASSERT_FALSE(report.is_discarded()) << result.output;
    EXPECT_EQ(report["issues"]["numErrors"].get<int>(), 0) << result.output;
    EXPECT_EQ(report["issues"]["numWarnings"].get<int>(), 0) << result.output;
    EXPECT_EQ(result.status, 0);
    std::printf("variant %d: %d errors, %d warnings, %d infos, %d hints\n", variant,
                report["issues"]["numErrors"].get<int>(),
                report["issues"]["numWarnings"].get<int>(), report["issues"]["numInfos"].get<int>(),
                report["issues"]["numHints"].get<int>());
  }
}

TEST_F(ModelFormatsTest, WriteModelWritesEveryFormatOnce) {
  const Mesh mesh = WithTexture(WithColours(Blob()));
  const Expected<std::vector<fs::path>> files =
      WriteModel(mesh, dir_, "model", {"ply", "obj", "stl", "glb", "wrl", "ply"});
  ASSERT_TRUE(files.has_value()) << files.error().ToString();
  EXPECT_EQ(*files,
            (std::vector<fs::path>{dir_ / "model.ply", dir_ / "model.obj", dir_ / "model.mtl",
                                   dir_ / "model.png", dir_ / "model.stl", dir_ / "model.glb",
                                   dir_ / "model.wrl"}));
  EXPECT_EQ(Listing(), (std::vector<std::string>{"model.glb", "model.mtl", "model.obj", "model.ply",
                                                 "model.png", "model.stl", "model.wrl"}));
  const Expected<std::vector<fs::path>> bad = WriteModel(mesh, dir_, "x", {"stl", "fbx"});
  ASSERT_FALSE(bad.has_value());
  EXPECT_EQ(bad.error().code, ErrorCode::kBadInput);
  EXPECT_FALSE(fs::exists(dir_ / "x.stl"));
  // A failed write names the file and leaves nothing behind.
  const Expected<std::vector<fs::path>> missing = WriteModel(mesh, dir_ / "nope", "m", {"glb"});
  ASSERT_FALSE(missing.has_value());
  EXPECT_NE(missing.error().message.find((dir_ / "nope" / "m.glb").string()), std::string::npos);
}

}  // namespace
}  // namespace revolve::reconstruct
