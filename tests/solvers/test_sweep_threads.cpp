// Tests of solvers/sweep_threads.hpp: which thread count each sweep of solver.threads = 0 runs
// on, from timings given by hand.
#include "solvers/sweep_threads.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace pbdbench {
namespace {

// Runs `sweeps` sweeps whose time is seconds(threads, sweep); returns the counts they ran on.
template <class Seconds>
std::vector<int> run(SweepThreads& st, int sweeps, Seconds seconds) {
  std::vector<int> counts;
  for (int k = 0; k < sweeps; ++k) {
    const int t = st.next();
    counts.push_back(t);
    st.record(t, seconds(t, k));
  }
  return counts;
}

TEST(SweepThreads, AnExplicitCountIsEverySweepsAndOneIsNeverAdaptive) {
  SweepThreads fixed(4, false);
  EXPECT_FALSE(fixed.adaptive());
  for (int k = 0; k < 200; ++k) EXPECT_EQ(fixed.next(), 4);
  EXPECT_EQ(fixed.chosen(), 4);
  SweepThreads one(1, true);  // auto on one core: nothing to choose
  EXPECT_FALSE(one.adaptive());
  EXPECT_EQ(one.next(), 1);
  EXPECT_EQ(one.most(), 1);
}

// The sweeps that run on `value` among [from, to).
std::vector<int> where(const std::vector<int>& v, int value, size_t from, size_t to) {
  std::vector<int> out;
  for (size_t k = from; k < to && k < v.size(); ++k)
    if (v[k] == value) out.push_back(static_cast<int>(k));
  return out;
}

TEST(SweepThreads, TheFirstSweepsTryBothThenTheFasterIsKeptWithProbesFartherApart) {
  SweepThreads st(2, true);
  // Two threads take 1 ms, one 1.8 ms.
  const auto quiet = [](int t, int) { return t == 2 ? 1e-3 : 1.8e-3; };
  const std::vector<int> c = run(st, 3000, quiet);
  EXPECT_EQ((std::vector<int>(c.begin(), c.begin() + 6)), (std::vector<int>{2, 1, 2, 1, 2, 1}));
  EXPECT_EQ(st.chosen(), 2);
  // The timings are in after sweep 5 (the 6th call): the first probe 64 calls later (sweep 69),
  // then 128, 256, 512, and 512 from there on.
  EXPECT_EQ(where(c, 1, 6, c.size()), (std::vector<int>{69, 197, 453, 965, 1477, 1989, 2501}));
}

TEST(SweepThreads, ALoadThatComesIsSeenAndOneThatGoesIsSeenByAProbe) {
  SweepThreads st(2, true);
  // Quiet for 100 sweeps, loaded (two threads 1.5 times as slow as one) for 200, quiet again.
  const auto load = [](int t, int k) {
    const bool loaded = k >= 100 && k < 300;
    if (t == 1) return 1.8e-3;
    return loaded ? 2.7e-3 : 1e-3;
  };
  const std::vector<int> c = run(st, 1000, load);
  // Two loaded sweeps put two threads' median (of three) above one thread's: one thread from
  // sweep 102, probed 64 and then 128 sweeps later (both loaded); the next probe, 256 later,
  // finds the load gone and turns the choice at once.
  EXPECT_EQ(where(c, 2, 100, 549), (std::vector<int>{100, 101, 165, 293}));
  EXPECT_EQ(c[549], 2);
  // Then two threads, the probes of one thread 64 and 128 and 256 sweeps on.
  EXPECT_EQ(where(c, 1, 549, c.size()), (std::vector<int>{613, 741, 997}));
  EXPECT_EQ(st.chosen(), 2);
}

TEST(SweepThreads, ASingleSlowSweepDoesNotTurnTheChoiceAndALuckyProbeTurnsItBackSoon) {
  SweepThreads st(2, true);
  // Two threads are faster except one sweep that the operating system held up 10 times as long.
  const auto spike = [](int t, int k) { return t == 2 ? (k == 40 ? 1e-2 : 1e-3) : 1.8e-3; };
  std::vector<int> c = run(st, 120, spike);
  EXPECT_EQ(where(c, 1, 6, c.size()), (std::vector<int>{69}));  // the probe, and no other
  EXPECT_EQ(st.chosen(), 2);

  // A probe of one thread that happened to be fast (0.5 ms) turns the choice; one thread's own
  // next two sweeps (1.8 ms) turn it back, and the probes start again 64 sweeps later.
  SweepThreads lucky(2, true);
  const auto once = [](int t, int k) { return t == 2 ? 1e-3 : (k == 69 ? 5e-4 : 1.8e-3); };
  c = run(lucky, 200, once);
  EXPECT_EQ(where(c, 1, 6, c.size()), (std::vector<int>{69, 70, 71, 135}));
  EXPECT_EQ(lucky.chosen(), 2);
}

}  // namespace
}  // namespace pbdbench
