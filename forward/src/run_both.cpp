#include "run_both.h"

#include <thread>

#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

namespace mvtwin::forward {

void run_both(int threads, const std::function<void()>& a, const std::function<void()>& b) {
  if (threads <= 1) {
    a();
    b();
    return;
  }
#if defined(__SANITIZE_THREAD__)
  // Under ThreadSanitizer (scripts/tsan), b on a thread of its own: libtbb is not built with the
  // sanitizer, so its hand-over of tasks would be reported as races on the captured state.
  std::thread other(b);
  a();
  other.join();
#else
  tbb::this_task_arena::isolate([&] { tbb::parallel_invoke(a, b); });
#endif
}

}  // namespace mvtwin::forward
