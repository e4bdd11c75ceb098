// The reconstruction on all cores gives what it gives on one (reconstruct/parallel.h): every
// model file the same bytes, the same metrics; and the silhouette rasteriser's runs equal testing
// every pixel.
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "base/png_encode.h"
#include "reconstruct/cameras/views.h"
#include "reconstruct/hull/marching_cubes.h"
#include "reconstruct/hull/silhouette_consensus.h"
#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/io/model_writer.h"
#include "reconstruct/io/writer_support.h"
#include "reconstruct/metrics/metrics.h"
#include "reconstruct/metrics/reprojection.h"
#include "reconstruct/parallel.h"
#include "reconstruct/reconstructor.h"
#include "reconstruct/texture/texture.h"
#include "reconstruct/texture/texture_internal.h"
#include "reconstruct/union_find.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

namespace fs = std::filesystem;

// RenderSilhouette as it was written first: every pixel centre of each face's bounding
// rectangle tested against the three edges.
cv::Mat SilhouetteByEveryPixel(const Mesh& mesh, const View& view) {
  const auto cross2 = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() * b.y() - a.y() * b.x();
  };
  cv::Mat out(view.height_px, view.width_px, CV_8UC1, cv::Scalar(0));
  std::vector<Eigen::Vector2d> projected(mesh.vertices.size());
  std::vector<std::uint8_t> visible(mesh.vertices.size(), 0);
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    visible[i] = view.Project(mesh.vertices[i].cast<double>(), &projected[i]) ? 1 : 0;
  }
  for (const Eigen::Vector3i& face : mesh.faces) {
    if (!visible[face[0]] || !visible[face[1]] || !visible[face[2]]) continue;
    const Eigen::Vector2d& p0 = projected[face[0]];
    const Eigen::Vector2d& p1 = projected[face[1]];
    const Eigen::Vector2d& p2 = projected[face[2]];
    const double area = cross2(p1 - p0, p2 - p0);
    if (area == 0.0 || !std::isfinite(area)) continue;
    const double sign = area > 0.0 ? 1.0 : -1.0;
    const int u0 = std::max(0, static_cast<int>(std::ceil(std::min({p0.x(), p1.x(), p2.x()}))));
    const int u1 = std::min(view.width_px - 1,
                            static_cast<int>(std::floor(std::max({p0.x(), p1.x(), p2.x()}))));
    const int v0 = std::max(0, static_cast<int>(std::ceil(std::min({p0.y(), p1.y(), p2.y()}))));
    const int v1 = std::min(view.height_px - 1,
                            static_cast<int>(std::floor(std::max({p0.y(), p1.y(), p2.y()}))));
    for (int v = v0; v <= v1; ++v) {
      for (int u = u0; u <= u1; ++u) {
        const Eigen::Vector2d p(u, v);
        if (sign * cross2(p1 - p0, p - p0) >= 0.0 && sign * cross2(p2 - p1, p - p1) >= 0.0 &&
            sign * cross2(p0 - p2, p - p2) >= 0.0) {
          out.at<std::uint8_t>(v, u) = 255;
        }
      }
    }
  }
  return out;
}

// A small scan: a sphere (r = 40 mm) seen by `views` cameras 20 degrees above it, 320 x 240,
// analytic silhouettes and frames of coloured stripes.
struct SmallScan {
  VoxelGrid grid;
  std::vector<cv::Mat> images, masks;
  std::vector<View> views;
};

