// The model writer of the live finish (reconstruct/io/model_writer.h): files put in place only
// when every one was written, errors that name the file, nothing left by an abandoned mesh.
#include "reconstruct/io/model_writer.h"

#include <sys/resource.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "base/png_encode.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/io/writer_support.h"
#include "tests/support/test_files.h"

namespace revolve::reconstruct {
namespace {

namespace fs = std::filesystem;

const std::vector<std::string> kFormats = {"ply", "obj", "stl", "glb", "wrl"};

class ModelWriterTest : public ::testing::Test {
 protected:
  // A textured, coloured grid of n x n vertices (2 (n-1)^2 triangles) with a noisy 64x64 atlas:
  // every file but the .mtl is larger than a few kB.
  static Mesh Grid(int n, std::uint8_t tint) {
    Mesh mesh;
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        mesh.vertices.emplace_back(0.37f * i, 0.41f * j, 0.013f * ((i * j) % 17));
        mesh.colors.emplace_back(static_cast<std::uint8_t>(i * 3 + tint),
                                 static_cast<std::uint8_t>(j * 5), tint);
        mesh.uvs.emplace_back((i + 0.5f) / n, (j + 0.5f) / n);
      }
    }
    for (int j = 0; j + 1 < n; ++j) {
      for (int i = 0; i + 1 < n; ++i) {
        const int a = j * n + i;
        mesh.faces.emplace_back(a, a + 1, a + n + 1);
        mesh.faces.emplace_back(a, a + n + 1, a + n);
      }
    }
    mesh.uv_faces = mesh.faces;
    mesh.texture = cv::Mat(64, 64, CV_8UC3);
    std::mt19937 random(tint);
    for (int v = 0; v < 64; ++v) {
      for (int u = 0; u < 64 * 3; ++u) mesh.texture.ptr<std::uint8_t>(v)[u] = random() & 0xff;
    }
    return mesh;
  }

  // Every entry of the folder (hidden temporary files too): name -> bytes.
  std::map<std::string, std::string> Contents() const {
    std::map<std::string, std::string> contents;
    for (const fs::directory_entry& entry : fs::directory_iterator(dir_)) {
      std::ifstream in(entry.path(), std::ios::binary);
      std::ostringstream bytes;
      bytes << in.rdbuf();
      contents[entry.path().filename().string()] = bytes.str();
    }
    return contents;
  }

  const test_support::TempDir temp_{"revolve_model_writer"};
  const fs::path dir_ = temp_.path();
};

// Copies `finished` into `*mesh` field by field, as TextureMesh makes it, telling `writer` of each
// stage up to `last` (the texture itself, at kDone, is Finish's to tell).
void MakeInStages(const Mesh& finished, MeshStage last, Mesh* mesh, ModelWriter* writer) {
  mesh->vertices = finished.vertices;
  mesh->faces = finished.faces;
  writer->Reached(MeshStage::kSurface);
  if (last == MeshStage::kSurface) return;
  mesh->colors = finished.colors;
  writer->Reached(MeshStage::kColors);
  if (last == MeshStage::kColors) return;
  mesh->uvs = finished.uvs;
  mesh->uv_faces = finished.uv_faces;
  writer->Reached(MeshStage::kUvs);
  if (last == MeshStage::kUvs) return;
  mesh->texture = finished.texture;
}

// Files larger than `bytes` fail to be written (EFBIG, "File too large") while it lives.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    ::getrlimit(RLIMIT_FSIZE, &old_);
    rlimit limit = old_;
    limit.rlim_cur = bytes;
    ::setrlimit(RLIMIT_FSIZE, &limit);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &old_);
    std::signal(SIGXFSZ, old_handler_);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;

 private:
  rlimit old_{};
  void (*old_handler_)(int) = nullptr;
};

TEST_F(ModelWriterTest, WritesWhatWriteModelWritesStageByStage) {
  const Mesh finished = Grid(40, 7);
  Mesh mesh;
  fs::create_directories(dir_ / "staged");
  Expected<std::unique_ptr<ModelWriter>> writer =
      ModelWriter::Start(mesh, dir_ / "staged", "model", kFormats);
  ASSERT_TRUE(writer);
  MakeInStages(finished, MeshStage::kDone, &mesh, writer->get());
  const Expected<std::vector<fs::path>> staged = (*writer)->Finish();
  ASSERT_TRUE(staged) << staged.error().ToString();
  fs::create_directories(dir_ / "whole");
  const Expected<std::vector<fs::path>> whole =
      WriteModel(finished, dir_ / "whole", "model", kFormats);
  ASSERT_TRUE(whole) << whole.error().ToString();
  ASSERT_EQ(staged->size(), 7u);
  ASSERT_EQ(whole->size(), 7u);
  for (std::size_t i = 0; i < staged->size(); ++i) {
    EXPECT_EQ((*staged)[i].filename(), (*whole)[i].filename());
    std::ifstream a((*staged)[i], std::ios::binary);
    std::ifstream b((*whole)[i], std::ios::binary);
    std::ostringstream a_bytes, b_bytes;
    a_bytes << a.rdbuf();
    b_bytes << b.rdbuf();
    EXPECT_TRUE(a_bytes.str() == b_bytes.str()) << (*staged)[i];
  }
}

