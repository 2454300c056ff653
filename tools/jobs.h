#pragma once
// Independent pieces of work (a benchmark's patients) run a few at a time.
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <functional>
#include <thread>
#include <vector>

namespace mvtwin::tools {

/// Calls work(i) for every i in [0, n), `jobs` threads at a time, each taking the next i. `work`
/// must not throw (catch and record per item: one bad patient must not stop a batch).
inline void run_jobs(std::size_t n, int jobs, const std::function<void(std::size_t)>& work) {
  std::atomic<std::size_t> next{0};
  auto worker = [&] {
    for (std::size_t i; (i = next++) < n;) work(i);
  };
  const int nt = std::max(1, std::min<int>(jobs, static_cast<int>(n)));
  std::vector<std::thread> pool;
  for (int t = 1; t < nt; ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
}

}  // namespace mvtwin::tools