SmallScan MakeScan(int views) {
  SmallScan scan;
  scan.grid = *VoxelGrid::FromBox({-60, -60, 0}, {60, 60, 120}, 96);
  const Rig rig = testing::StationRig(450.0, 20.0, 40.0, 320, 240);
  for (int k = 0; k < views; ++k) {
    const double angle = 360.0 * k / views;
    scan.masks.push_back(testing::SphereMask(rig, angle, testing::Sphere{}));
    cv::Mat image(240, 320, CV_8UC3);
    for (int v = 0; v < image.rows; ++v) {
      for (int u = 0; u < image.cols; ++u) {
        image.at<cv::Vec3b>(v, u) = cv::Vec3b(static_cast<std::uint8_t>(u * 7 + k * 31),
                                              static_cast<std::uint8_t>(v * 5 + u),
                                              static_cast<std::uint8_t>((u / 8 + v / 8) % 2 * 200));
      }
    }
    scan.images.push_back(image);
    scan.views.push_back(testing::ViewOf(rig, angle));
  }
  return scan;
}

std::string Bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

// Everything the live finish makes, with at most `threads` threads: file name -> bytes, plus
// the metrics as text.
std::map<std::string, std::string> Finish(const SmallScan& scan, int threads, const fs::path& dir) {
  const ThreadLimit limit(threads);
  VisualHull hull(scan.grid);
  for (std::size_t k = 0; k < scan.views.size(); ++k) {
    EXPECT_TRUE(hull.Integrate(scan.masks[k], scan.views[k]));
  }
  HullSurfaceOptions surface;
  surface.clip_below_z_mm = 0.0;
  Mesh mesh = hull.ExtractSurface(surface);
  EXPECT_TRUE(TextureMesh(&mesh, scan.views, scan.images));
  fs::create_directories(dir);
  const Expected<std::vector<fs::path>> files =
      WriteModel(mesh, dir, "model", {"ply", "obj", "stl", "glb", "wrl"});
  EXPECT_TRUE(files);
  std::map<std::string, std::string> result;
  for (const fs::path& file : files.value_or(std::vector<fs::path>{})) {
    result[file.filename().string()] = Bytes(file);
  }
  const ReprojectionStats reprojection = SilhouetteReprojection(mesh, scan.views, scan.masks);
  std::ostringstream metrics;
  metrics.precision(17);
  for (double iou : reprojection.iou) metrics << iou << " ";
  const MeshStats stats = ComputeStats(mesh);
  metrics << stats.volume_mm3 << " " << stats.area_mm2 << " " << stats.closed << stats.oriented;
  result["metrics"] = metrics.str();
  return result;
}

TEST(Threads, OneThreadAndAllCoresWriteTheSameBytes) {
  const SmallScan scan = MakeScan(18);
  const fs::path dir =
      fs::temp_directory_path() / ("revolve_threads_" + std::to_string(::getpid()));
  const std::map<std::string, std::string> one = Finish(scan, 1, dir / "one");
  const std::map<std::string, std::string> all = Finish(scan, 8, dir / "all");
  // ./run test compares these files between the default build and the portable one
  // (REVOLVE_PORTABLE): the SIMD paths promise the same values.
  if (const char* keep = std::getenv("REVOLVE_THREADS_TEST_MODEL_DIR"); keep != nullptr) {
    fs::create_directories(keep);
    for (const auto& [name, bytes] : one)
      std::ofstream(fs::path(keep) / name, std::ios::binary) << bytes;
  }
  fs::remove_all(dir);
  ASSERT_EQ(one.size(), 8u);  // ply, obj, mtl, png, stl, glb, wrl and the metrics
  for (const auto& [name, bytes] : one) {
    ASSERT_TRUE(all.count(name)) << name;
    EXPECT_GT(bytes.size(), 0u) << name;
    EXPECT_TRUE(bytes == all.at(name)) << name << " differs between 1 thread and all cores";
  }
}

