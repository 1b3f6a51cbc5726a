// Tests of solvers/staged_tasks.hpp: tasks in stages on threads, each task once, a stage after
// every earlier one, and each thread's home share of a stage claimed by that thread first.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "solvers/staged_tasks.hpp"

namespace pbdbench::test {
namespace {

// wait[] of stages with these numbers of tasks (each task waits for the tasks before its stage).
std::vector<int> stages(const std::vector<int>& sizes) {
  std::vector<int> wait;
  int before = 0;
  for (int n : sizes) {
    for (int k = 0; k < n; ++k) wait.push_back(before);
    before += n;
  }
  return wait;
}

TEST(StagedTasks, EachTaskOnceAndAfterEveryEarlierStage) {
  const std::vector<int> wait = stages({1, 5, 3, 7, 1, 16, 2, 9});
  const int n = static_cast<int>(wait.size());
  for (int threads : {1, 2, 3, 4}) {
    std::vector<std::atomic<int>> runs(static_cast<size_t>(n));
    std::vector<std::atomic<int>> finished(static_cast<size_t>(n));
    std::atomic<int> early{0}, bad_thread{0};
    run_staged(threads, wait, [&](int k, int thread) {
      if (thread < 0 || thread >= threads) bad_thread.fetch_add(1);
      for (int j = 0; j < wait[static_cast<size_t>(k)]; ++j)
        if (finished[static_cast<size_t>(j)].load() == 0) early.fetch_add(1);
      runs[static_cast<size_t>(k)].fetch_add(1);
      std::this_thread::sleep_for(std::chrono::microseconds(50));
      finished[static_cast<size_t>(k)].store(1);
    });
    for (int k = 0; k < n; ++k) EXPECT_EQ(runs[static_cast<size_t>(k)].load(), 1) << "task " << k << ", " << threads << " threads";
    EXPECT_EQ(early.load(), 0) << threads << " threads";
    EXPECT_EQ(bad_thread.load(), 0);
  }
}

// Two threads, one stage of 8 tasks: thread 0's share is tasks 0-3, thread 1's 4-7. Tasks 0 and 4
// each wait until the other has started, so neither thread can finish its share and take the
// other's before both have started: task 0 can only be claimed first by thread 0, and task 4 by
// thread 1. (With one counter for the whole stage, which thread claimed task 0 was a race.)
TEST(StagedTasks, EachThreadClaimsItsHomeShareFirst) {
  const std::vector<int> wait = stages({8});
  std::atomic<bool> started[8] = {};
  std::atomic<int> thread_of[8];
  for (auto& t : thread_of) t.store(-1);
  std::atomic<bool> timed_out{false};
  const auto await = [&](int other) {
    const auto limit = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (!started[other].load()) {
      if (std::chrono::steady_clock::now() > limit) {
        timed_out.store(true);
        return;
      }
      std::this_thread::yield();
    }
  };
  run_staged(2, wait, [&](int k, int thread) {
    thread_of[k].store(thread);
    started[k].store(true);
    if (k == 0) await(4);
    if (k == 4) await(0);
  });
  ASSERT_FALSE(timed_out.load()) << "tasks 0 and 4 did not run at the same time";
  EXPECT_EQ(thread_of[0].load(), 0);
  EXPECT_EQ(thread_of[4].load(), 1);
  for (int k = 0; k < 8; ++k) EXPECT_GE(thread_of[k].load(), 0) << "task " << k;
}

}  // namespace
}  // namespace pbdbench::test
