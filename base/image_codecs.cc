#include "base/image_codecs.h"

#include <atomic>
#include <climits>
#include <mutex>
#include <string>
#include <system_error>

#include <fmt/format.h>

#include "base/atomic_file.h"
#include "base/image_codecs_plugin.h"
#include "base/plugin.h"

namespace revolve {
namespace {

namespace fs = std::filesystem;
namespace plugin = image_codecs_plugin;

std::atomic<bool> g_loaded{false};

// The plugin's table, or why it could not be loaded.
Expected<const plugin::Table*> Load() {
  const PluginFile file{"OpenCV's image codecs (librevolve_imgcodecs.so)",
                        REVOLVE_IMGCODECS_FROM_BINDIR, REVOLVE_IMGCODECS_BUILD_FILE};
  Expected<const plugin::Table*> table =
      LoadPluginTable<plugin::Table>(file, plugin::kEntryPoint, plugin::kVersion);
  if (table) g_loaded = true;
  return table;
}

const Expected<const plugin::Table*>& Codecs() {
  static const Expected<const plugin::Table*> table = Load();  // thread-safe, once
  return table;
}

}  // namespace

Expected<cv::Mat> DecodeImage(std::span<const std::uint8_t> bytes, int imread_flags) {
  const auto& codecs = Codecs();
  if (!codecs) return std::unexpected(codecs.error());
  if (bytes.size() > static_cast<std::size_t>(INT_MAX)) {
    return MakeError(ErrorCode::kBadInput, "too large for OpenCV's decoders (over 2 GB)");
  }
  cv::Mat image;
  std::string error;
  if (!(*codecs)->decode(bytes.data(), bytes.size(), imread_flags, &image, &error)) {
    return MakeError(ErrorCode::kBadInput, error);
  }
  return image;
}

Expected<std::vector<std::uint8_t>> EncodeImage(std::string_view extension, const cv::Mat& image,
                                                const std::vector<int>& params) {
  const auto& codecs = Codecs();
  if (!codecs) return std::unexpected(codecs.error());
  std::vector<std::uint8_t> bytes;
  std::string error;
  const std::string ext(extension);
  if (!(*codecs)->encode(ext.c_str(), &image, &params, &bytes, &error)) {
    return MakeError(ErrorCode::kBadInput, error);
  }
  return bytes;
}

Expected<void> WriteImageFile(const fs::path& path, const cv::Mat& image,
                              const std::vector<int>& params) {
  Expected<std::vector<std::uint8_t>> bytes = EncodeImage(path.extension().string(), image, params);
  if (!bytes) {
    return MakeError(bytes.error().code, fmt::format("{}: cannot write the image: {}",
                                                     path.string(), bytes.error().message));
  }
  return WriteFileAtomically(
      path, std::span<const char>(reinterpret_cast<const char*>(bytes->data()), bytes->size()));
}

bool ImageCodecsLoaded() { return g_loaded; }

}  // namespace revolve
