// What reading an image costs with its checks (base/image_read.h): the header check, the decode
// to the end with every libjpeg/libpng warning fatal (base/image_verify.h), and OpenCV's decode,
// each alone and together, on a 1280 x 960 camera frame; and a 720 x 576 silhouette PNG decoded
// by OpenCV (libpng), by libpng with warnings fatal, and by DecodePlainPng (base/png_decode.h).
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "base/image_header.h"
#include "base/image_read.h"
#include "base/image_verify.h"
#include "base/png_decode.h"

namespace {

std::vector<std::uint8_t> Frame(const char* ext) {
  cv::Mat image(960, 1280, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(60));
  cv::GaussianBlur(image, image, {9, 9}, 3.0);
  cv::circle(image, {640, 480}, 300, {200, 180, 160}, -1);
  std::vector<std::uint8_t> bytes;
  cv::imencode(ext, image, bytes);
  return bytes;
}

void Run(benchmark::State& state, const char* ext, int stage) {
  const std::vector<std::uint8_t> bytes = Frame(ext);
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / (std::string("revolve_image_read_bench") + ext);
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  for (auto _ : state) {
    if (stage == 0) benchmark::DoNotOptimize(revolve::CheckImageBytes(bytes));
    if (stage == 1) {
      benchmark::DoNotOptimize(revolve::VerifyImageData(
          ext[1] == 'j' ? revolve::ImageFormat::kJpeg : revolve::ImageFormat::kPng, bytes));
    }
    if (stage == 2) benchmark::DoNotOptimize(cv::imdecode(bytes, cv::IMREAD_COLOR));
    if (stage == 3) {
      revolve::ImageReadOptions options;
      options.imread_flags = cv::IMREAD_COLOR;
      benchmark::DoNotOptimize(revolve::ReadImageFile(path, options));
    }
  }
  std::filesystem::remove(path);
}

// A silhouette as a grey PNG, as OpenCV writes it (one row filter per row, libpng's choice).
std::vector<std::uint8_t> SilhouettePng() {
  cv::Mat mask(576, 720, CV_8UC1, cv::Scalar(0));
  cv::ellipse(mask, {360, 300}, {120, 200}, 10.0, 0, 360, cv::Scalar(255), cv::FILLED);
  cv::circle(mask, {430, 120}, 60, cv::Scalar(255), cv::FILLED);
  std::vector<std::uint8_t> bytes;
  cv::imencode(".png", mask, bytes);
  return bytes;
}

// range(0): 0 OpenCV (libpng), 1 libpng with warnings fatal (VerifyImageData), 2 DecodePlainPng.
void BM_SilhouettePng(benchmark::State& state) {
  const std::vector<std::uint8_t> bytes = SilhouettePng();
  for (auto _ : state) {
    if (state.range(0) == 0) benchmark::DoNotOptimize(cv::imdecode(bytes, cv::IMREAD_GRAYSCALE));
    if (state.range(0) == 1) {
      benchmark::DoNotOptimize(revolve::VerifyImageData(revolve::ImageFormat::kPng, bytes));
    }
    if (state.range(0) == 2) {
      benchmark::DoNotOptimize(revolve::DecodePlainPng(bytes, cv::IMREAD_GRAYSCALE));
    }
  }
}
BENCHMARK(BM_SilhouettePng)
    ->Name("SilhouettePng")
    ->ArgName("decoder")
    ->Arg(0)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond);

void BM_JpegHeaderCheck(benchmark::State& s) { Run(s, ".jpg", 0); }
void BM_JpegVerify(benchmark::State& s) { Run(s, ".jpg", 1); }
void BM_JpegOpenCvDecode(benchmark::State& s) { Run(s, ".jpg", 2); }
void BM_JpegReadImageFile(benchmark::State& s) { Run(s, ".jpg", 3); }
void BM_PngHeaderCheck(benchmark::State& s) { Run(s, ".png", 0); }
void BM_PngVerify(benchmark::State& s) { Run(s, ".png", 1); }
void BM_PngOpenCvDecode(benchmark::State& s) { Run(s, ".png", 2); }
void BM_PngReadImageFile(benchmark::State& s) { Run(s, ".png", 3); }

BENCHMARK(BM_JpegHeaderCheck)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_JpegVerify)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_JpegOpenCvDecode)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_JpegReadImageFile)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PngHeaderCheck)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PngVerify)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PngOpenCvDecode)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PngReadImageFile)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
