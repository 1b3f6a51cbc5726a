// How many threads the next projection sweep runs on, when solver.threads = 0 leaves it to the
// run: the cores it may use, or one, whichever the run's own sweeps show to be faster.
//
// Two threads on an otherwise idle 2-core machine made the 256x256 cloth's coloured sweeps 1.7 to 2.0 times
// as fast as one; with one other busy process on the machine, 0.5 to 0.8 times as fast
// (scripts/bench_ab.py, with and without --load 1): a thread the operating system sets aside in the middle of
// a colour holds the colour's end. Which is faster is a property of the machine at the time,
// not of the run, so it is measured as the run goes. The sweeps compute the same bits at any
// thread count (solvers/staged_tasks.hpp), so the choice changes when a run finishes, never what it
// computes.
//
// The rule: the first sweeps alternate `most` and 1 until each has kSamples timings; then every
// sweep runs on the count whose median of its last kSamples timings is lower (the favoured),
// except a probe now and then, which runs on the other, so that a change of load is seen both
// ways. A probe's timing stands for all of its count's samples: when it is faster than the
// favoured's median the choice turns at once (and turns back within two sweeps if that was
// luck, when the new favoured's own timings come in). The first probe comes kProbeFirst sweeps
// after the timings are in; each probe that leaves the favoured as it was doubles the wait for
// the next, up to kProbeMost sweeps; a change of the favoured (by a probe or by its own
// timings) brings it back to kProbeFirst. So a steady machine is probed rarely (a probe on the
// slower count costs a sweep's worth of time or more), and a changing one soon. With
// `adaptive` false, every sweep runs on `most`. Pure: no clock here; the caller times.
#pragma once

#include <algorithm>
#include <array>

namespace pbdbench {

class SweepThreads {
 public:
  static constexpr int kSamples = 3;
  static constexpr long kProbeFirst = 64;
  static constexpr long kProbeMost = 512;

  SweepThreads(int most, bool adaptive) : most_(std::max(1, most)), adaptive_(adaptive && most > 1) {}

  // The threads of the next sweep.
  int next() {
    if (!adaptive_) return most_;
    ++calls_;
    for (int c : {1, 0})  // `most` first
      if (filled_[static_cast<size_t>(c)] < kSamples && filled_[static_cast<size_t>(c)] <= filled_[static_cast<size_t>(1 - c)])
        return count_of(c);
    const int best = favoured();
    if (calls_ >= next_probe_) {
      probing_ = true;
      return count_of(1 - best);
    }
    return count_of(best);
  }

  // The seconds a sweep on `threads` took.
  void record(int threads, double seconds) {
    if (!adaptive_) return;
    const size_t c = threads == 1 ? 0 : 1;
    if (probing_) {
      samples_[c].fill(seconds);
    } else {
      samples_[c][static_cast<size_t>(cursor_[c])] = seconds;
      cursor_[c] = (cursor_[c] + 1) % kSamples;
      filled_[c] = std::min(filled_[c] + 1, kSamples);
    }
    if (filled_[0] < kSamples || filled_[1] < kSamples) return;
    const int now = favoured();
    if (last_favoured_ < 0 || now != last_favoured_) {  // the timings just came in, or it changed
      interval_ = kProbeFirst;
      next_probe_ = calls_ + interval_;
    } else if (probing_) {  // the probe left it as it was
      interval_ = std::min(2 * interval_, kProbeMost);
      next_probe_ = calls_ + interval_;
    }
    probing_ = false;
    last_favoured_ = now;
  }

  // The count the timings favour now (`most` until both have theirs; `most` when not adaptive):
  // what work between the sweeps (xpbd's residuals) runs on.
  int chosen() const {
    if (!adaptive_ || filled_[0] < kSamples || filled_[1] < kSamples) return most_;
    return count_of(favoured());
  }

  // The most threads a sweep may run on.
  int most() const { return most_; }
  bool adaptive() const { return adaptive_; }

 private:
  int count_of(int c) const { return c == 0 ? 1 : most_; }
  double median(size_t c) const {
    std::array<double, kSamples> s = samples_[c];
    std::sort(s.begin(), s.end());
    return s[kSamples / 2];
  }
  // 1 (index 1: `most`) when its median is not above one thread's, else 0.
  int favoured() const { return median(1) <= median(0) ? 1 : 0; }

  int most_;
  bool adaptive_;
  long calls_ = 0;
  long interval_ = kProbeFirst;        // sweeps from one probe to the next
  long next_probe_ = 0;                // the call that probes next (set once the timings are in)
  bool probing_ = false;               // the last sweep given out was a probe
  int last_favoured_ = -1;             // favoured() after the last record (-1: not yet)
  std::array<std::array<double, kSamples>, 2> samples_{};  // [0]: one thread, [1]: most
  std::array<int, 2> cursor_{0, 0};
  std::array<int, 2> filled_{0, 0};
};

}  // namespace pbdbench