// The live finish as the station makes it: the hull reconstructor telling a ModelWriter of each
// stage of the mesh (the STL written from the surface while the colours are made, the PLY and
// VRML from the colours while the atlas is made, ...). Every file is the same bytes as
// WriteModel's of the finished mesh, and as the one-thread finish above, on one thread and on
// all cores.
TEST(Threads, FilesWrittenWhileTheMeshIsMadeAreWriteModelsBytes) {
  const SmallScan scan = MakeScan(18);
  const fs::path dir =
      fs::temp_directory_path() / ("revolve_threads_staged_" + std::to_string(::getpid()));
  const std::map<std::string, std::string> reference = Finish(scan, 1, dir / "reference");
  const std::vector<std::string> formats = {"ply", "obj", "stl", "glb", "wrl"};
  for (const int threads : {1, 8}) {
    SCOPED_TRACE(::testing::Message() << threads << " threads");
    const ThreadLimit limit(threads);
    ReconstructOptions options;
    options.bbox_min_mm = {-60, -60, 0};
    options.bbox_max_mm = {60, 60, 120};
    options.resolution = 96;
    std::unique_ptr<Reconstructor> reconstructor = Create(options).value();
    for (std::size_t k = 0; k < scan.views.size(); ++k) {
      ASSERT_TRUE(reconstructor->Integrate(scan.masks[k], scan.images[k], scan.views[k]));
    }
    const fs::path staged = dir / ("staged" + std::to_string(threads));
    const fs::path after = dir / ("after" + std::to_string(threads));
    fs::create_directories(staged);
    fs::create_directories(after);
    Mesh mesh;
    std::vector<MeshStage> stages;
    Expected<std::unique_ptr<ModelWriter>> writer =
        ModelWriter::Start(mesh, staged, "model", formats);
    ASSERT_TRUE(writer);
    ASSERT_TRUE(reconstructor->FinishStaged(&mesh, [&](MeshStage stage) {
      stages.push_back(stage);
      (*writer)->Reached(stage);
    }));
    EXPECT_EQ(stages, (std::vector<MeshStage>{MeshStage::kSurface, MeshStage::kColors,
                                              MeshStage::kUvs, MeshStage::kDone}));
    const Expected<std::vector<fs::path>> files = (*writer)->Finish();
    ASSERT_TRUE(files) << files.error().ToString();
    const Expected<std::vector<fs::path>> again = WriteModel(mesh, after, "model", formats);
    ASSERT_TRUE(again);
    ASSERT_EQ(files->size(), 7u);  // ply, obj, mtl, png, stl, glb, wrl
    ASSERT_EQ(again->size(), files->size());
    for (std::size_t i = 0; i < files->size(); ++i) {
      const std::string name = (*files)[i].filename().string();
      EXPECT_EQ(name, (*again)[i].filename().string());
      const std::string bytes = Bytes((*files)[i]);
      EXPECT_GT(bytes.size(), 0u) << name;
      EXPECT_TRUE(bytes == Bytes((*again)[i])) << name << " differs from WriteModel's";
      EXPECT_TRUE(bytes == reference.at(name)) << name << " differs from the one-thread finish";
    }
  }
  fs::remove_all(dir);
}

// The silhouette consensus (one carve per view, the leave-one-out hulls on all cores): the same
// agreements and cut masks on one thread as on all cores.
TEST(Threads, ConsensusIsTheSameOnOneThreadAndAllCores) {
  SmallScan scan = MakeScan(12);
  cv::rectangle(scan.masks[4], cv::Rect(0, 200, 320, 40), cv::Scalar(255), cv::FILLED);  // a stand
  const auto run = [&](int threads) {
    const ThreadLimit limit(threads);
    return ConsensusOfSilhouettes(scan.masks, scan.views, {-60, -60, 0}, {60, 60, 120});
  };
  const Expected<SilhouetteConsensus> one = run(1);
  const Expected<SilhouetteConsensus> all = run(8);
  ASSERT_TRUE(one && all);
  EXPECT_EQ(one->agreement, all->agreement);
  EXPECT_LT(one->agreement[4], one->agreement[3]);
  for (std::size_t i = 0; i < scan.masks.size(); ++i) {
    EXPECT_EQ(cv::countNonZero(one->CutMask(i) != all->CutMask(i)), 0) << i;
  }
  EXPECT_LT(cv::countNonZero(one->masks[4]), cv::countNonZero(scan.masks[4]));  // the stand cut
}

