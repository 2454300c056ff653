#pragma once
// How a cohort spreads over ranks: the dynamic balancing of WorkPool::map (a free rank takes
// the next patient) replayed on measured per-patient times.
#include <cstdint>
#include <vector>

namespace mvtwin::studies {

/// Wall time of items taking `times` (s, in index order) on `ranks` workers that each take the
/// next item when free.
double dynamic_makespan(const std::vector<double>& times, int ranks);

/// sum(times) / (ranks x makespan): 1 when no rank waits.
double dynamic_efficiency(const std::vector<double>& times, int ranks);

/// Expected efficiency for a cohort of `patients` whose times are drawn with replacement from
/// `measured` (seeded), the mean over `trials` draws. Throws mvtwin::Error for empty input.
double expected_efficiency(const std::vector<double>& measured, int patients, int ranks,
                           std::uint64_t seed = 1, int trials = 20);

}  // namespace mvtwin::studies
