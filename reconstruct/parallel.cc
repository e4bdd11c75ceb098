#include "reconstruct/parallel.h"

#include <algorithm>

namespace revolve::reconstruct {

ThreadLimit::ThreadLimit(int threads)
    : control_(
          std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                static_cast<std::size_t>(std::max(threads, 1)))) {}

ThreadLimit::~ThreadLimit() = default;

int ThreadCount() {
  return static_cast<int>(
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

}  // namespace revolve::reconstruct
