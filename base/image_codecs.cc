#include "base/image_codecs.h"

#include <dlfcn.h>

#include <atomic>
#include <climits>
#include <mutex>
#include <string>
#include <system_error>

#include <fmt/format.h>

#include "base/atomic_file.h"
#include "base/image_codecs_plugin.h"

namespace revolve {
namespace {

namespace fs = std::filesystem;
namespace plugin = image_codecs_plugin;

std::atomic<bool> g_loaded{false};

// Where the plugin is: beside an installed executable, then the build tree's.
std::vector<fs::path> Candidates() {
  std::vector<fs::path> paths;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) paths.push_back((exe.parent_path() / REVOLVE_IMGCODECS_FROM_BINDIR).lexically_normal());
  paths.emplace_back(REVOLVE_IMGCODECS_BUILD_FILE);
  return paths;
}

// The plugin's table, or why it could not be loaded. The handle is never closed: OpenCV's
// libraries stay for the life of the process.
Expected<const plugin::Table*> Load() {
  std::string tried;
  for (const fs::path& path : Candidates()) {
    std::error_code ec;
    if (!fs::exists(path, ec)) {
      tried += fmt::format("\n  {}: no such file", path.string());
      continue;
    }
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) {
      tried += fmt::format("\n  {}: {}", path.string(), dlerror());
      continue;
    }
    auto entry = reinterpret_cast<plugin::EntryPoint>(dlsym(handle, plugin::kEntryPoint));
    const plugin::Table* table = entry != nullptr ? entry() : nullptr;
    if (table == nullptr || table->version != plugin::kVersion) {
      tried += fmt::format("\n  {}: not this build's plugin (rebuild or reinstall revolve)",
                           path.string());
      continue;
    }
    g_loaded = true;
    return table;
  }
  return MakeError(ErrorCode::kIo,
                   fmt::format("cannot load OpenCV's image codecs (librevolve_imgcodecs.so); "
                               "install revolve whole (cmake --install) or run it from its "
                               "build tree. Tried:{}",
                               tried));
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
