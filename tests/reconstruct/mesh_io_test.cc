// Writers and readers: round trips, the atomic write, errors that name the file.
#include "reconstruct/io/mesh_io.h"

#include <sys/stat.h>
#include <unistd.h>

#include <fstream>
#include <limits>
#include <random>
#include <utility>

#include <gtest/gtest.h>

#include "reconstruct/hull/marching_cubes.h"
#include "reconstruct/io/writer_support.h"
#include "reconstruct/metrics/metrics.h"

namespace revolve::reconstruct {
namespace {

namespace fs = std::filesystem;

class MeshIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           (std::string("revolve_mesh_io_") + info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::permissions(dir_, fs::perms::owner_all, ec);
    fs::remove_all(dir_, ec);
  }

  // A closed mesh with irregular coordinates (a blob from random edge crossings).
  static Mesh Blob(bool colors) {
    BitVolume field({6, 5, 4});
    std::mt19937 rng(9);
    for (int k = 0; k < 4; ++k) {
      for (int j = 0; j < 5; ++j) {
        for (int i = 0; i < 6; ++i) field.Set(i, j, k, (rng() % 3) != 0);
      }
    }
    std::uniform_real_distribution<double> t(0.01, 0.99);
    Mesh mesh = MarchingCubes(field, Eigen::Vector3d(-12.345, 6.789, 0.1), 0.731,
                              [&](const std::vector<GridEdge>& edges) {
                                std::vector<double> ts;
                                for (std::size_t i = 0; i < edges.size(); ++i) ts.push_back(t(rng));
                                return ts;
                              });
    if (colors) {
      for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        mesh.colors.emplace_back(static_cast<std::uint8_t>(i * 7),
                                 static_cast<std::uint8_t>(255 - i),
                                 static_cast<std::uint8_t>(i * 13 + 1));
      }
    }
    return mesh;
  }