// `reconstruct --images` hands the consensus each mask as its window: the same agreements and
// cut masks as the whole masks, for tight windows, loose ones reaching the image's edge, and an
// empty mask's whole image; a window outside its view's image is refused.
TEST(Threads, ConsensusOfWindowsIsTheWholeMasks) {
  SmallScan scan = MakeScan(12);
  cv::rectangle(scan.masks[4], cv::Rect(0, 200, 320, 40), cv::Scalar(255), cv::FILLED);  // a stand
  scan.masks[7].setTo(0);                                                                // empty
  std::vector<cv::Mat> windows;
  std::vector<cv::Point> origins;
  for (std::size_t i = 0; i < scan.masks.size(); ++i) {
    cv::Rect window = cv::boundingRect(scan.masks[i]);
    if (window.empty()) window = cv::Rect(0, 0, scan.masks[i].cols, scan.masks[i].rows);
    if (i % 3 == 1) {  // loose, to the image's edges
      window = cv::Rect(window.x - 50, window.y - 3, window.width + 400, window.height + 9) &
               cv::Rect(0, 0, scan.masks[i].cols, scan.masks[i].rows);
    }
    windows.push_back(scan.masks[i](window).clone());
    origins.push_back(window.tl());
  }
  const Expected<SilhouetteConsensus> whole =
      ConsensusOfSilhouettes(scan.masks, scan.views, {-60, -60, 0}, {60, 60, 120});
  const Expected<SilhouetteConsensus> held =
      ConsensusOfSilhouettes(windows, scan.views, {-60, -60, 0}, {60, 60, 120}, {}, origins);
  ASSERT_TRUE(whole && held) << (held ? "" : held.error().ToString());
  EXPECT_EQ(whole->agreement, held->agreement);
  for (std::size_t i = 0; i < scan.masks.size(); ++i) {
    EXPECT_EQ(whole->cut_roi[i], held->cut_roi[i]) << i;
    EXPECT_EQ(cv::countNonZero(whole->CutMask(i) != held->CutMask(i)), 0) << i;
  }
  origins[2].x = scan.masks[2].cols - windows[2].cols + 1;  // one pixel past the right edge
  EXPECT_FALSE(
      ConsensusOfSilhouettes(windows, scan.views, {-60, -60, 0}, {60, 60, 120}, {}, origins));
}

// The atlas's PNG is encoded in bands of rows on all cores: any image, as many bands as it
// takes (one row, a band's edge, many), decodes to its own pixels, and one thread makes the same
// bytes.
TEST(Threads, PngOfEveryShapeDecodesToItsPixelsInTheSameBytes) {
  std::mt19937 random(11);
  std::uniform_int_distribution<int> byte(0, 255);
  const struct {
    int width, height, type;
  } kShapes[] = {{1, 1, CV_8UC3},   {5, 1, CV_8UC3},     {1, 40, CV_8UC3},   {17, 32, CV_8UC3},
                 {64, 33, CV_8UC3}, {640, 257, CV_8UC3}, {123, 95, CV_8UC1}, {1024, 70, CV_8UC3}};
  for (const auto& shape : kShapes) {
    SCOPED_TRACE(::testing::Message() << shape.width << "x" << shape.height);
    cv::Mat image(shape.height, shape.width, shape.type);
    // Noise, flat runs and a gradient: every filter case and long runs.
    for (int v = 0; v < image.rows; ++v) {
      auto* row = image.ptr<std::uint8_t>(v);
      for (int i = 0; i < image.cols * image.channels(); ++i) {
        row[i] = v % 3 == 0   ? static_cast<std::uint8_t>(byte(random))
                 : v % 3 == 1 ? std::uint8_t{0}
                              : static_cast<std::uint8_t>(i + v);
      }
    }
    const Expected<std::string> all = EncodePng(image);
    ASSERT_TRUE(all);
    Expected<std::string> one = std::string();
    {
      const ThreadLimit limit(1);
      one = EncodePng(image);
    }
    ASSERT_TRUE(one);
    EXPECT_TRUE(*one == *all) << "the PNG differs between 1 thread and all cores";
    const cv::Mat decoded = cv::imdecode(
        cv::Mat(1, static_cast<int>(all->size()), CV_8UC1, const_cast<char*>(all->data())),
        cv::IMREAD_UNCHANGED);
    ASSERT_EQ(decoded.size(), image.size());
    ASSERT_EQ(decoded.type(), image.type());
    EXPECT_EQ(cv::norm(decoded, image, cv::NORM_INF), 0.0);
  }
  // Anything but 8-bit grey or BGR is refused, not written wrongly.
  EXPECT_FALSE(EncodePng(cv::Mat(4, 4, CV_16UC3, cv::Scalar(1))));
  EXPECT_FALSE(EncodePng(cv::Mat()));
}