TEST_F(ModelWriterTest, AFailedFileLeavesTheOldModelWhole) {
  // A complete model first.
  ASSERT_TRUE(WriteModel(Grid(40, 1), dir_, "model", kFormats));
  const std::map<std::string, std::string> before = Contents();
  ASSERT_EQ(before.size(), 7u);
  // Then a new one whose larger files cannot be written: an error naming one of them, and the
  // old files as they were (none replaced by a new one, none half-written, no temporary file).
  const Mesh mesh = Grid(40, 2);
  Expected<std::vector<fs::path>> written;
  {
    const FileSizeLimit limit(4096);
    Expected<std::unique_ptr<ModelWriter>> writer =
        ModelWriter::Start(mesh, dir_, "model", kFormats);
    ASSERT_TRUE(writer);
    for (MeshStage stage : {MeshStage::kSurface, MeshStage::kColors, MeshStage::kUvs}) {
      (*writer)->Reached(stage);
    }
    written = (*writer)->Finish();
  }
  ASSERT_FALSE(written.has_value());
  EXPECT_EQ(written.error().code, ErrorCode::kIo);
  EXPECT_NE(written.error().message.find((dir_ / "model.ply").string()), std::string::npos)
      << written.error().message;
  EXPECT_NE(written.error().message.find("File too large"), std::string::npos)
      << written.error().message;
  EXPECT_EQ(Contents(), before);
}

TEST_F(ModelWriterTest, AnAbandonedMeshLeavesNoFile) {
  const Mesh finished = Grid(40, 3);
  Mesh mesh;
  {
    Expected<std::unique_ptr<ModelWriter>> writer =
        ModelWriter::Start(mesh, dir_, "model", kFormats);
    ASSERT_TRUE(writer);
    MakeInStages(finished, MeshStage::kColors, &mesh, writer->get());
    // The mesh fails here (say the atlas): the writer is destroyed without Finish.
  }
  EXPECT_TRUE(Contents().empty());
}

TEST_F(ModelWriterTest, TheMeshDoneBeforeFinishOrAbandonedThenIsWrittenOrLeavesNoFile) {
  // The reconstruction says kDone through the hook before Finish, which encodes the PNG: the
  // PNG's writer waits for it. Abandoned after kDone, nothing waits for ever and no file stays.
  const Mesh finished = Grid(40, 6);
  for (const bool finish : {true, false}) {
    SCOPED_TRACE(finish ? "finished" : "abandoned");
    const fs::path dir = dir_ / (finish ? "finished" : "abandoned");
    fs::create_directories(dir);
    Mesh mesh;
    {
      Expected<std::unique_ptr<ModelWriter>> writer =
          ModelWriter::Start(mesh, dir, "model", kFormats);
      ASSERT_TRUE(writer);
      MakeInStages(finished, MeshStage::kDone, &mesh, writer->get());
      (*writer)->Reached(MeshStage::kDone);
      if (finish) {
        const Expected<std::vector<fs::path>> files = (*writer)->Finish();
        ASSERT_TRUE(files) << files.error().ToString();
        EXPECT_EQ(files->size(), 7u);
      }
    }
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), finish ? 7 : 0);
  }
}

