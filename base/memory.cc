#include "base/memory.h"

#include <cstdlib>  // defines __GLIBC__ with glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace revolve::base {

bool RetainFreedMemory() {
#if defined(__GLIBC__)
  constexpr int kMiB = 1 << 20;
  // M_MMAP_THRESHOLD's largest accepted value on 64-bit glibc is 32 MiB (HEAP_MAX_SIZE / 2).
  const bool mmap_set = mallopt(M_MMAP_THRESHOLD, 32 * kMiB) == 1;
  const bool trim_set = mallopt(M_TRIM_THRESHOLD, 512 * kMiB) == 1;
  return mmap_set && trim_set;
#else
  return false;
#endif
}

}  // namespace revolve::base