// Marching cubes polygonises slabs of layers on all cores and joins them: any slab height gives
// the mesh one sweep over every layer gives, vertex numbers and triangle order included.
TEST(Threads, MarchingCubesInSlabsIsOneSweep) {
  std::mt19937 random(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Vector3i dims(37, 29, 41);
  BitVolume field(dims);
  // Two overlapping balls, a thin slab through them, and noise: holes, islands, thin walls.
  for (int k = 0; k < dims.z(); ++k) {
    for (int j = 0; j < dims.y(); ++j) {
      for (int i = 0; i < dims.x(); ++i) {
        const double a = Eigen::Vector3d(i - 14, j - 14, k - 15).norm();
        const double b = Eigen::Vector3d(i - 24, j - 15, k - 26).norm();
        const bool inside = a < 11.0 || b < 9.0 || (k == 20 && i > 3) || unit(random) < 0.03;
        field.Set(i, j, k, inside && unit(random) > 0.02);
      }
    }
  }
  MarchingCubesOptions options;
  options.keep_largest_component = false;
  options.slab_layers = dims.z() + 1;  // one slab: the sweep
  const Mesh sweep = MarchingCubes(field, Eigen::Vector3d(1, 2, 3), 0.5, {}, options);
  ASSERT_GT(sweep.faces.size(), 1000u);
  for (const int slab_layers : {1, 2, 3, 16, 0}) {
    SCOPED_TRACE(slab_layers);
    options.slab_layers = slab_layers;
    const Mesh slabs = MarchingCubes(field, Eigen::Vector3d(1, 2, 3), 0.5, {}, options);
    ASSERT_EQ(slabs.vertices.size(), sweep.vertices.size());
    ASSERT_EQ(slabs.faces.size(), sweep.faces.size());
    EXPECT_TRUE(slabs.vertices == sweep.vertices);
    EXPECT_TRUE(slabs.faces == sweep.faces);
  }
}

// Faces on a strip of `rows` x `cols` squares, two triangles each, with random candidate views
// (of 4) and cosines (some unseen): islands and ragged borders for the labels to smooth.
struct RandomLabelling {
  std::vector<float> face_cos;
  std::vector<texture_internal::Candidates> candidates;
  std::vector<std::array<int, 3>> neighbours;
};
RandomLabelling MakeRandomLabelling(int rows, int cols, unsigned seed) {
  using texture_internal::kCandidates;
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  RandomLabelling out;
  const int nf = 2 * rows * cols;
  out.candidates.resize(nf);
  out.face_cos.assign(static_cast<std::size_t>(nf) * kCandidates, -2.0f);
  out.neighbours.assign(nf, {-1, -1, -1});
  auto face = [cols](int r, int c, int half) { return 2 * (r * cols + c) + half; };
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      // Lower half: left, bottom, diagonal; upper half: right, top, diagonal.
      out.neighbours[face(r, c, 0)] = {c > 0 ? face(r, c - 1, 1) : -1,
                                       r > 0 ? face(r - 1, c, 1) : -1, face(r, c, 1)};
      out.neighbours[face(r, c, 1)] = {c + 1 < cols ? face(r, c + 1, 0) : -1,
                                       r + 1 < rows ? face(r + 1, c, 0) : -1, face(r, c, 0)};
    }
  }
  for (int i = 0; i < nf; ++i) {
    // Views drift along the strip, so that neighbours mostly share them.
    const int base = (i / (2 * cols) / 7 + i % (2 * cols) / 9) % 4;
    for (int s = 0; s < kCandidates; ++s) {
      out.candidates[i].Insert(0.9f - 0.05f * static_cast<float>(s) + 0.03f * unit(random),
                               (base + s) % 4);
    }
    for (int s = 0; s < kCandidates; ++s) {
      if (unit(random) < 0.8f) out.face_cos[i * kCandidates + s] = out.candidates[i].score[s];
    }
  }
  return out;
}

