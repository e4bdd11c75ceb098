// Segmentation of one 1280x960 frame on one core (issue 17's bars: <= 10 ms for the live
// methods, <= 60 ms with the graph-cut refinement); 640x480 for comparison. And SegmentSet: a
// whole set of 36 photos as `reconstruct --images` segments it (SetPhotos, below), on one core.
// Run: taskset -c 0 build/tests/bench/segment_bench The frame is a real photograph
// (shared/data templeSparseRing view 1: plaster on a dark, uneven cloth stand) scaled up to
// 1280x960; without the shared data, a drawn frame of the same kind.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/segment/set_segmentation.h"
#include "capture/segmenter.h"
#include "capture/synthetic/render.h"
#include "capture/synthetic/scene.h"
#include "tests/reconstruct/sphere_scene.h"

namespace {

cv::Mat Frame(cv::Size size) {
  const std::filesystem::path photo = std::filesystem::path(REVOLVE_SHARED_DIR) /
                                      "data/middlebury-templeSparseRing/templeSR0001.png";
  cv::Mat image = cv::imread(photo.string(), cv::IMREAD_COLOR);
  if (image.empty()) {
    image = cv::Mat(480, 640, CV_8UC3, cv::Scalar(8, 8, 8));
    cv::rectangle(image, {0, 0, 150, 480}, cv::Scalar(50, 45, 55), cv::FILLED);
    cv::ellipse(image, {330, 240}, {180, 120}, 0.0, 0.0, 360.0, cv::Scalar(120, 170, 190),
                cv::FILLED);
  }
  cv::Mat frame;
  cv::resize(image, frame, size, 0.0, 0.0, cv::INTER_LINEAR);
  return frame;
}

// state.range(0): the frame's width (1280: the bars; 640: the Middlebury photos' size).
void BM_Segment(benchmark::State& state, const std::string& method, bool refine) {
  cv::setNumThreads(1);  // one core, as the bars say
  const int width = static_cast<int>(state.range(0));
  const cv::Mat frame = Frame(cv::Size(width, width * 3 / 4));
  // A flat dark frame for the empty scene (the difference is then the frame's own levels).
  cv::Mat background(frame.size(), CV_8UC3, cv::Scalar(8, 8, 8));
  revolve::capture::SegmentOptions options;
  options.method = method;
  options.refine = refine;
  auto segmenter = revolve::capture::CreateSegmenter(options);
  if (!segmenter) {
    state.SkipWithError(segmenter.error().message.c_str());
    return;
  }
  for (auto _ : state) {
    auto mask = (*segmenter)->Segment(frame, method == "background" ? background : cv::Mat());
    benchmark::DoNotOptimize(mask);
  }
}

void Sizes(benchmark::internal::Benchmark* b) {
  b->Arg(1280)->Arg(640)->Unit(benchmark::kMillisecond);
}

// Live methods (bar: <= 10 ms at 1280x960).
BENCHMARK_CAPTURE(BM_Segment, otsu, std::string("otsu"), false)->Apply(Sizes);
BENCHMARK_CAPTURE(BM_Segment, background, std::string("background"), false)->Apply(Sizes);
// With the graph-cut refinement (bar: <= 60 ms at 1280x960).
BENCHMARK_CAPTURE(BM_Segment, background_refined, std::string("background"), true)->Apply(Sizes);
BENCHMARK_CAPTURE(BM_Segment, graphcut, std::string("graphcut"), false)->Apply(Sizes);
BENCHMARK_CAPTURE(BM_Segment, auto, std::string("auto"), false) -> Apply(Sizes);

// A set of 36 photos 1280x960: the files of REVOLVE_BENCH_PHOTOS (a folder: every .jpg and .png
// in name order, e.g. `reconstruct --images`' JPEGs), else the simulator's textured cylinder on a
// grey backdrop, rendered at 10-degree steps and passed through JPEG (quality 90) as a camera's
// files would be.
const std::vector<cv::Mat>& SetPhotos() {
  static const std::vector<cv::Mat> photos = [] {
    std::vector<cv::Mat> out;
    if (const char* dir = std::getenv("REVOLVE_BENCH_PHOTOS")) {
      std::vector<std::filesystem::path> files;
      for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        const std::string ext = entry.path().extension().string();
        if (ext == ".jpg" || ext == ".png") files.push_back(entry.path());
      }
      std::sort(files.begin(), files.end());
      for (const auto& file : files) out.push_back(cv::imread(file.string(), cv::IMREAD_COLOR));
      if (out.empty() || out.front().empty()) {
        std::fprintf(stderr, "REVOLVE_BENCH_PHOTOS=%s: no photo read\n", dir);
        std::exit(2);
      }
      return out;
    }
    const revolve::capture::Scene scene =
        *revolve::capture::Scene::Create(revolve::capture::Shape::kCylinder, 40.0, 80.0);
    const revolve::Rig rig =
        revolve::reconstruct::testing::StationRig(450.0, 20.0, 40.0, 1280, 960, 30.0);
    const revolve::capture::SimProjection projection(rig);
    revolve::capture::RenderSettings settings;
    settings.backdrop_bgr = {110.0f, 112.0f, 115.0f};
    for (int k = 0; k < 36; ++k) {
      std::vector<std::uint8_t> jpeg;
      cv::imencode(".jpg", revolve::capture::RenderFrame(scene, projection, 10.0 * k, settings, k),
                   jpeg, {cv::IMWRITE_JPEG_QUALITY, 90});
      out.push_back(cv::imdecode(jpeg, cv::IMREAD_COLOR));
    }
    return out;
  }();
  return photos;
}

// The whole set as `reconstruct --images` segments it (method auto: the survey, then every
// photo), on one core.
void BM_SegmentSet(benchmark::State& state) {
  cv::setNumThreads(1);
  const tbb::global_control one_core(tbb::global_control::max_allowed_parallelism, 1);
  const std::vector<cv::Mat>& photos = SetPhotos();
  revolve::capture::SegmentOptions options;
  options.method = "auto";
  for (auto _ : state) {
    auto segmented = revolve::capture::SegmentImageSet(photos, options);
    if (!segmented) {
      state.SkipWithError(segmented.error().message.c_str());
      break;
    }
    benchmark::DoNotOptimize(segmented);
  }
  state.counters["per_photo"] = benchmark::Counter(
      static_cast<double>(photos.size()),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_SegmentSet)->Name("SegmentSet")->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
