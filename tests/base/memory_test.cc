#include "base/memory.h"

#include <sys/resource.h>

#include <cstddef>
#include <cstdlib>
#include <cstring>

#include <gtest/gtest.h>

namespace revolve::base {
namespace {

long MinorFaults() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_minflt;
}

// Writes `bytes` of fresh memory and frees it; returns the page faults the writing took.
long FaultsToWrite(std::size_t bytes) {
  const long before = MinorFaults();
  char* block = static_cast<char*>(std::malloc(bytes));
  if (block == nullptr) return -1;
  std::memset(block, 1, bytes);
  // The writes are not optimised away: the block escapes.
  asm volatile("" : : "r"(block) : "memory");
  std::free(block);
  return MinorFaults() - before;
}

// What the station relies on: once the finish's working memory has been written and freed,
// the next scan writes it again without page faults.
TEST(Memory, FreedMemoryIsReusedWithoutPageFaults) {
#if defined(__GLIBC__)
  ASSERT_TRUE(RetainFreedMemory());
  constexpr std::size_t kBytes = 24u << 20;  // 24 MiB: under the 32 MiB mmap threshold
  const long first = FaultsToWrite(kBytes);
  const long again = FaultsToWrite(kBytes);
  // 6144 pages; the first writing faults on most of them (the heap is new), the second on
  // almost none (a few for the allocator's own bookkeeping at most).
  EXPECT_GT(first, 1000);
  EXPECT_LT(again, 64);
#else
  GTEST_SKIP() << "glibc only";
#endif
}

}  // namespace
}  // namespace revolve::base