TEST_F(ModelWriterTest, SharedVertexTextsAreTheTextsFormattedInPlace) {
  // The model writer formats the vertices' coordinates once for the VRML and the OBJ; WriteVrml
  // and WriteObj format them in place. Coordinates of every length (long ones past the 32 bytes
  // copied at once, huge and non-finite ones in their shortest form) read the same.
  Mesh mesh = Grid(12, 8);
  mesh.texture = cv::Mat();
  mesh.uvs.clear();
  mesh.uv_faces.clear();
  mesh.vertices[1] = Eigen::Vector3f(-1234.56789f, -9876.54321f, -5555.55555f);
  mesh.vertices[2] = Eigen::Vector3f(1e12f, -3e15f, 7.25e18f);
  mesh.vertices[3] = Eigen::Vector3f(std::numeric_limits<float>::infinity(), -0.0f, 1e-7f);
  mesh.vertices[4] = Eigen::Vector3f(-123456.79f, -234567.89f, -345678.91f);  // 38 characters
  ASSERT_TRUE(WriteModel(mesh, dir_, "model", {"obj", "wrl"}));
  fs::create_directories(dir_ / "apart");
  ASSERT_TRUE(WriteObj(mesh, dir_ / "apart" / "model.obj"));
  ASSERT_TRUE(WriteVrml(mesh, dir_ / "apart" / "model.wrl"));
  for (const char* name : {"model.obj", "model.wrl"}) {
    std::ifstream a(dir_ / name, std::ios::binary);
    std::ifstream b(dir_ / "apart" / name, std::ios::binary);
    const std::string a_bytes(std::istreambuf_iterator<char>(a), std::istreambuf_iterator<char>{});
    const std::string b_bytes(std::istreambuf_iterator<char>(b), std::istreambuf_iterator<char>{});
    EXPECT_FALSE(a_bytes.empty());
    EXPECT_TRUE(a_bytes == b_bytes) << name;
  }
}

TEST_F(ModelWriterTest, ErrorsNameTheFile) {
  const Mesh mesh = Grid(8, 4);
  // An unknown format: nothing started.
  const Expected<std::unique_ptr<ModelWriter>> unknown =
      ModelWriter::Start(mesh, dir_, "model", {"stl", "fbx"});
  ASSERT_FALSE(unknown.has_value());
  EXPECT_EQ(unknown.error().code, ErrorCode::kBadInput);
  EXPECT_NE(unknown.error().message.find("fbx"), std::string::npos);
  // A missing folder: the first file asked for.
  Expected<std::unique_ptr<ModelWriter>> writer =
      ModelWriter::Start(mesh, dir_ / "nope", "model", {"obj", "ply"});
  ASSERT_TRUE(writer);
  const Expected<std::vector<fs::path>> written = (*writer)->Finish();
  ASSERT_FALSE(written.has_value());
  EXPECT_EQ(written.error().code, ErrorCode::kIo);
  EXPECT_NE(written.error().message.find((dir_ / "nope" / "model.obj").string()), std::string::npos)
      << written.error().message;
  EXPECT_TRUE(Contents().empty());
}

TEST_F(ModelWriterTest, TheGlbIsTheSameWhateverThePngSizeGuessed) {
  // The textured glTF's bulk is written before its PNG is encoded, where a guess of the PNG's
  // size puts it; a wrong guess (the JSON longer or shorter) must not change a byte.
  const Mesh mesh = Grid(40, 5);
  const Expected<std::string> png = EncodePng(mesh.texture);
  ASSERT_TRUE(png);
  const internal::StageGate done(MeshStage::kDone);
  std::vector<std::string> files;
  for (const std::size_t guess :
       {std::size_t{1}, std::size_t{99}, png->size(), std::size_t{1} << 20, std::size_t{1} << 40}) {
    const fs::path path = dir_ / fmt::format("guess{}.glb", guess);
    AtomicFile file(path);
    ASSERT_TRUE(file.Open());
    ASSERT_TRUE(internal::PutGlb(
        mesh, done, [&png] { return &*png; }, &file, guess));
    ASSERT_TRUE(file.Commit());
    std::ifstream in(path, std::ios::binary);
    files.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  ASSERT_TRUE(WriteGlb(mesh, dir_ / "whole.glb"));
  std::ifstream in(dir_ / "whole.glb", std::ios::binary);
  const std::string whole(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>{});
  for (const std::string& bytes : files) EXPECT_TRUE(bytes == whole);
  // And it is a whole GLB: its length, its JSON chunk, then the binary chunk to the end, which
  // opens with the first face's first corner and ends with the PNG (padded to 4 bytes).
  ASSERT_GT(whole.size(), 28u);
  std::uint32_t total = 0, json_length = 0, bin_length = 0;
  std::memcpy(&total, whole.data() + 8, 4);
  std::memcpy(&json_length, whole.data() + 12, 4);
  EXPECT_EQ(total, whole.size());
  const std::size_t bin = 20 + std::size_t{json_length};
  ASSERT_LT(bin + 8, whole.size());
  std::memcpy(&bin_length, whole.data() + bin, 4);
  EXPECT_EQ(bin + 8 + bin_length, whole.size());
  EXPECT_EQ(std::memcmp(whole.data() + bin + 8, mesh.vertices[mesh.faces[0][0]].data(), 12), 0);
  const std::size_t padding = (4 - png->size() % 4) % 4;
  EXPECT_EQ(whole.substr(whole.size() - padding - png->size(), png->size()), *png);
}

}  // namespace
}  // namespace revolve::reconstruct
