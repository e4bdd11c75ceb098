// Segmentation of one 1280x960 frame on one core (issue 17's bars: <= 10 ms for the live
// methods, <= 60 ms with the graph-cut refinement); 640x480 for comparison.
// Run: taskset -c 0 build/tests/bench/segment_bench The frame is a real photograph
// (shared/data templeSparseRing view 1: plaster on a dark, uneven cloth stand) scaled up to
// 1280x960; without the shared data, a drawn frame of the same kind.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/segmenter.h"

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

}  // namespace

BENCHMARK_MAIN();
