#include "mvtwin/studies/scaling.h"

#include <algorithm>
#include <functional>
#include <numeric>
#include <queue>

#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"

namespace mvtwin::studies {

double dynamic_makespan(const std::vector<double>& times, int ranks) {
  if (ranks < 1) throw Error("dynamic_makespan: ranks must be >= 1");
  // Min-heap of the times at which each rank becomes free.
  std::priority_queue<double, std::vector<double>, std::greater<>> free_at;
  for (int r = 0; r < ranks; ++r) free_at.push(0.0);
  double end = 0;
  for (double t : times) {
    const double start = free_at.top();
    free_at.pop();
    free_at.push(start + t);
    end = std::max(end, start + t);
  }
  return end;
}

double dynamic_efficiency(const std::vector<double>& times, int ranks) {
  const double m = dynamic_makespan(times, ranks);
  if (m <= 0) return 1.0;
  return std::accumulate(times.begin(), times.end(), 0.0) / (ranks * m);
}

double expected_efficiency(const std::vector<double>& measured, int patients, int ranks,
                           std::uint64_t seed, int trials) {
  if (measured.empty() || patients < 1 || trials < 1)
    throw Error("expected_efficiency: needs measured times, patients and trials");
  Rng rng(seed);
  double sum = 0;
  std::vector<double> draw(static_cast<std::size_t>(patients));
  for (int k = 0; k < trials; ++k) {
    for (double& t : draw)
      t = measured[static_cast<std::size_t>(
          rng.uniform_int(0, static_cast<int>(measured.size()) - 1))];
    sum += dynamic_efficiency(draw, ranks);
  }
  return sum / trials;
}

}  // namespace mvtwin::studies