// LabelFaces as it was first written: every face in every pass.
std::vector<int> LabelFacesEveryPass(const RandomLabelling& in) {
  using texture_internal::kCandidates;
  const int nf = static_cast<int>(in.candidates.size());
  std::vector<int> label(nf, -1);
  for (int i = 0; i < nf; ++i) {
    float best = -2.0f;
    for (int s = 0; s < kCandidates; ++s) {
      if (in.face_cos[i * kCandidates + s] > best) {
        best = in.face_cos[i * kCandidates + s];
        label[i] = in.candidates[i].view[s];
      }
    }
  }
  std::vector<int> next(nf);
  for (int pass = 0; pass < texture_internal::kSmoothingPasses; ++pass) {
    for (int i = 0; i < nf; ++i) {
      next[i] = label[i];
      float best = -std::numeric_limits<float>::infinity();
      for (int s = 0; s < kCandidates; ++s) {
        const float c = in.face_cos[i * kCandidates + s];
        if (c <= -2.0f) continue;
        float score = c;
        for (int nb : in.neighbours[i]) {
          if (nb >= 0 && label[nb] == in.candidates[i].view[s]) {
            score += texture_internal::kNeighbourBonus;
          }
        }
        if (score > best) {
          best = score;
          next[i] = in.candidates[i].view[s];
        }
      }
    }
    label.swap(next);
  }
  return label;
}

TEST(Threads, LabelsLookingAgainOnlyNextToChangesEqualEveryPass) {
  for (const unsigned seed : {1u, 2u, 3u}) {
    SCOPED_TRACE(seed);
    const RandomLabelling in = MakeRandomLabelling(120, 170, seed);
    const std::vector<int> expected = LabelFacesEveryPass(in);
    EXPECT_EQ(texture_internal::LabelFaces(in.face_cos, in.candidates, in.neighbours), expected);
    const ThreadLimit one(1);
    EXPECT_EQ(texture_internal::LabelFaces(in.face_cos, in.candidates, in.neighbours), expected);
  }
}

