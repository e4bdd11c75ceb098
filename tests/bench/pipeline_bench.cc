// From the last view to every model file written, at 256^3 on the station's default volume:
// the synthetic camera's textured sphere (r = 40 mm, 36 frames of 768 x 576, true silhouettes),
// one thread. Timed: integrating the last view, the surface (flat bottom at the plate), colour
// (vertex colours and, with range(0) = 1, the texture atlas) and writing model.{ply, obj + mtl
// (+ png), stl, glb, wrl}. The reference ("naive") integrates the last view per voxel and walks
// every edge in every view. Compare CPU times: the machine may be shared. The process keeps the
// memory it frees, as the station's programs do (base::RetainFreedMemory).
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "base/memory.h"
#include "base/png_encode.h"
#include "capture/synthetic/render.h"
#include "capture/synthetic/scene.h"
#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/io/mesh_io.h"
#include "reconstruct/io/model_writer.h"
#include "reconstruct/io/writer_support.h"
#include "reconstruct/texture/texture.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

namespace fs = std::filesystem;

constexpr int kViews = 36;
constexpr int kResolution = 256;

struct Frames {
  VoxelGrid grid;
  std::vector<cv::Mat> images;
  std::vector<cv::Mat> masks;
  std::vector<View> views;
};

const Frames& GetFrames() {
  static const Frames frames = [] {
    Frames f;
    f.grid = *VoxelGrid::FromBox({-60, -60, 0}, {60, 60, 120}, kResolution);
    const capture::Scene scene = *capture::Scene::Create(capture::Shape::kSphere, 40.0, 80.0);
    const Rig rig = testing::StationRig(450.0, 0.0, 40.0);
    const capture::SimProjection projection(rig);
    capture::RenderSettings settings;
    for (int k = 0; k < kViews; ++k) {
      const capture::RenderOutput out =
          capture::RenderScene(scene, projection, 10.0 * k, settings, k);
      f.images.push_back(out.image);
      f.masks.push_back(out.true_mask);
      f.views.push_back(testing::ViewOf(rig, 10.0 * k));
    }
    return f;
  }();
  return frames;
}

// kStaged: the files written as the mesh is made (the station's way); else once it is done.
// kGlbOnly: the glTF alone rather than every format ([reconstruct] formats = ["glb"]).
template <bool kNaive, bool kStaged = true, bool kGlbOnly = false>
void BM_LastViewToFiles(benchmark::State& state) {
  const bool texture = state.range(0) != 0;
  const Frames& f = GetFrames();
  VisualHull before(f.grid);
  for (int k = 0; k + 1 < kViews; ++k) (void)before.Integrate(f.masks[k], f.views[k]);
  const fs::path dir =
      fs::temp_directory_path() / ("revolve_pipeline_bench_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::size_t triangles = 0;
  const fs::path out = dir / "model";
  // Wall time of each part (ms, summed over the runs): the view, the surface, colour, files.
  double part_ms[4] = {0.0, 0.0, 0.0, 0.0};
  using Clock = std::chrono::steady_clock;
  auto lap = [](Clock::time_point* since, double* ms) {
    const Clock::time_point now = Clock::now();
    *ms += std::chrono::duration<double, std::milli>(now - *since).count();
    *since = now;
  };
  // Minor page faults per run (memory given to the process as it first writes it), the
  // untimed copy of the hull included.
  rusage before_run{};
  getrusage(RUSAGE_SELF, &before_run);
  for (auto _ : state) {
    state.PauseTiming();
    VisualHull hull = before;
    // A new folder each time, as a scan's: deleting the last run's files is not part of it.
    fs::remove_all(out);
    fs::create_directories(out);
    state.ResumeTiming();
    Clock::time_point since = Clock::now();
    const int last = kViews - 1;
    const Expected<void> integrated = kNaive ? hull.IntegrateNaive(f.masks[last], f.views[last])
                                             : hull.Integrate(f.masks[last], f.views[last]);
    benchmark::DoNotOptimize(integrated);
    lap(&since, &part_ms[0]);
    HullSurfaceOptions surface;
    surface.clip_below_z_mm = 0.0;
    surface.cull_views = !kNaive;
    // As the station does it (HullReconstructor::FinishStaged): each file written as soon as
    // what it holds is final. files_ms is what is left of the files once the mesh is done.
    // Without kStaged the writer is told nothing before Finish: WriteModel after the mesh.
    Mesh mesh;
    auto writer =
        ModelWriter::Start(mesh, out, "model",
                           kGlbOnly ? std::vector<std::string>{"glb"}
                                    : std::vector<std::string>{"ply", "obj", "stl", "glb", "wrl"});
    if (!writer) {
      state.SkipWithError("write failed");
      break;
    }
    mesh = hull.ExtractSurface(surface);
    if (kStaged) (*writer)->Reached(MeshStage::kSurface);
    lap(&since, &part_ms[1]);
    TextureOptions options;
    options.atlas = texture;
    if (kStaged) options.on_stage = (*writer)->Hook();
    if (!TextureMesh(&mesh, f.views, f.images, options)) state.SkipWithError("texture failed");
    lap(&since, &part_ms[2]);
    if (!(*writer)->Finish()) state.SkipWithError("write failed");
    lap(&since, &part_ms[3]);
    triangles = mesh.faces.size();
  }
  rusage after_run{};
  getrusage(RUSAGE_SELF, &after_run);
  state.counters["faults"] = static_cast<double>(after_run.ru_minflt - before_run.ru_minflt) /
                             static_cast<double>(state.iterations());
  // The CPU time of every thread of the process per run (user + system; the untimed copy of the
  // hull included): the work the cores share.
  const auto cpu_ms = [](const rusage& r) {
    return 1e3 * static_cast<double>(r.ru_utime.tv_sec + r.ru_stime.tv_sec) +
           1e-3 * static_cast<double>(r.ru_utime.tv_usec + r.ru_stime.tv_usec);
  };
  state.counters["process_cpu_ms"] =
      (cpu_ms(after_run) - cpu_ms(before_run)) / static_cast<double>(state.iterations());
  // The bytes of the last run's files (MB): what the disk takes at the end of a scan.
  std::uintmax_t bytes = 0;
  std::error_code ec;
  for (const fs::directory_entry& file : fs::directory_iterator(out, ec)) {
    bytes += file.is_regular_file(ec) ? file.file_size(ec) : 0;
  }
  state.counters["file_mb"] = static_cast<double>(bytes) / 1e6;
  fs::remove_all(dir);
  state.counters["triangles"] = static_cast<double>(triangles);
  const char* parts[4] = {"view_ms", "surface_ms", "colour_ms", "files_ms"};
  for (int i = 0; i < 4; ++i) {
    state.counters[parts[i]] = part_ms[i] / static_cast<double>(state.iterations());
  }
}
BENCHMARK(BM_LastViewToFiles<false>)
    ->Name("LastViewToFiles/hierarchical")
    ->ArgName("texture")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond);
