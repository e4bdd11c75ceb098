// Visual hull speed on the station's default volume (120 x 120 x 120 mm: 0.47 mm voxels at
// 256^3, 0.23 mm at 512^3): 36 analytic sphere silhouettes (r = 40 mm, 768 x 576, 10 degree
// steps), one thread. Each hierarchical figure has its per-voxel reference ("naive") beside it.
// Compare CPU times: the machine may be shared.
#include <map>

#include <benchmark/benchmark.h>

#include "reconstruct/cameras/views.h"
#include "reconstruct/hull/visual_hull.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

constexpr int kViews = 36;

struct Scene {
  VoxelGrid grid;
  std::vector<cv::Mat> masks;
  std::vector<View> views;
};

const Scene& GetScene(int resolution) {
  static std::map<int, Scene> scenes;
  auto it = scenes.find(resolution);
  if (it != scenes.end()) return it->second;
  Scene s;
  s.grid = *VoxelGrid::FromBox({-60, -60, 0}, {60, 60, 120}, resolution);
  const Rig rig = testing::StationRig(450.0, 0.0, 40.0);
  for (int k = 0; k < kViews; ++k) {
    s.masks.push_back(testing::SphereMask(rig, 10.0 * k, testing::Sphere{}));
    s.views.push_back(testing::ViewOf(rig, 10.0 * k));
  }
  return scenes.emplace(resolution, std::move(s)).first->second;
}

// A hull with the first `views` views integrated.
VisualHull HullWith(int resolution, int views) {
  const Scene& s = GetScene(resolution);
  VisualHull hull(s.grid);
  for (int k = 0; k < views; ++k) (void)hull.Integrate(s.masks[k], s.views[k]);
  return hull;
}

// Integrates view range(1) into a hull of resolution range(0) holding all views before it.
template <bool kNaive>
void BM_IntegrateOneView(benchmark::State& state) {
  const int resolution = static_cast<int>(state.range(0));
  const int index = static_cast<int>(state.range(1));
  const Scene& s = GetScene(resolution);
  const VisualHull before = HullWith(resolution, index);
  for (auto _ : state) {
    state.PauseTiming();
    VisualHull hull = before;
    state.ResumeTiming();
    const Expected<void> result = kNaive ? hull.IntegrateNaive(s.masks[index], s.views[index])
                                         : hull.Integrate(s.masks[index], s.views[index]);
    benchmark::DoNotOptimize(result);
  }
}
BENCHMARK(BM_IntegrateOneView<false>)
    ->Name("IntegrateOneView/hierarchical")
    ->Args({256, 0})
    ->Args({256, 1})
    ->Args({256, 18})
    ->Args({256, 35})
    ->Args({512, 0})
    ->Args({512, 18})
    ->Args({512, 35})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_IntegrateOneView<true>)
    ->Name("IntegrateOneView/naive")
    ->Args({256, 0})
    ->Args({512, 0})
    ->Args({256, 18})
    ->Args({256, 35})
    ->Args({512, 18})
    ->Args({512, 35})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2);

// All 36 views into a fresh hull.
template <bool kNaive>
void BM_Carve36Views(benchmark::State& state) {
  const int resolution = static_cast<int>(state.range(0));
  const Scene& s = GetScene(resolution);
  for (auto _ : state) {
    VisualHull hull(s.grid);
    for (int k = 0; k < kViews; ++k) {
      const Expected<void> result = kNaive ? hull.IntegrateNaive(s.masks[k], s.views[k])
                                           : hull.Integrate(s.masks[k], s.views[k]);
      benchmark::DoNotOptimize(result);
    }
  }
}
// The mean per view is the time / 36.
BENCHMARK(BM_Carve36Views<false>)
    ->Name("Carve36Views/hierarchical")
    ->Arg(256)
    ->Arg(512)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Carve36Views<true>)
    ->Name("Carve36Views/naive")
    ->Arg(256)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// The surface: marching cubes over the occupancy (flat bottom at the plate) with vertices at
// exact crossings (range(1) = 1: walking only the views that can cut each edge; 2: every view,
// the reference) or at midpoints (0).
void BM_ExtractSurface(benchmark::State& state) {
  const VisualHull hull = HullWith(static_cast<int>(state.range(0)), kViews);
  HullSurfaceOptions options;
  options.sub_voxel = state.range(1) != 0;
  options.cull_views = state.range(1) != 2;
  options.clip_below_z_mm = 0.0;
  std::size_t triangles = 0;
  for (auto _ : state) {
    const Mesh mesh = hull.ExtractSurface(options);
    triangles = mesh.faces.size();
    benchmark::DoNotOptimize(mesh.vertices.data());
  }
  state.counters["triangles"] = static_cast<double>(triangles);
}
BENCHMARK(BM_ExtractSurface)
    ->Name("ExtractSurface")
    ->ArgNames({"res", "mode"})
    ->Args({256, 1})
    ->Args({256, 0})
    ->Args({256, 2})
    ->Unit(benchmark::kMillisecond);

// The carving volume found from the silhouettes alone (CarvingVolumeFromSilhouettes: two coarse
// passes of 64^3 cells), as `reconstruct --images` finds it before and after the consensus;
// range(0) = 1 passes over blocks of cells that fall for certain, 0 tests every cell (the
// reference).
void BM_CarvingVolume(benchmark::State& state) {
  const Scene& s = GetScene(256);
  AutoVolumeOptions options;
  options.block_tests = state.range(0) != 0;
  for (auto _ : state) {
    const Expected<AutoVolume> volume = CarvingVolumeFromSilhouettes(s.masks, s.views, options);
    benchmark::DoNotOptimize(volume);
  }
}
BENCHMARK(BM_CarvingVolume)
    ->Name("CarvingVolume")
    ->ArgName("blocks")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace revolve::reconstruct

BENCHMARK_MAIN();