TEST(Threads, ChartsAreTheConnectedFacesOfAView) {
  // 60000 faces: GroupCharts' union-find works in chunks of 32768, and joins across them after.
  RandomLabelling in = MakeRandomLabelling(200, 150, 4);
  // A few one-way neighbours (a face naming one that does not name it back) must join too, in a
  // chunk and across chunks.
  in.neighbours[100][0] = 5000;
  in.neighbours[7000][1] = 30;
  in.neighbours[40000][0] = 20;
  in.neighbours[90][1] = 50000;
  std::vector<int> label = texture_internal::LabelFaces(in.face_cos, in.candidates, in.neighbours);
  label[100] = label[5000] = 2;
  label[30] = label[7000] = 1;
  label[40000] = label[20] = 3;
  label[90] = label[50000] = 0;
  const int nf = static_cast<int>(label.size());
  // Every pair, both ways: the reference sets.
  UnionFind sets(nf);
  for (int i = 0; i < nf; ++i) {
    for (int nb : in.neighbours[i]) {
      if (nb >= 0 && label[i] >= 0 && label[nb] == label[i]) sets.Unite(i, nb);
    }
  }
  const texture_internal::Charts charts = texture_internal::GroupCharts(label, in.neighbours);
  ASSERT_GT(charts.count, 10);
  for (int c = 0; c < charts.count; ++c) {
    const int first = charts.faces[charts.start[c]];
    EXPECT_EQ(charts.view[c], label[first]);
    for (int k = charts.start[c]; k < charts.start[c + 1]; ++k) {
      EXPECT_EQ(sets.Find(charts.faces[k]), sets.Find(first));
    }
    // Numbered by their first faces: a chart's first face is its set's smallest.
    EXPECT_EQ(sets.Find(first), first);
    if (c > 0) {
      EXPECT_LT(charts.faces[charts.start[c - 1]], first);
    }
  }
  EXPECT_EQ(charts.start[charts.count + 1], nf);
}

TEST(Threads, ThreadLimitBoundsTheLoops) {
  {
    const ThreadLimit limit(1);
    EXPECT_EQ(ThreadCount(), 1);
  }
  EXPECT_GE(ThreadCount(), 1);
}

TEST(Threads, SilhouetteRunsEqualTestingEveryPixel) {
  const SmallScan scan = MakeScan(8);
  VisualHull hull(scan.grid);
  for (std::size_t k = 0; k < scan.views.size(); ++k) {
    ASSERT_TRUE(hull.Integrate(scan.masks[k], scan.views[k]));
  }
  std::vector<Mesh> meshes = {hull.ExtractSurface()};
  HullSurfaceOptions midpoints;
  midpoints.sub_voxel = false;
  meshes.push_back(hull.ExtractSurface(midpoints));
  // Random triangles of every size and orientation, slivers, shared edges and vertices on pixel
  // centres.
  std::mt19937 random(7);
  std::uniform_real_distribution<float> coordinate(-70.0f, 70.0f);
  Mesh soup;
  for (int i = 0; i < 3000; ++i) {
    Eigen::Vector3f a(coordinate(random), coordinate(random), coordinate(random) + 60.0f);
    if (i % 7 == 0) a = a.array().round();  // on pixel centres in the thesis view
    const Eigen::Vector3f b = i % 3 == 0 ? a + Eigen::Vector3f(0.01f, 0.0f, 40.0f)
                                         : Eigen::Vector3f(coordinate(random), coordinate(random),
                                                           coordinate(random) + 60.0f);
    const Eigen::Vector3f c = i % 5 == 0 ? a + 0.5f * (b - a) + Eigen::Vector3f(0.0f, 1e-3f, 0.0f)
                                         : Eigen::Vector3f(coordinate(random), coordinate(random),
                                                           coordinate(random) + 60.0f);
    const int first = static_cast<int>(soup.vertices.size());
    soup.vertices.insert(soup.vertices.end(), {a, b, c});
    soup.faces.emplace_back(first, first + 1, first + 2);
  }
  meshes.push_back(soup);
  std::vector<View> views = scan.views;
  views.push_back(ThesisView(320, 240, 30.0));
  for (const Mesh& mesh : meshes) {
    for (const View& view : views) {
      const cv::Mat expected = SilhouetteByEveryPixel(mesh, view);
      const cv::Mat got = RenderSilhouette(mesh, view);
      ASSERT_GT(cv::countNonZero(expected), 0);
      EXPECT_EQ(cv::countNonZero(expected != got), 0);
      // Drawn in its box alone: within the image, every pixel of the silhouette in it.
      const BoxedSilhouette boxed = RenderSilhouetteInBox(mesh, view);
      ASSERT_EQ(boxed.box & cv::Rect(0, 0, view.width_px, view.height_px), boxed.box);
      ASSERT_EQ(boxed.pixels.size(), boxed.box.size());
      EXPECT_EQ(cv::countNonZero(expected(boxed.box) != boxed.pixels), 0);
      EXPECT_EQ(cv::countNonZero(expected(boxed.box)), cv::countNonZero(expected));
    }
  }
}

