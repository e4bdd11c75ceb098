// The programs' main(): no exception is expected past the commands (errors are values), so one
// that escapes is a bug. Say so and exit with EX_SOFTWARE (70) instead of aborting without a word.
// First, the allocator keeps freed memory for the next scan (base::RetainFreedMemory).
#pragma once

#include <cstdio>
#include <exception>

#include "base/memory.h"

namespace revolve::station {

inline constexpr int kExitSoftware = 70;

template <typename Main>
int GuardedMain(const char* program, Main main, int argc, char** argv) noexcept {
  base::RetainFreedMemory();
  try {
    return main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: internal error: %s\n", program, e.what());
  } catch (...) {
    std::fprintf(stderr, "%s: internal error\n", program);
  }
  return kExitSoftware;
}

}  // namespace revolve::station
