// revolve's side of the libcamera plugin (libcamera_plugin.h): CreateLibcameraCamera and
// ListLibcameraCameras load librevolve_libcamera.so on first use and call it.
#include <fmt/format.h>

#include "base/plugin.h"
#include "capture/libcamera/libcamera_camera.h"
#include "capture/libcamera/libcamera_plugin.h"
#include "capture/v4l2/pixel_convert.h"

namespace revolve::capture {
namespace {

namespace plugin = libcamera_plugin;

// The plugin's table, or why it could not be loaded; once per process.
const Expected<const plugin::Table*>& Plugin() {
  static const Expected<const plugin::Table*> table =
      LoadPluginTable<plugin::Table>({"the libcamera backend (librevolve_libcamera.so)",
                                      REVOLVE_LIBCAMERA_FROM_BINDIR, REVOLVE_LIBCAMERA_BUILD_FILE},
                                     plugin::kEntryPoint, plugin::kVersion);
  return table;
}

}  // namespace

Expected<std::unique_ptr<Camera>> CreateLibcameraCamera(const LibcameraOptions& options) {
  const auto& table = Plugin();
  if (!table) return std::unexpected(table.error());
  return (*table)->create(options, &ConvertToBgr);
}

std::string ListLibcameraCameras() {
  const auto& table = Plugin();
  if (!table) return fmt::format("libcamera: {}\n", table.error().message);
  return (*table)->list();
}

}  // namespace revolve::capture
