// The reprojection metrics (SilhouetteReprojection, reconstruct/metrics/reprojection.h) on a
// realistic hull: a visual hull at 256^3 of a union of spheres (~420 k triangles, about the size
// of `reconstruct --images`'s model at 256^3), 36 views, on all cores. "search:0" projects and
// signs every face in every view (main's before issue 18's tenth pass); otherwise most faces are
// signed by their planes and only the rest and the outline's ends are projected, one view at a
// time ("search:1", the tenth pass) or 32 views per pass over the faces ("search:2"). Cameras: the
// station's pinhole ring (768 x 576, 20 degrees above) or the thesis's orthographic views
// (1280 x 960, the hull scaled to pixels, as `reconstruct --images` without calibration).
// REVOLVE_BENCH_MESH=model.ply takes that mesh instead (e.g. `reconstruct --images`'s own model:
// it is in the thesis's pixels already), and REVOLVE_BENCH_SIZE=WxH the thesis views' size (its
// photos', e.g. 720x576 for silhouettes of that size; 1280x960 unless said).
#include <cstdio>
#include <cstdlib>

#include <benchmark/benchmark.h>

#include "reconstruct/cameras/views.h"
#include "reconstruct/hull/silhouette_consensus.h"
#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/metrics/metrics.h"
#include "reconstruct/metrics/outline_internal.h"
#include "reconstruct/metrics/reprojection.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

constexpr int kViews = 36;

struct Scene {
  Mesh mesh;
  std::vector<View> views;
  std::vector<cv::Mat> masks;
};

std::vector<testing::Sphere> Spheres() {
  return {{{0.0, 0.0, 45.0}, 42.0},
          {{0.0, 0.0, 95.0}, 22.0},
          {{30.0, 20.0, 60.0}, 18.0},
          {{-28.0, 25.0, 30.0}, 20.0},
          {{10.0, -35.0, 75.0}, 14.0}};
}

Mesh HullMesh() {
  const Rig rig = testing::StationRig(450.0, 20.0, 60.0);
  VisualHull hull(*VoxelGrid::FromBox({-60, -60, 0}, {60, 60, 120}, 256));
  for (int k = 0; k < kViews; ++k) {
    (void)hull.Integrate(testing::SphereMask(rig, 10.0 * k, Spheres()),
                         testing::ViewOf(rig, 10.0 * k));
  }
  HullSurfaceOptions options;
  options.clip_below_z_mm = 0.0;
  return hull.ExtractSurface(options);
}

const Scene& GetScene(bool thesis) {
  static const Mesh mesh = [] {
    const char* path = std::getenv("REVOLVE_BENCH_MESH");
    if (path == nullptr) return HullMesh();
    Expected<Mesh> read = ReadPly(path);
    if (!read) {
      std::fprintf(stderr, "REVOLVE_BENCH_MESH=%s: %s\n", path, read.error().ToString().c_str());
      std::exit(2);
    }
    return *std::move(read);
  }();
  static Scene scenes[2];
  Scene& s = scenes[thesis ? 1 : 0];
  if (!s.views.empty()) return s;
  s.mesh = mesh;
  if (thesis && !std::getenv("REVOLVE_BENCH_MESH")) {
    for (Eigen::Vector3f& v : s.mesh.vertices) v = 3.5f * v + Eigen::Vector3f(0.0f, 0.0f, 60.0f);
  }
  const Rig rig = testing::StationRig(450.0, 20.0, 60.0);
  int width = 1280;
  int height = 960;
  if (const char* size = std::getenv("REVOLVE_BENCH_SIZE");
      size != nullptr && std::sscanf(size, "%dx%d", &width, &height) != 2) {
    std::fprintf(stderr, "REVOLVE_BENCH_SIZE=%s: not WxH (e.g. 720x576)\n", size);
    std::exit(2);
  }
  for (int k = 0; k < kViews; ++k) {
    s.views.push_back(thesis ? ThesisView(width, height, 10.0 * k)
                             : testing::ViewOf(rig, 10.0 * k));
    s.masks.push_back(thesis ? RenderSilhouette(s.mesh, s.views.back())
                             : testing::SphereMask(rig, 10.0 * k, Spheres()));
  }
  return s;
}

// range(0): 1 = thesis views; range(1): the search, 0 every edge, 1 one view at a time, 2 all
// views at once (SilhouetteReprojection's).
void BM_Reprojection(benchmark::State& state) {
  const Scene& s = GetScene(state.range(0) != 0);
  const auto search = static_cast<outline_internal::OutlineSearch>(state.range(1));
  for (auto _ : state) {
    const ReprojectionStats stats =
        outline_internal::SilhouetteReprojectionBy(s.mesh, s.views, s.masks, {}, search);
    benchmark::DoNotOptimize(stats.mean);
  }
  double decided = 0;
  double faces = 0;
  double outline = 0;
  const outline_internal::OutlineIndex index(s.mesh);
  for (const View& view : s.views) {
    outline_internal::OutlineCounts counts;
    (void)outline_internal::SilhouetteFromOutline(s.mesh, index, view, &counts);
    decided += counts.decided;
    faces += counts.faces;
    outline += counts.outline_edges;
  }
  state.counters["triangles"] = static_cast<double>(s.mesh.faces.size());
  state.counters["outline_edges"] = outline / kViews;
  state.counters["decided"] = faces > 0 ? decided / faces : 0.0;
}
BENCHMARK(BM_Reprojection)
    ->Name("Reprojection36Views")
    ->ArgNames({"thesis", "search"})
    ->Args({0, 0})
    ->Args({0, 1})
    ->Args({0, 2})
    ->Args({1, 0})
    ->Args({1, 1})
    ->Args({1, 2})
    ->Unit(benchmark::kMillisecond);