// A closed, consistently oriented mesh drawn with one winding of faces (`closed`), or filled
// from its outline (SilhouetteReprojection with `closed`), casts the silhouette every face casts:
// hull surfaces (exact and midpoint vertices, a coarse hull) in perspective views around and above
// it and in the thesis's orthographic view.
TEST(Threads, ClosedSilhouetteEqualsEveryFace) {
  const SmallScan scan = MakeScan(8);
  VisualHull hull(scan.grid);
  VisualHull coarse(*VoxelGrid::FromBox({-60, -60, 0}, {60, 60, 120}, 20));
  for (std::size_t k = 0; k < scan.views.size(); ++k) {
    ASSERT_TRUE(hull.Integrate(scan.masks[k], scan.views[k]));
    ASSERT_TRUE(coarse.Integrate(scan.masks[k], scan.views[k]));
  }
  HullSurfaceOptions midpoints;
  midpoints.sub_voxel = false;
  const std::vector<Mesh> meshes = {hull.ExtractSurface(), hull.ExtractSurface(midpoints),
                                    coarse.ExtractSurface(midpoints)};
  std::vector<View> views = MakeScan(7).views;
  for (double angle : {0.0, 30.0, 90.0}) views.push_back(ThesisView(320, 240, angle));
  views.push_back(testing::ViewOf(testing::StationRig(300.0, 70.0, 40.0, 320, 240), 15.0));
  // Masks to score against: the every-face silhouettes themselves (IoU 1 only if the outline
  // fill gives every pixel) and shifted by 3 px; an open mesh (a face left out) is drawn face by
  // face.
  for (const Mesh& mesh : meshes) {
    const MeshStats stats = ComputeStats(mesh);
    ASSERT_TRUE(stats.closed && stats.oriented);
    std::vector<cv::Mat> own;
    for (const View& view : views) {
      const cv::Mat every = RenderSilhouette(mesh, view);
      ASSERT_GT(cv::countNonZero(every), 0);
      EXPECT_EQ(cv::countNonZero(every != RenderSilhouette(mesh, view, /*closed=*/true)), 0);
      own.push_back(every);
    }
    const ReprojectionStats outline = SilhouetteReprojection(mesh, views, own);
    for (std::size_t i = 0; i < views.size(); ++i) EXPECT_EQ(outline.iou[i], 1.0) << i;
    std::vector<cv::Mat> shifted_masks;
    for (std::size_t i = 0; i < views.size(); ++i) {
      cv::Mat shifted = cv::Mat::zeros(own[i].size(), CV_8UC1);
      own[i](cv::Rect(0, 0, own[i].cols - 3, own[i].rows))
          .copyTo(shifted(cv::Rect(3, 0, own[i].cols - 3, own[i].rows)));
      shifted_masks.push_back(shifted);
    }
    const ReprojectionStats a = SilhouetteReprojection(mesh, views, shifted_masks);
    for (std::size_t i = 0; i < views.size(); ++i) {
      EXPECT_EQ(a.iou[i], MaskIoU(own[i], shifted_masks[i])) << i;
    }
    Mesh open = mesh;
    open.faces.pop_back();
    const ReprojectionStats b = SilhouetteReprojection(open, views, shifted_masks);
    for (std::size_t i = 0; i < views.size(); ++i) {
      EXPECT_EQ(b.iou[i], MaskIoU(RenderSilhouette(open, views[i]), shifted_masks[i])) << i;
    }
  }
}

}  // namespace
}  // namespace revolve::reconstruct
