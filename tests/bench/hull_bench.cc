// Visual hull speed at 256^3 on the station's default volume (120 x 120 x 120 mm, 0.47 mm
// voxels): 36 analytic sphere silhouettes (r = 40 mm, 768 x 576, 10 degree steps), one thread.
#include <benchmark/benchmark.h>

#include "reconstruct/hull/visual_hull.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

constexpr int kViews = 36;
constexpr int kResolution = 256;

struct Scene {
  VoxelGrid grid;
  std::vector<cv::Mat> masks;
  std::vector<View> views;
};

const Scene& GetScene() {
  static const Scene scene = [] {
    Scene s;
    s.grid = *VoxelGrid::FromBox({-60, -60, 0}, {60, 60, 120}, kResolution);
    const Rig rig = testing::StationRig(450.0, 0.0, 40.0);
    for (int k = 0; k < kViews; ++k) {
      s.masks.push_back(testing::SphereMask(rig, 10.0 * k, testing::Sphere{}));
      s.views.push_back(testing::ViewOf(rig, 10.0 * k));
    }
    return s;
  }();
  return scene;
}

// A hull with the first `views` views integrated.
VisualHull HullWith(int views) {
  const Scene& s = GetScene();
  VisualHull hull(s.grid);
  for (int k = 0; k < views; ++k) (void)hull.Integrate(s.masks[k], s.views[k]);
  return hull;
}

// Integrates view `index` (arg) into a hull holding all views before it.
template <bool kNaive>
void BM_IntegrateOneView(benchmark::State& state) {
  const Scene& s = GetScene();
  const int index = static_cast<int>(state.range(0));
  const VisualHull before = HullWith(index);
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
    ->Arg(0)
    ->Arg(1)
    ->Arg(35)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_IntegrateOneView<true>)
    ->Name("IntegrateOneView/naive")
    ->Arg(0)
    ->Arg(35)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

// All 36 views into a fresh hull.
template <bool kNaive>
void BM_Carve36Views(benchmark::State& state) {
  const Scene& s = GetScene();
  for (auto _ : state) {
    VisualHull hull(s.grid);
    for (int k = 0; k < kViews; ++k) {
      const Expected<void> result = kNaive ? hull.IntegrateNaive(s.masks[k], s.views[k])
                                           : hull.Integrate(s.masks[k], s.views[k]);
      benchmark::DoNotOptimize(result);
    }
  }
  state.counters["ms_per_view"] = benchmark::Counter(
      1e3 / kViews * state.iterations(), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_Carve36Views<false>)->Name("Carve36Views/hierarchical")->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Carve36Views<true>)
    ->Name("Carve36Views/naive")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// Finish: marching cubes over the occupancy with `steps` bisection steps per vertex.
void BM_Finish(benchmark::State& state) {
  const VisualHull hull = HullWith(kViews);
  HullSurfaceOptions options;
  options.bisection_steps = static_cast<int>(state.range(0));
  std::size_t triangles = 0;
  for (auto _ : state) {
    const Mesh mesh = hull.ExtractSurface(options);
    triangles = mesh.faces.size();
    benchmark::DoNotOptimize(mesh.vertices.data());
  }
  state.counters["triangles"] = static_cast<double>(triangles);
}
BENCHMARK(BM_Finish)->Name("Finish")->Arg(10)->Arg(0)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace revolve::reconstruct

BENCHMARK_MAIN();
