#pragma once
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace mvtwin::inverse {

/// Runs fn(i) for every i in [0, n), `jobs` at a time, one index per task (each is a whole
/// simulation). TBB: a task arena of `jobs` threads. Under ThreadSanitizer (scripts/tsan) the
/// same work runs on std::threads taking the next index from an atomic counter: libtbb is not
/// built with the sanitizer, so its hand-over of tasks is invisible to it and would be reported
/// as races on every task's captured state.
template <typename Fn>
void parallel_indices(std::size_t n, int jobs, const Fn& fn) {
  jobs = std::max(1, jobs);
#if defined(__SANITIZE_THREAD__)
  std::atomic<std::size_t> next{0};
  auto worker = [&] {
    for (std::size_t i = next++; i < n; i = next++) fn(i);
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < jobs && static_cast<std::size_t>(t) < n; ++t) threads.emplace_back(worker);
  worker();
  for (std::thread& t : threads) t.join();
#else
  tbb::task_arena arena(jobs);
  arena.execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 1),
        [&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) fn(i);
        },
        tbb::simple_partitioner());
  });
#endif
}

}  // namespace mvtwin::inverse
