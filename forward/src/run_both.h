#pragma once
#include <functional>

namespace mvtwin::forward {

/// Runs a and b: at the same time when threads > 1 (on TBB's workers, isolated, so that the
/// waiting thread never picks up unrelated work such as another candidate's simulation), one
/// after the other when threads == 1. Callers give a and b disjoint outputs and combine them in
/// a fixed order afterwards, so that no result depends on threads.
void run_both(int threads, const std::function<void()>& a, const std::function<void()>& b);

}  // namespace mvtwin::forward
