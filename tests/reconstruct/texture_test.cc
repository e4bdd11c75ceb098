// Colour and texture of the hull, against the synthetic camera's textured object: rendering the
// textured model back into each input view must match the frame inside the silhouette.
#include "reconstruct/texture/texture.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "capture/synthetic/render.h"
#include "capture/synthetic/scene.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/io/writer_support.h"
#include "reconstruct/metrics/metrics.h"
#include "reconstruct/reconstructor.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

struct Frames {
  std::vector<cv::Mat> images;
  std::vector<cv::Mat> masks;  // the true silhouettes
  std::vector<View> views;
};

// 36 noise-free frames of a textured solid at 10 degree steps on the station's rig. `lit`: the
// synthetic camera's own frames (a lamp beside the lens: the shading moves with the camera, so
// no single texture can match every view); otherwise the object's albedo under even light (each
// pixel centre's ray cast into the scene), which a texture can match.
Frames Render(const capture::Scene& scene, bool lit) {
  const Rig rig = testing::StationRig(450.0, 0.0, 40.0);
  const capture::SimProjection projection(rig);
  capture::RenderSettings settings;
  settings.noise_sigma = 0.0;
  Frames frames;
  for (int k = 0; k < 36; ++k) {
    const double angle = 10.0 * k;
    frames.views.push_back(testing::ViewOf(rig, angle));
    if (lit) {
      const capture::RenderOutput out = capture::RenderScene(scene, projection, angle, settings, k);
      frames.images.push_back(out.image);
      frames.masks.push_back(out.true_mask);
      continue;
    }
    cv::Mat image(rig.intrinsics.height_px, rig.intrinsics.width_px, CV_8UC3,
                  cv::Scalar(20, 20, 20));
    cv::Mat mask(image.size(), CV_8UC1, cv::Scalar(0));
    const capture::PixelRays rays(projection, angle);
    const cv::Rect bounds = capture::ProjectedBounds(scene, projection, angle, 2);
    for (int v = bounds.y; v < bounds.y + bounds.height; ++v) {
      for (int u = bounds.x; u < bounds.x + bounds.width; ++u) {
        const std::optional<capture::RayHit> hit =
            scene.Intersect(rays.Origin(u, v), rays.Direction(u, v));
        if (!hit) continue;
        const Eigen::Vector3f bgr = 230.0f * capture::SurfaceAlbedo(scene, hit->point);
        image.at<cv::Vec3b>(v, u) = cv::Vec3b(static_cast<std::uint8_t>(bgr[0] + 0.5f),
                                              static_cast<std::uint8_t>(bgr[1] + 0.5f),
                                              static_cast<std::uint8_t>(bgr[2] + 0.5f));
        mask.at<std::uint8_t>(v, u) = 255;
      }
    }
    frames.images.push_back(image);
    frames.masks.push_back(mask);
  }
  return frames;
}

Mesh Reconstruct(const Frames& frames, int resolution, bool texture, int texture_size_px = 4096) {
  ReconstructOptions options;
  options.resolution = resolution;
  options.bbox_min_mm = Eigen::Vector3d(-50.0, -50.0, 0.0);
  options.bbox_max_mm = Eigen::Vector3d(50.0, 50.0, 100.0);
  options.texture = texture;
  options.texture_size_px = texture_size_px;
  Expected<std::unique_ptr<Reconstructor>> reconstructor = Create(options);
  EXPECT_TRUE(reconstructor.has_value());
  for (std::size_t k = 0; k < frames.views.size(); ++k) {
    EXPECT_TRUE((*reconstructor)
                    ->Integrate(frames.masks[k], frames.images[k], frames.views[k])
                    .has_value());
  }
  Expected<Mesh> mesh = (*reconstructor)->Finish();
  EXPECT_TRUE(mesh.has_value());
  return mesh ? *mesh : Mesh{};
}

struct PsnrSummary {
  double mean_db = 0.0;
  double min_db = 1e9;
  double coverage = 0.0;  // drawn pixels / silhouette pixels
};

// PSNR of the model rendered into each view against the frame, over the pixels of the true
// silhouette that the model covers.
PsnrSummary RenderBack(const Mesh& mesh, const Frames& frames) {
  PsnrSummary summary;
  double coverage = 0.0;
  for (std::size_t k = 0; k < frames.views.size(); ++k) {
    const MeshRendering rendering = RenderMesh(mesh, frames.views[k]);
    cv::Mat both;
    cv::bitwise_and(rendering.coverage, frames.masks[k], both);
    const double psnr = Psnr(rendering.image, frames.images[k], both);
    if (k == 3 && mesh.HasTexture() && std::getenv("REVOLVE_TEXTURE_DUMP") != nullptr) {
      cv::imwrite("/tmp/tex_render.png", rendering.image);
      cv::imwrite("/tmp/tex_frame.png", frames.images[k]);
      cv::Mat diff;
      cv::absdiff(rendering.image, frames.images[k], diff);
      cv::imwrite("/tmp/tex_diff.png", diff * 4);
      if (mesh.HasTexture()) cv::imwrite("/tmp/tex_atlas.png", mesh.texture);
    }
    summary.mean_db += psnr / frames.views.size();
    summary.min_db = std::min(summary.min_db, psnr);
    coverage += static_cast<double>(cv::countNonZero(both)) / cv::countNonZero(frames.masks[k]);
  }
  summary.coverage = coverage / frames.views.size();
  return summary;
}

