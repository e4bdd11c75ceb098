// Fuzzes the --cameras file parser: no input may crash, throw or hang.
#include <cstdint>
#include <string_view>

#include "reconstruct/cameras/camera_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto file = revolve::reconstruct::ParseCameraFile(
      std::string_view(reinterpret_cast<const char*>(data), size), "fuzz_par.txt");
  if (file) (void)file->Find("view_000.png");
  return 0;
}
