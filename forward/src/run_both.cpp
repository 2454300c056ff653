#include "run_both.h"

#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

namespace mvtwin::forward {

void run_both(int threads, const std::function<void()>& a, const std::function<void()>& b) {
  if (threads <= 1) {
    a();
    b();
    return;
  }
  tbb::this_task_arena::isolate([&] { tbb::parallel_invoke(a, b); });
}

}  // namespace mvtwin::forward
