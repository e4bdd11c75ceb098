// librevolve_imgcodecs.so: OpenCV's imgcodecs behind the table of base/image_codecs_plugin.h.
// Only this module links opencv_imgcodecs, so revolve loads its ~140 libraries only when an
// image needs OpenCV's codecs (base/image_codecs.h).
#include "base/image_codecs_plugin.h"

#include <exception>

#include <opencv2/imgcodecs.hpp>

namespace revolve::image_codecs_plugin {
namespace {

bool Decode(const std::uint8_t* bytes, std::size_t size, int imread_flags, cv::Mat* image,
            std::string* error) {
  try {
    const cv::Mat data(1, static_cast<int>(size), CV_8UC1, const_cast<std::uint8_t*>(bytes));
    *image = cv::imdecode(data, imread_flags);
    if (!image->empty()) return true;
    *error = "OpenCV cannot decode the data";
  } catch (const std::exception& e) {
    *error = e.what();
  }
  return false;
}

bool Encode(const char* extension, const cv::Mat* image, const std::vector<int>* params,
            std::vector<std::uint8_t>* bytes, std::string* error) {
  try {
    if (cv::imencode(extension, *image, *bytes, *params)) return true;
    *error = std::string("OpenCV cannot encode the image as ") + extension;
  } catch (const std::exception& e) {
    *error = e.what();
  }
  return false;
}

const Table kTable{kVersion, &Decode, &Encode};

}  // namespace
}  // namespace revolve::image_codecs_plugin

extern "C" __attribute__((visibility("default"))) const revolve::image_codecs_plugin::Table*
revolve_image_codecs_v1() {
  return &revolve::image_codecs_plugin::kTable;
}
