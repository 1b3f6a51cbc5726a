// Tasks in stages on a few threads, without barriers: task k may start once the first wait[k]
// tasks are done (a stage's tasks wait for every earlier stage). The tasks are claimed in order
// from a shared counter by whichever thread is free, and a thread waits only for tasks other
// threads are running, never for a thread to arrive: on a machine shared with other work, a
// thread that the operating system has set aside holds nothing up unless it holds a task.
// Which thread runs which task never changes what a task computes (the projection sweeps give
// each task items no other task of its stage touches), so the results do not depend on the
// thread count or the timing.
//
//   run_staged(threads, wait, [&](int task, int thread) { ... });
//
// OpenMP threads (GCC's libgomp); with threads == 1 the tasks run in order on the caller.
#pragma once

#include <omp.h>

#include <atomic>
#include <sched.h>
#include <vector>

#include <emmintrin.h>

namespace pbdbench {

template <class Task>
void run_staged(int threads, const std::vector<int>& wait, Task&& task) {
  const int n = static_cast<int>(wait.size());
  if (threads <= 1 || n <= 1) {
    for (int k = 0; k < n; ++k) task(k, 0);
    return;
  }
  std::atomic<int> next{0}, done{0};
#pragma omp parallel num_threads(threads)
  {
    const int me = omp_get_thread_num();
    for (;;) {
      const int k = next.fetch_add(1, std::memory_order_relaxed);
      if (k >= n) break;
      // Wait for the earlier stages: spin briefly, then let other threads (and processes) run.
      for (int spins = 0; done.load(std::memory_order_acquire) < wait[static_cast<size_t>(k)]; ++spins) {
        if (spins < 4096) _mm_pause();
        else sched_yield();
      }
      task(k, me);
      done.fetch_add(1, std::memory_order_release);
    }
  }
}

}  // namespace pbdbench
