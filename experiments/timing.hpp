// Costs measured like a benchmark. The runs of a [[timing]] group (experiments/experiment.hpp) are
// timed together, in each of kTimingSessions separate processes (sessions) at separate times: one
// warm-up repeat, then `repeats` repeats, each running every
// run of the group once, in an order rotated from repeat to repeat (interleaved, so that a machine
// that slows down or speeds up weighs on every run alike). Each run's cost in a repeat is its
// solver time per step (RunOutcome::solver_time / steps, s): the solver's step, not the metrics or
// the output. A measure of the group evaluates its expression once per repeat; its value is the
// median over the repeats, with a distribution-free 95 % interval for the median.
//
// The samples are kept in <runs>/<experiment>/timing-<group>.toml with the machine, the build and
// the configurations timed; a record from the same build with the same configurations is read
// instead of timed again (unless forced), so a shard's timings merge like its run files.
#pragma once

#include <filesystem>
#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include "config/config.hpp"
#include "experiments/experiment.hpp"

namespace pbdbench::experiments {

// An interval for the median of n samples from order statistics: [x_(k), x_(n+1-k)] (1-based, the
// samples sorted) with the largest k such that P(Binomial(n, 1/2) < k) <= 0.025, so that it holds
// the median with probability `coverage` >= 0.95 whatever the distribution. With n < 6 no such k
// exists: the interval is the whole range and the coverage 1 - 2^(1-n).
struct MedianInterval {
  double median = 0.0;
  double lo = 0.0;
  double hi = 0.0;
  double coverage = 0.0;  // the interval's exact coverage probability
};
MedianInterval median_interval(std::vector<double> samples);

// A timing verdict needs the group timed in this many separate processes, at separate times: the
// spread between processes (a machine's state, the placement of memory, the other loads) is
// larger than the spread within one (S5.4.4's cost ratio read 1.12 [1.02, 1.25] in one process,
// 1.31 [1.24, 1.37] and 1.33 [1.21, 1.41] in two earlier ones).
inline constexpr int kTimingSessions = 3;

struct TimingResult {
  std::string group;
  std::vector<std::string> runs;                     // the group's runs, in the file's order
  std::vector<std::vector<double>> seconds_per_step;  // [repeat][run]: solver time per step (s)
  std::vector<std::string> status;                   // per run: complete, or the first other status
  std::string machine;
  std::string build;
  std::vector<int> session;           // per repeat: the session that timed it (from 0)
  std::vector<std::string> sessions;  // per session: "pid P, started T (UTC)"
  int processes = 0;                  // distinct processes among the sessions
  bool reused = false;     // read from a current record, not timed now
  double wall_time = 0.0;  // s spent timing now
  std::filesystem::path record;
};

// The value and interval of a timing measure from its per-repeat values over a group's repeats:
// the median of every repeat, and an interval that holds each session's 95 % interval of the
// median (so it includes the spread between the processes); its coverage is the least of theirs.
MedianInterval timing_interval(const TimingResult& timing, const std::vector<double>& per_repeat);

// The configuration a run of the group is timed in: the experiment's (Experiment::timing_overrides)
// and, for a solver that reads solver.threads when neither the experiment nor its scenario sets it,
// solver.threads = 1. The experiments' timings are registered for one thread; the default
// (0: the run's cores or one, sweep by sweep, whichever its own timings favour;
// docs/solvers.md) would make a timed run's thread count, and so a cost ratio,
// follow the machine's load rather than the experiment. The results of a run are the same bits
// at any thread count; only its time depends on it.
config::Config timing_config(const Experiment& experiment, const RunSpec& run, const TimingSpec& timing, Tier tier);

// Where a group's record lives.
std::filesystem::path timing_record_path(const std::filesystem::path& runs_dir, const std::string& experiment,
                                         const std::string& group);

// Whether the record holds the group's configurations in this tier from this build.
bool timing_is_current(const Experiment& experiment, const TimingSpec& timing, Tier tier,
                       const std::filesystem::path& runs_dir);

// Times one session of the group (a warm-up, then `repeats` interleaved repeats) in this process
// and appends it to the group's record (a record of another build or configuration is replaced).
void time_session(const Experiment& experiment, const TimingSpec& timing, Tier tier,
                  const std::filesystem::path& runs_dir, std::ostream* log);

// Makes one session in a separate process (`pbdbench time-session ...`); returns false when it
// could not. Empty: the sessions are timed in this process (the tests), and a part that reads
// them is inconclusive (fewer than kTimingSessions processes).
using SessionLauncher = std::function<bool(const std::filesystem::path& runs_dir)>;

// Reads the group's record and times the sessions it lacks (kTimingSessions in all; with --force
// all of them again), each by `launch` in a separate process, or here when it is empty. The timed
// runs' files go to <runs>/<experiment>/timing/<group>/ and are overwritten from repeat to repeat.
TimingResult time_group(const Experiment& experiment, const TimingSpec& timing, Tier tier,
                        const std::filesystem::path& runs_dir, bool force, std::ostream* log,
                        const SessionLauncher& launch = {});

}  // namespace pbdbench::experiments
