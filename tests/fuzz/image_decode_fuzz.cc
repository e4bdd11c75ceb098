// Fuzzes what an image file goes through before OpenCV may decode it: the header check, then a
// decode to the end with libjpeg, libpng or libtiff where every warning is an error
// (base/image_verify.h). No input may crash, leak, read out of bounds or hang.
#include <cstdint>
#include <span>

#include "base/image_header.h"
#include "base/image_verify.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  auto header = revolve::CheckImageBytes(bytes);
  // The decoders run only on files within a small size here, so that a run stays fast.
  if (!header || header->pixels() > 4'000'000) return 0;
  (void)revolve::VerifyImageData(header->format, bytes);
  return 0;
}
