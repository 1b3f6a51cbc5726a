// Tasks in stages on a few threads, without barriers: task k may start once the first wait[k]
// tasks are done (a stage, the tasks that share one wait value, waits for every earlier stage).
// Which thread runs which task never changes what a task computes (the projection sweeps give
// each task items no other task of its stage touches), so the results do not depend on the
// thread count or the timing.
//
// Each thread has a home share of every stage: thread t of T first claims the tasks
// [b + t m / T, b + (t + 1) m / T) of a stage [b, b + m), in order, then takes the tasks still
// unclaimed in the other threads' shares. A stage's tasks are in the order of the items (for the
// sweeps: a colour's items in model order, which on the generated meshes is space), so a thread
// keeps projecting the same region of the mesh from colour to colour and the particles it writes
// stay in its core's cache; when tasks were claimed from one shared counter, the thread of a
// region changed from colour to colour and its particles moved between cores each time (the
// 256x256 cloth, 2 threads: solver/cloth256*/t2 of bench_solvers). A thread waits only for tasks
// other threads are running, never for a thread to arrive: a thread that the operating system
// has set aside holds nothing up unless it holds a task, since its share is taken by the others.
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
  // Stages: runs of equal wait values, [stage_begin[s], stage_begin[s + 1]).
  std::vector<int> stage_begin;
  for (int k = 0; k < n; ++k)
    if (k == 0 || wait[static_cast<size_t>(k)] != wait[static_cast<size_t>(k - 1)]) stage_begin.push_back(k);
  const int stages = static_cast<int>(stage_begin.size());
  stage_begin.push_back(n);
  // One claim cursor per (stage, home share), each on a cache line of its own.
  struct alignas(64) Cursor {
    std::atomic<int> next{0};
  };
  std::vector<Cursor> cursor(static_cast<size_t>(stages) * static_cast<size_t>(threads));
  const auto share_begin = [&](int s, int t) {
    const long b = stage_begin[static_cast<size_t>(s)], m = stage_begin[static_cast<size_t>(s) + 1] - b;
    return static_cast<int>(b + m * t / threads);
  };
  for (int s = 0; s < stages; ++s)
    for (int t = 0; t < threads; ++t)
      cursor[static_cast<size_t>(s * threads + t)].next.store(share_begin(s, t), std::memory_order_relaxed);
  alignas(64) std::atomic<int> done{0};
#pragma omp parallel num_threads(threads)
  {
    const int me = omp_get_thread_num();
    for (int s = 0; s < stages; ++s) {
      // Wait for the earlier stages: spin briefly, then let other threads (and processes) run.
      const int need = wait[static_cast<size_t>(stage_begin[static_cast<size_t>(s)])];
      for (int spins = 0; done.load(std::memory_order_acquire) < need; ++spins) {
        if (spins < 4096) _mm_pause();
        else sched_yield();
      }
      // The home share first, then what is left of the others' (also when the team is smaller
      // than asked: every share is taken by whoever runs).
      for (int o = 0; o < threads; ++o) {
        const int t = (me + o) % threads;
        std::atomic<int>& next = cursor[static_cast<size_t>(s * threads + t)].next;
        const int end = share_begin(s, t + 1);
        for (;;) {
          if (next.load(std::memory_order_relaxed) >= end) break;
          const int k = next.fetch_add(1, std::memory_order_relaxed);
          if (k >= end) break;
          task(k, me);
          done.fetch_add(1, std::memory_order_release);
        }
      }
    }
  }
}

}  // namespace pbdbench
