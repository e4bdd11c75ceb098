// The reconstruction's loops on every core, on oneTBB's work-stealing pool (Debian libtbb-dev):
// nested loops share the one pool instead of each starting threads, and tbb::global_control
// bounds the threads for a whole process or a test.
//
// Contract of every use in revolve: the result does not depend on the number of threads nor on
// how the work is split. Each index writes only its own outputs; whatever is combined over
// indices is combined afterwards, in index order, on one thread (or with an order-independent
// exact operation such as min), never as a floating-point sum in the order the tasks finish.
#pragma once

#include <cstddef>
#include <memory>

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

namespace revolve::reconstruct {

// fn(i) for every i in [begin, end), spread over the cores, at least `grain` indices a task.
template <typename Fn>
void ParallelFor(std::size_t begin, std::size_t end, const Fn& fn, std::size_t grain = 1) {
  if (begin >= end) return;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(begin, end, grain),
                    [&fn](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i) fn(i);
                    });
}

// fn(lo, hi) over disjoint chunks [lo, hi) that cover [begin, end), each of at least `grain`
// indices (but the last), spread over the cores: for loops that keep scratch per chunk.
template <typename Fn>
void ParallelChunks(std::size_t begin, std::size_t end, std::size_t grain, const Fn& fn) {
  if (begin >= end) return;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(begin, end, grain),
      [&fn](const tbb::blocked_range<std::size_t>& range) { fn(range.begin(), range.end()); });
}

// Runs every function given, possibly at once; returns when all have returned.
template <typename... Fns>
void ParallelInvoke(const Fns&... fns) {
  tbb::parallel_invoke(fns...);
}

// While it lives, the parallel loops of the process use at most `threads` threads (1: all on the
// calling thread; values below 1 count as 1). The tests compare a one-thread run with an
// all-core run through it; the innermost live limit wins.
class ThreadLimit {
 public:
  explicit ThreadLimit(int threads);
  ~ThreadLimit();
  ThreadLimit(const ThreadLimit&) = delete;
  ThreadLimit& operator=(const ThreadLimit&) = delete;

 private:
  std::unique_ptr<tbb::global_control> control_;
};

// The threads the parallel loops may use now (the cores this process may run on, or less under a
// ThreadLimit).
int ThreadCount();

}  // namespace revolve::reconstruct