const capture::Scene& Sphere() {
  static const capture::Scene scene = *capture::Scene::Create(capture::Shape::kSphere, 40.0, 80.0);
  return scene;
}
const Frames& SphereFrames() {
  static const Frames frames = Render(Sphere(), false);
  return frames;
}

TEST(Texture, TexturedSphereRendersBackIntoEveryView) {
  const Frames& frames = SphereFrames();
  const Mesh mesh = Reconstruct(frames, 256, true);
  ASSERT_TRUE(mesh.HasTexture());
  ASSERT_TRUE(mesh.HasColors());
  for (const Eigen::Vector2f& uv : mesh.uvs) {
    ASSERT_TRUE(uv.x() >= 0.0f && uv.x() <= 1.0f && uv.y() >= 0.0f && uv.y() <= 1.0f);
  }
  const PsnrSummary textured = RenderBack(mesh, frames);
  Mesh colours_only = mesh;
  colours_only.texture = cv::Mat();
  const PsnrSummary vertex = RenderBack(colours_only, frames);
  std::printf(
      "sphere 256^3, even light: atlas %dx%d, %zu uvs; render-back PSNR textured mean %.2f dB "
      "min %.2f dB (coverage %.4f); vertex colours mean %.2f dB min %.2f dB\n",
      mesh.texture.cols, mesh.texture.rows, mesh.uvs.size(), textured.mean_db, textured.min_db,
      textured.coverage, vertex.mean_db, vertex.min_db);
  RecordProperty("psnr_textured_mean_db", std::to_string(textured.mean_db));
  RecordProperty("psnr_vertex_mean_db", std::to_string(vertex.mean_db));
  EXPECT_GE(textured.mean_db, 30.0);
  EXPECT_GE(textured.min_db, 28.0);
  EXPECT_GT(textured.coverage, 0.99);
  EXPECT_GE(vertex.mean_db, 22.0);
}

// The synthetic camera's lit frames: the texture holds each point's best view, lit as that view
// saw it; elsewhere the lamp that moves with the camera shades it differently. Measured and
// reported; the bound only guards against a broken pipeline.
TEST(Texture, LitSphereRendersBackIntoEveryView) {
  const Frames frames = Render(Sphere(), true);
  const Mesh mesh = Reconstruct(frames, 192, true);
  ASSERT_TRUE(mesh.HasTexture());
  const PsnrSummary textured = RenderBack(mesh, frames);
  std::printf("sphere 192^3, the camera's lamp: render-back PSNR mean %.2f dB min %.2f dB\n",
              textured.mean_db, textured.min_db);
  EXPECT_GE(textured.mean_db, 20.0);
}

TEST(Texture, SmallAtlasShrinksTheCharts) {
  const Frames& frames = SphereFrames();
  const Mesh mesh = Reconstruct(frames, 96, true, 256);
  ASSERT_TRUE(mesh.HasTexture());
  EXPECT_LE(mesh.texture.cols, 256);
  EXPECT_LE(mesh.texture.rows, 256);
  const PsnrSummary textured = RenderBack(mesh, frames);
  std::printf("sphere 96^3, 256 px atlas %dx%d: PSNR mean %.2f dB\n", mesh.texture.cols,
              mesh.texture.rows, textured.mean_db);
  EXPECT_GE(textured.mean_db, 20.0);
}

TEST(Texture, VertexColoursOnlyWhenTextureIsOff) {
  const Frames& frames = SphereFrames();
  const Mesh mesh = Reconstruct(frames, 64, false);
  EXPECT_TRUE(mesh.HasColors());
  EXPECT_FALSE(mesh.HasTexture());
  // The marker patch (magenta, on the object's +x side at mid-height) is where it belongs.
  const Eigen::Vector3d marker = capture::MarkerCenter(Sphere());
  std::size_t nearest = 0;
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    if ((mesh.vertices[v].cast<double>() - marker).norm() <
        (mesh.vertices[nearest].cast<double>() - marker).norm()) {
      nearest = v;
    }
  }
  const Color c = mesh.colors[nearest];  // RGB
  EXPECT_GT(c[0], 150);
  EXPECT_GT(c[2], 150);
  EXPECT_LT(c[1], c[0] - 60);
}