// One view (range(2)) on the calling thread: the silhouette alone, no IoU.
void BM_OneView(benchmark::State& state) {
  const Scene& s = GetScene(state.range(0) != 0);
  const bool every_edge = state.range(1) != 0;
  const View& view = s.views[static_cast<std::size_t>(state.range(2))];
  const outline_internal::OutlineIndex index(s.mesh);
  const std::vector<outline_internal::SharedEdge> edges = outline_internal::SharedEdges(s.mesh);
  outline_internal::OutlineScratch scratch;
  for (auto _ : state) {
    const auto silhouette =
        every_edge
            ? outline_internal::SilhouetteFromEveryEdge(s.mesh, edges, view)
            : outline_internal::SilhouetteFromOutline(s.mesh, index, view, nullptr, &scratch);
    benchmark::DoNotOptimize(silhouette->pixels.data);
  }
}
BENCHMARK(BM_OneView)
    ->Name("OneView")
    ->ArgNames({"thesis", "every_edge", "view"})
    ->Args({0, 1, 3})
    ->Args({0, 0, 3})
    ->Args({1, 1, 3})
    ->Args({1, 0, 3})
    ->Unit(benchmark::kMillisecond);

// The index alone (once per mesh, on one thread).
void BM_OutlineIndex(benchmark::State& state) {
  const Scene& s = GetScene(false);
  for (auto _ : state) {
    const outline_internal::OutlineIndex index(s.mesh);
    benchmark::DoNotOptimize(index.neighbours().data());
    benchmark::DoNotOptimize(index.normal_x().data());  // the planes, measured when first read
  }
}
BENCHMARK(BM_OutlineIndex)->Name("OutlineIndex")->Unit(benchmark::kMillisecond);

// The thesis's views' silhouettes from the mesh's slices alone (the index made once, outside the
// loop): what SilhouetteReprojection does after the index for views that share their rows.
void BM_Slices(benchmark::State& state) {
  const Scene& s = GetScene(true);
  const outline_internal::OutlineIndex index(s.mesh);
  std::vector<std::size_t> which(s.views.size());
  for (std::size_t i = 0; i < which.size(); ++i) which[i] = i;
  int not_sliced = 0;
  for (auto _ : state) {
    const bool sliced = outline_internal::SilhouettesFromSlices(
        s.mesh, index, s.views, which, [&](std::size_t, std::optional<BoxedSilhouette> silhouette) {
          benchmark::DoNotOptimize(silhouette);
        });
    if (!sliced) ++not_sliced;
  }
  state.counters["not_sliced"] = not_sliced;
}
BENCHMARK(BM_Slices)->Name("Slices36Views")->Unit(benchmark::kMillisecond);

// ComputeStats, which `reconstruct --images` runs beside SilhouetteReprojection (its
// metrics_ms is both).
void BM_ComputeStats(benchmark::State& state) {
  const Scene& s = GetScene(false);
  for (auto _ : state) {
    const MeshStats stats = ComputeStats(s.mesh);
    benchmark::DoNotOptimize(stats.volume_mm3);
  }
}
BENCHMARK(BM_ComputeStats)->Name("ComputeStats")->Unit(benchmark::kMillisecond);

// The silhouette consensus (ConsensusOfSilhouettes) on the scene's silhouettes, as `reconstruct
// --images` runs it on photos (thesis views, 1280 x 960): 36 leave-one-out hulls of 64^3, each
// drawn into its view and the view's mask cut to it, on all cores.
void BM_Consensus(benchmark::State& state) {
  const Scene& s = GetScene(state.range(0) != 0);
  Eigen::Vector3f lo = s.mesh.vertices.front();
  Eigen::Vector3f hi = lo;
  for (const Eigen::Vector3f& v : s.mesh.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  const Eigen::Vector3d pad = 0.05 * (hi - lo).cast<double>();
  for (auto _ : state) {
    const Expected<SilhouetteConsensus> consensus =
        ConsensusOfSilhouettes(s.masks, s.views, lo.cast<double>() - pad, hi.cast<double>() + pad);
    benchmark::DoNotOptimize(consensus->agreement.data());
  }
}
BENCHMARK(BM_Consensus)
    ->Name("Consensus36Views")
    ->ArgName("thesis")
    ->Arg(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace revolve::reconstruct

BENCHMARK_MAIN();
