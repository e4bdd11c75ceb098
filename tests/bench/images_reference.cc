// The references the whole `revolve reconstruct --images` is timed against (docs/performance.md),
// each on one thread, as a process of its own:
//   images_reference decode DIR            decodes every image of DIR (cv::imread), nothing more
//   images_reference read DIR              reads every image of DIR as revolve does (ReadImageFile:
//                                          header checks, one strict decode), nothing more
//   images_reference naive-carve DIR RES   loads DIR's binary silhouettes, finds the carving volume
//                                          and carves RES^3 voxels per voxel (thesis cameras, 10
//                                          degrees a view; every cell of the volume's coarse
//                                          passes tested); writes nothing
//   images_reference jpeg SRC DST QUALITY  writes every image of SRC into DST as JPEG (OpenCV's
//                                          encoder; how docs/performance.md's photo set is made)
// Prints what it did; exit status 1 on a bad folder.
#include <cstdio>
#include <cstdlib>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "base/image_files.h"
#include "base/image_read.h"
#include "reconstruct/cameras/views.h"
#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/image_set.h"
#include "reconstruct/parallel.h"

namespace {

namespace rc = revolve::reconstruct;

// Reads every image of `dir` with `read` (an empty image or an error stops it).
template <typename ReadFn>
int EachImage(const std::filesystem::path& dir, const char* verb, const ReadFn& read) {
  const revolve::Expected<std::vector<std::filesystem::path>> files = revolve::ListImageFiles(dir);
  if (!files) {
    std::fprintf(stderr, "%s\n", files.error().message.c_str());
    return 1;
  }
  std::size_t pixels = 0;
  for (const std::filesystem::path& file : *files) {
    const revolve::Expected<cv::Mat> image = read(file);
    if (!image || image->empty()) {
      std::fprintf(stderr, "%s: %s\n", file.string().c_str(),
                   image ? "cannot be read" : image.error().message.c_str());
      return 1;
    }
    pixels += image->total();
  }
  std::printf("%s %zu images, %zu pixels\n", verb, files->size(), pixels);
  return 0;
}

int Decode(const std::filesystem::path& dir) {
  return EachImage(dir, "decoded", [](const std::filesystem::path& file) {
    return revolve::Expected<cv::Mat>(cv::imread(file.string(), cv::IMREAD_UNCHANGED));
  });
}

int Read(const std::filesystem::path& dir) {
  return EachImage(dir, "read",
                   [](const std::filesystem::path& file) { return revolve::ReadImageFile(file); });
}

int NaiveCarve(const std::filesystem::path& dir, int resolution) {
  rc::ImageSetOptions options;
  const revolve::Expected<rc::ImageSet> set = rc::LoadImageSet(dir, options);
  if (!set || set->kind != rc::ImageKind::kSilhouette) {
    std::fprintf(stderr, "%s: expected binary silhouettes\n", dir.string().c_str());
    return 1;
  }
  std::vector<cv::Mat> masks;
  std::vector<revolve::View> views;
  for (const rc::SetImage& image : set->images) {
    masks.push_back(image.mask);
    views.push_back(rc::ThesisView(set->width_px, set->height_px, image.angle_deg));
  }
  rc::AutoVolumeOptions every_cell;
  every_cell.block_tests = false;
  const revolve::Expected<rc::AutoVolume> volume =
      rc::CarvingVolumeFromSilhouettes(masks, views, every_cell);
  if (!volume) return 1;
  rc::VisualHull hull(*rc::VoxelGrid::FromBox(volume->box.min, volume->box.max, resolution));
  for (std::size_t k = 0; k < masks.size(); ++k) (void)hull.IntegrateNaive(masks[k], views[k]);
  std::printf("carved %zu views per voxel: %lld voxels occupied\n", masks.size(),
              static_cast<long long>(hull.OccupiedCount()));
  return 0;
}

int Jpeg(const std::filesystem::path& src, const std::filesystem::path& dst, int quality) {
  const revolve::Expected<std::vector<std::filesystem::path>> files = revolve::ListImageFiles(src);
  if (!files || files->empty()) {
    std::fprintf(stderr, "%s: no images\n", src.string().c_str());
    return 1;
  }
  std::error_code ec;
  std::filesystem::create_directories(dst, ec);
  for (const std::filesystem::path& file : *files) {
    const cv::Mat image = cv::imread(file.string(), cv::IMREAD_COLOR);
    const std::filesystem::path out = dst / file.filename().replace_extension(".jpg");
    if (image.empty() || !cv::imwrite(out.string(), image, {cv::IMWRITE_JPEG_QUALITY, quality})) {
      std::fprintf(stderr, "%s: cannot convert to %s\n", file.string().c_str(),
                   out.string().c_str());
      return 1;
    }
  }
  std::printf("wrote %zu JPEGs (quality %d) into %s\n", files->size(), quality,
              dst.string().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const rc::ThreadLimit one_thread(1);
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode == "decode" && argc == 3) return Decode(argv[2]);
  if (mode == "read" && argc == 3) return Read(argv[2]);
  if (mode == "naive-carve" && argc == 4) return NaiveCarve(argv[2], std::atoi(argv[3]));
  if (mode == "jpeg" && argc == 5) return Jpeg(argv[2], argv[3], std::atoi(argv[4]));
  std::fprintf(stderr,
               "usage: images_reference decode DIR | read DIR | naive-carve DIR RESOLUTION | "
               "jpeg SRC DST QUALITY\n");
  return 2;
}