// TextureMesh leaves in the mesh the vertex normals the writers would compute, so the glTF
// writer takes them as they are: the same file either way.
TEST(Texture, LeavesTheNormalsTheWritersWouldCompute) {
  Mesh mesh = Reconstruct(SphereFrames(), 64, false);
  ASSERT_TRUE(mesh.HasNormals());
  const std::vector<Eigen::Vector3f> computed = internal::VertexNormals(mesh);
  ASSERT_EQ(computed.size(), mesh.normals.size());
  for (std::size_t v = 0; v < computed.size(); ++v) {
    ASSERT_EQ(mesh.normals[v], computed[v]) << "vertex " << v;
  }
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("revolve_texture_normals_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(WriteModel(mesh, dir, "kept", {"glb"}).has_value());
  mesh.normals.clear();
  ASSERT_TRUE(WriteModel(mesh, dir, "computed", {"glb"}).has_value());
  auto bytes = [](const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string kept = bytes(dir / "kept.glb");
  EXPECT_GT(kept.size(), 12 * mesh.vertices.size());
  EXPECT_EQ(kept, bytes(dir / "computed.glb"));
  std::filesystem::remove_all(dir);
}

// The files of a textured reconstruction, read by code no one here wrote.
TEST(Texture, ModelFilesOfATexturedHullLoadElsewhere) {
  const Mesh mesh = Reconstruct(SphereFrames(), 96, true);
  ASSERT_TRUE(mesh.HasTexture());
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("revolve_texture_files_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const Expected<std::vector<std::filesystem::path>> files =
      WriteModel(mesh, dir, "model", {"ply", "obj", "stl", "glb", "wrl"});
  ASSERT_TRUE(files.has_value()) << files.error().ToString();
  auto run = [](const std::string& command, std::string* output) {
    FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
    if (pipe == nullptr) return -1;
    char buffer[4096];
    std::size_t n = 0;
    while ((n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0) output->append(buffer, n);
    const int status = ::pclose(pipe);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  std::string probe;
  if (run("command -v assimp", &probe) == 0) {
    for (const char* name : {"model.ply", "model.obj", "model.stl", "model.glb"}) {
      std::string output;
      ASSERT_EQ(run("assimp info '" + (dir / name).string() + "' -r", &output), 0) << output;
      std::smatch faces;
      ASSERT_TRUE(std::regex_search(output, faces, std::regex(R"(\nFaces:\s+(\d+))"))) << output;
      EXPECT_EQ(std::stoul(faces[1]), mesh.faces.size()) << name;
      std::smatch vertices;
      ASSERT_TRUE(std::regex_search(output, vertices, std::regex(R"(\nVertices:\s+(\d+))")));
      const std::size_t expected = std::string(name) == "model.ply"   ? mesh.vertices.size()
                                   : std::string(name) == "model.glb" ? GlbVertexCount(mesh)
                                                                      : 3 * mesh.faces.size();
      EXPECT_EQ(std::stoul(vertices[1]), expected) << name;
    }
  } else {
    std::printf("assimp (Debian assimp-utils) is not installed: skipped its checks\n");
  }
  const std::filesystem::path tools = std::filesystem::path(REVOLVE_SOURCE_DIR) / "tests" / "tools";
  if (run("command -v node", &probe) == 0 &&
      std::filesystem::exists(tools / "node_modules" / "gltf-validator")) {
    std::string output;
    const int status = run("node '" + (tools / "validate_gltf.js").string() + "' '" +
                               (dir / "model.glb").string() + "'",
                           &output);
    EXPECT_EQ(status, 0) << output;
    EXPECT_NE(output.find("\"numErrors\": 0"), std::string::npos) << output;
    EXPECT_NE(output.find("\"numWarnings\": 0"), std::string::npos) << output;
  } else {
    std::printf("the glTF validator is not installed (./run test installs it): skipped\n");
  }
  std::filesystem::remove_all(dir);
}

TEST(Texture, RejectsMismatchedInputs) {
  Mesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.faces = {{0, 1, 2}};
  const View view = testing::ViewOf(testing::StationRig(), 0.0);
  EXPECT_FALSE(TextureMesh(&mesh, {view}, {}).has_value());
  EXPECT_FALSE(TextureMesh(&mesh, {view}, {cv::Mat(10, 10, CV_8UC3)}).has_value());
  TextureOptions options;
  options.texture_size_px = 8;
  EXPECT_FALSE(TextureMesh(&mesh, {view}, {cv::Mat()}, options).has_value());
  EXPECT_TRUE(TextureMesh(&mesh, {view}, {cv::Mat()}).has_value());  // no image: nothing seen
}

}  // namespace
}  // namespace revolve::reconstruct