// The same finish with the files written only once the mesh is done (WriteModel's way), for
// comparison.
BENCHMARK(BM_LastViewToFiles<false, false>)
    ->Name("LastViewToFiles/sequential")
    ->ArgName("texture")
    ->Arg(1)
    ->Unit(benchmark::kMillisecond);
// The same finish writing the glTF alone (the web console's model): fewer bytes and no text.
BENCHMARK(BM_LastViewToFiles<false, true, true>)
    ->Name("LastViewToFiles/glb_only")
    ->ArgName("texture")
    ->Arg(1)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_LastViewToFiles<true>)
    ->Name("LastViewToFiles/naive")
    ->ArgName("texture")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2);

// The stages of the hierarchical path, apart.
void BM_Stage(benchmark::State& state) {
  const Frames& f = GetFrames();
  VisualHull hull(f.grid);
  for (int k = 0; k < kViews; ++k) (void)hull.Integrate(f.masks[k], f.views[k]);
  HullSurfaceOptions surface;
  surface.clip_below_z_mm = 0.0;
  const Mesh plain = hull.ExtractSurface(surface);
  Mesh textured = plain;
  (void)TextureMesh(&textured, f.views, f.images);
  const fs::path dir =
      fs::temp_directory_path() / ("revolve_stage_bench_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const int stage = static_cast<int>(state.range(0));
  static const char* kFormats[] = {"ply", "obj", "stl", "glb", "wrl"};
  for (auto _ : state) {
    if (stage == 0) {
      Mesh mesh = plain;
      TextureOptions options;
      options.atlas = false;
      benchmark::DoNotOptimize(TextureMesh(&mesh, f.views, f.images, options));
    } else if (stage == 1) {
      Mesh mesh = plain;
      benchmark::DoNotOptimize(TextureMesh(&mesh, f.views, f.images));
    } else if (stage == 12) {
      benchmark::DoNotOptimize(hull.ExtractSurface(surface));
    } else if (stage == 13) {
      benchmark::DoNotOptimize(EncodePng(textured.texture));
    } else {
      const std::string format = kFormats[(stage - 2) % 5];
      benchmark::DoNotOptimize(WriteModel(stage < 7 ? plain : textured, dir, "m", {format}));
    }
  }
  fs::remove_all(dir);
}
BENCHMARK(BM_Stage)->Name("Stage")->ArgName("stage")->DenseRange(0, 13)->Unit(
    benchmark::kMillisecond);
// Stages: 0 vertex colours, 1 colours + atlas, 2-6 write ply/obj/stl/glb/wrl without texture,
// 7-11 the same with the texture (obj writes the PNG, glb embeds it), 12 the surface (marching
// cubes and the placement on the edges, the base clipped at the plate), 13 the atlas's PNG encoded
// in memory.

}  // namespace
}  // namespace revolve::reconstruct

// The station's programs keep freed memory for the next scan (GuardedMain); so does this one,
// or every run would pay again for the pages the last one freed.
int main(int argc, char** argv) {
  revolve::base::RetainFreedMemory();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
