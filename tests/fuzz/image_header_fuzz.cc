// Fuzzes the image header check: no input may crash or read out of bounds, and a header that
// passes has a positive size.
#include <cstdint>
#include <cstdlib>
#include <span>

#include "base/image_header.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto header = revolve::CheckImageBytes(std::span<const std::uint8_t>(data, size));
  if (header && (header->width_px < 1 || header->height_px < 1)) std::abort();
  return 0;
}