  // `tolerance_mm` 0: bit-exact vertices (binary formats); text formats keep 4 decimals.
  static void ExpectEqualMeshes(const Mesh& a, const Mesh& b, float tolerance_mm = 0.0f) {
    ASSERT_EQ(a.vertices.size(), b.vertices.size());
    ASSERT_EQ(a.faces.size(), b.faces.size());
    ASSERT_EQ(a.colors.size(), b.colors.size());
    for (std::size_t i = 0; i < a.vertices.size(); ++i) {
      if (tolerance_mm == 0.0f) {
        ASSERT_EQ(a.vertices[i], b.vertices[i]) << "vertex " << i;
      } else {
        ASSERT_LE((a.vertices[i] - b.vertices[i]).cwiseAbs().maxCoeff(), tolerance_mm)
            << "vertex " << i;
      }
    }
    for (std::size_t i = 0; i < a.faces.size(); ++i) ASSERT_EQ(a.faces[i], b.faces[i]);
    for (std::size_t i = 0; i < a.colors.size(); ++i) ASSERT_EQ(a.colors[i], b.colors[i]);
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

TEST_F(MeshIoTest, PlyRoundTripWithoutColours) {
  const Mesh mesh = Blob(false);
  ASSERT_GT(mesh.faces.size(), 20u);
  ASSERT_TRUE(WritePly(mesh, dir_ / "m.ply").has_value());
  std::ifstream in(dir_ / "m.ply", std::ios::binary);
  std::string head(64, '\0');
  in.read(head.data(), 64);
  EXPECT_TRUE(head.starts_with("ply\nformat binary_little_endian 1.0\n"));
  const Expected<Mesh> back = ReadPly(dir_ / "m.ply");
  ASSERT_TRUE(back.has_value()) << back.error().ToString();
  ExpectEqualMeshes(mesh, *back);
  // Size: header + 12 bytes per vertex + 13 bytes per face.
  const auto size = fs::file_size(dir_ / "m.ply");
  EXPECT_GT(size, 12 * mesh.vertices.size() + 13 * mesh.faces.size());
  EXPECT_LT(size, 12 * mesh.vertices.size() + 13 * mesh.faces.size() + 400);
  EXPECT_EQ(Listing(), std::vector<std::string>{"m.ply"});
}

TEST_F(MeshIoTest, PlyRoundTripWithColours) {
  const Mesh mesh = Blob(true);
  ASSERT_TRUE(mesh.HasColors());
  ASSERT_TRUE(WritePly(mesh, dir_ / "c.ply").has_value());
  const Expected<Mesh> back = ReadPly(dir_ / "c.ply");
  ASSERT_TRUE(back.has_value()) << back.error().ToString();
  ExpectEqualMeshes(mesh, *back);
}

TEST_F(MeshIoTest, ReadsAsciiPly) {
  std::ofstream(dir_ / "a.ply") << "ply\nformat ascii 1.0\ncomment hand made\n"
                                   "element vertex 4\nproperty double x\nproperty double y\n"
                                   "property double z\nproperty uchar red\nproperty uchar green\n"
                                   "property uchar blue\nproperty float confidence\n"
                                   "element face 1\nproperty list uchar uint vertex_index\n"
                                   "end_header\n"
                                   "0 0 0 255 0 0 1\n1 0 0 0 255 0 1\n1 1 0 0 0 255 1\n"
                                   "0 1 0.5 9 9 9 1\n4 0 1 2 3\n";
  const Expected<Mesh> mesh = ReadPly(dir_ / "a.ply");
  ASSERT_TRUE(mesh.has_value()) << mesh.error().ToString();
  ASSERT_EQ(mesh->vertices.size(), 4u);
  ASSERT_EQ(mesh->faces.size(), 2u);  // the quad, fanned
  EXPECT_EQ(mesh->faces[1], Eigen::Vector3i(0, 2, 3));
  EXPECT_EQ(mesh->vertices[3], Eigen::Vector3f(0, 1, 0.5f));
  ASSERT_TRUE(mesh->HasColors());
  EXPECT_EQ(mesh->colors[2], Color(0, 0, 255));
}

TEST_F(MeshIoTest, VrmlRoundTrip) {
  for (bool colors : {false, true}) {
    SCOPED_TRACE(colors ? "with colours" : "without colours");
    const Mesh mesh = Blob(colors);
    const fs::path path = dir_ / (colors ? "c.wrl" : "m.wrl");
    ASSERT_TRUE(WriteVrml(mesh, path).has_value());
    std::ifstream in(path);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_TRUE(text.starts_with("#VRML V2.0 utf8\n"));
    for (const char* part :
         {"Shape {", "appearance Appearance", "material Material", "geometry IndexedFaceSet",
          "solid TRUE", "coord Coordinate", "point [", "coordIndex [", "NavigationInfo"}) {
      EXPECT_NE(text.find(part), std::string::npos) << part;
    }
    EXPECT_EQ(text.find("colorPerVertex TRUE") != std::string::npos, colors);
    const Expected<Mesh> back = ReadVrml(path);
    ASSERT_TRUE(back.has_value()) << back.error().ToString();
    ExpectEqualMeshes(mesh, *back, 5.1e-5f);
  }
}

TEST_F(MeshIoTest, WriteModelWritesEveryFormat) {
  const Mesh mesh = Blob(false);
  const Expected<std::vector<fs::path>> paths = WriteModel(mesh, dir_, "model", {"ply", "wrl"});
  ASSERT_TRUE(paths.has_value()) << paths.error().ToString();
  EXPECT_EQ(*paths, (std::vector<fs::path>{dir_ / "model.ply", dir_ / "model.wrl"}));
  EXPECT_EQ(Listing(), (std::vector<std::string>{"model.ply", "model.wrl"}));
  ASSERT_TRUE(ReadPly(dir_ / "model.ply").has_value());
  ASSERT_TRUE(ReadVrml(dir_ / "model.wrl").has_value());
  // Overwriting an existing model replaces it.
  ASSERT_TRUE(WriteModel(Blob(true), dir_, "model", {"ply"}).has_value());
  EXPECT_TRUE(ReadPly(dir_ / "model.ply")->HasColors());

  const Expected<std::vector<fs::path>> bad = WriteModel(mesh, dir_, "x", {"ply", "fbx"});
  ASSERT_FALSE(bad.has_value());
  EXPECT_EQ(bad.error().code, ErrorCode::kBadInput);
  EXPECT_NE(bad.error().message.find("fbx"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir_ / "x.ply"));
}

TEST_F(MeshIoTest, FailedWriteNamesThePathAndLeavesNoTemporaryFile) {
  const Mesh mesh = Blob(false);
  // Missing directory.
  const fs::path missing = dir_ / "no" / "such" / "model.ply";
  Expected<void> result = WritePly(mesh, missing);
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kIo);
  EXPECT_NE(result.error().message.find(missing.string()), std::string::npos)
      << result.error().message;
  const Expected<std::vector<fs::path>> model = WriteModel(mesh, dir_ / "nope", "m", {"wrl"});
  ASSERT_FALSE(model.has_value());
  EXPECT_NE(model.error().message.find((dir_ / "nope" / "m.wrl").string()), std::string::npos);

  // The target is a directory: the temporary file is written, the rename fails, and the
  // temporary file is removed.
  fs::create_directory(dir_ / "taken.wrl");
  fs::create_directory(dir_ / "taken.wrl" / "inside");
  result = WriteVrml(mesh, dir_ / "taken.wrl");
  ASSERT_FALSE(result.has_value());
  EXPECT_NE(result.error().message.find((dir_ / "taken.wrl").string()), std::string::npos);
  EXPECT_EQ(Listing(), std::vector<std::string>{"taken.wrl"});

  // A directory we may not write into (permissions do not stop root).
  if (::geteuid() != 0) {
    fs::create_directory(dir_ / "ro");
    fs::permissions(dir_ / "ro", fs::perms::owner_read | fs::perms::owner_exec);
    result = WritePly(mesh, dir_ / "ro" / "m.ply");
    ASSERT_FALSE(result.has_value());
    EXPECT_NE(result.error().message.find((dir_ / "ro" / "m.ply").string()), std::string::npos);
    fs::permissions(dir_ / "ro", fs::perms::owner_all);
    EXPECT_TRUE(fs::is_empty(dir_ / "ro"));
  }
}

TEST_F(MeshIoTest, AtomicFileWritesLargeContentExactly) {
  // Several times the write buffer, not a whole number of blocks, and the three ways in (a small
  // Append, items built in place, a large Append): every byte arrives, in order.
  std::mt19937 rng(5);
  std::string large(3 * (1 << 20) + 12345, '\0');
  for (char& c : large) c = static_cast<char>(rng());
  std::string expected = "header\n";
  for (std::size_t i = 0; i < 200000; ++i) {
    expected += std::to_string(i) + ' ';
  }
  expected += large;
  AtomicFile file(dir_ / "big.bin");
  ASSERT_TRUE(file.Open().has_value());
  file.Append("header\n");
  file.PutEach(200000, internal::kMaxNumberChars, [](char* p, std::size_t i) {
    p = internal::WriteInt(p, static_cast<long long>(i));
    *p = ' ';
    return p + 1;
  });
  file.Append(large);
  ASSERT_TRUE(file.Commit().has_value());
  std::ifstream in(dir_ / "big.bin", std::ios::binary);
  const std::string back((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(back.size(), expected.size());
  EXPECT_TRUE(back == expected);
  EXPECT_EQ(Listing(), std::vector<std::string>{"big.bin"});
}

TEST_F(MeshIoTest, ReadErrorsNameTheFile) {
  Expected<Mesh> mesh = ReadPly(dir_ / "absent.ply");
  ASSERT_FALSE(mesh.has_value());
  EXPECT_EQ(mesh.error().code, ErrorCode::kNotFound);
  EXPECT_NE(mesh.error().message.find("absent.ply"), std::string::npos);

  std::ofstream(dir_ / "junk.ply") << "this is not a mesh\n";
  mesh = ReadPly(dir_ / "junk.ply");
  ASSERT_FALSE(mesh.has_value());
  EXPECT_EQ(mesh.error().code, ErrorCode::kBadInput);
  EXPECT_NE(mesh.error().message.find("junk.ply"), std::string::npos);

  // Truncated binary body.
  ASSERT_TRUE(WritePly(Blob(false), dir_ / "t.ply").has_value());
  fs::resize_file(dir_ / "t.ply", fs::file_size(dir_ / "t.ply") - 5);
  mesh = ReadPly(dir_ / "t.ply");
  ASSERT_FALSE(mesh.has_value());
  EXPECT_NE(mesh.error().message.find("truncated"), std::string::npos);

  // Face index out of range.
  std::ofstream(dir_ / "idx.ply") << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                     "property float y\nproperty float z\nelement face 1\n"
                                     "property list uchar int vertex_indices\nend_header\n"
                                     "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n";
  mesh = ReadPly(dir_ / "idx.ply");
  ASSERT_FALSE(mesh.has_value());
  EXPECT_EQ(mesh.error().code, ErrorCode::kBadInput);

  std::ofstream(dir_ / "junk.wrl") << "#VRML V1.0 ascii\n";
  mesh = ReadVrml(dir_ / "junk.wrl");
  ASSERT_FALSE(mesh.has_value());
  EXPECT_NE(mesh.error().message.find("junk.wrl"), std::string::npos);
}

TEST(TextNumbers, IntegersAndIndexTextsMatchToString) {
  auto written = [](long long value) {
    char buffer[internal::kMaxNumberChars];
    return std::string(buffer, internal::WriteInt(buffer, value));
  };
  for (const long long value :
       {0LL, 9LL, 10LL, 9999LL, 10000LL, 12345678LL, 99999999LL, 100000000LL, -1LL, -10000LL,
        std::numeric_limits<long long>::max(), std::numeric_limits<long long>::min()}) {
    EXPECT_EQ(written(value), std::to_string(value));
  }
  // The writers' vertex index texts: made in runs of 10^4, formatted on the spot outside the
  // table and when the table would need 8 digits or a sign.
  for (const auto& [first, count] :
       std::vector<std::pair<int, int>>{{0, 123457}, {1, 20001}, {9999990, 20}, {-3, 10}}) {
    const internal::IndexTexts texts(first, static_cast<std::size_t>(count));
    for (int i = -2; i < count + 2; ++i) {
      char buffer[internal::kMaxNumberChars];
      ASSERT_EQ(std::string(buffer, texts.Write(buffer, i)), std::to_string(first + i))
          << first << " + " << i;
    }
  }
}

TEST(TextNumbers, FixedDecimalsRoundHalfAwayFromZeroAndDropTrailingZeros) {
  // The text writers' numbers: value * 10^decimals rounded as std::round does (ties away from
  // zero: coordinates on multiples of 1/32 mm are ties at 4 decimals), trailing zeros dropped.
  auto reference = [](float value, int decimals) {
    long long scale = 1;
    for (int d = 0; d < decimals; ++d) scale *= 10;
    const double rounded = std::round(static_cast<double>(value) * static_cast<double>(scale));
    const auto magnitude = static_cast<unsigned long long>(std::abs(rounded));
    std::string text = (rounded < 0.0 && magnitude > 0) ? "-" : "";
    text += std::to_string(magnitude / scale);
    std::string fraction = decimals > 0 ? std::to_string(magnitude % scale) : "";
    fraction.insert(0, static_cast<std::size_t>(decimals) - fraction.size(), '0');
    while (!fraction.empty() && fraction.back() == '0') fraction.pop_back();
    if (!fraction.empty()) text += "." + fraction;
    return text;
  };
  auto written = [](float value, int decimals) {
    char buffer[internal::kMaxNumberChars];
    return std::string(buffer, internal::WriteFixed(buffer, value, decimals));
  };
  std::vector<float> values = {0.0f,     -0.0f,       0.03125f,   -0.03125f, 0.3125f,
                               1.00005f, 5e-5f,       4.9999e-5f, 0.5f,      123.45675f,
                               -60.0f,   0.49999997f, 9.99995f};
  for (int k = -4096; k <= 4096; ++k) values.push_back(static_cast<float>(k) / 64.0f);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> coordinate(-500.0f, 500.0f);
  std::uniform_real_distribution<float> small(-1e-3f, 1e-3f);
  for (int i = 0; i < 200000; ++i) {
    values.push_back(coordinate(rng));
    values.push_back(small(rng));
  }
  for (const int decimals : {0, 3, 4, 6}) {
    for (const float value : values) {
      ASSERT_EQ(written(value, decimals), reference(value, decimals))
          << "value " << value << " with " << decimals << " decimals";
    }
  }
  EXPECT_EQ(written(0.03125f, 4), "0.0313");
  EXPECT_EQ(written(-0.03125f, 4), "-0.0313");
  EXPECT_EQ(written(-0.00001f, 4), "0");
  EXPECT_EQ(written(12.5f, 4), "12.5");
}

}  // namespace
}  // namespace revolve::reconstruct
