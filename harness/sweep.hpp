// Sweeps: one scenario run over a grid of parameters, in parallel, skipping runs already done.
//
// A sweep file (TOML):
//   name = "chain_iterations_vs_substeps"
//   scenario = "hanging_chain"            # a catalog name, or a path relative to this file
//   description = "..."
//   [set]                                 # overrides applied to every run
//   "time.duration" = 2.0
//   [grid]                                # every combination of these values
//   "solver.name" = ["pbd", "xpbd"]
//   [[case]]                              # optional: explicit sets of overrides, each combined
//   "solver.iterations" = 10              #   with every grid point
//   "solver.substeps" = 1
//
// Keys may be quoted dotted paths ("solver.iterations") or nested tables ([set.solver]); a key
// swept twice (twice in [grid] or in one [[case]], or in both) is refused. `name` is one plain
// folder name (results/sweeps/<name>/). At most kMaxSweepRuns runs.
// Each run writes <out>/<parameters>.h5 and a log beside it; <out>/index.json lists them all,
// written when the sweep ends, and <out>/index.jsonl has a line per run as it ends (a shard:
// <out>/index.shard-I-of-N.json and .jsonl). docs/sweeps.md has the formats.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include "config/config.hpp"
#include "harness/shards.hpp"

namespace pbdbench {

// The most runs a sweep file may make (grid points times cases), counted before the grid is
// expanded. Checking a run (its configuration built, its file compared) costs about a
// millisecond and its entry about a kilobyte (docs/sweeps.md, "Limits", has the measurement), so
// the limit keeps a sweep's check to about two minutes and its memory to about a hundred
// megabytes; a grid of more runs is a mistake, or a study to split into several sweep files.
inline constexpr std::size_t kMaxSweepRuns = 100000;

struct SweepRun {
  std::vector<std::pair<std::string, std::string>> params;  // swept path -> TOML value text
  std::vector<config::Override> overrides;                  // [set], then the run's params
  std::string stem;                                         // file name without extension
};

struct SweepSpec {
  std::string name;
  std::string description;
  std::string scenario;               // resolved path of the scenario file
  std::filesystem::path file;         // the sweep file
  std::vector<std::string> parameters;  // swept paths, in order (grid keys, then case keys)
  std::vector<SweepRun> runs;           // the expanded runs, in a stable order
};

// Reads and expands a sweep file. Throws config::ConfigError naming the file and line.
SweepSpec load_sweep(const std::filesystem::path& path);

struct SweepOptions {
  std::filesystem::path out_dir;     // where the run files go
  int jobs = 1;                      // runs at once (child processes)
  bool force = false;                // rerun runs that are already complete
  int shard_index = 0;               // run only the runs with index % shard_count == shard_index
  int shard_count = 1;               // (harness/shards.hpp: one run a unit, dealt in turn)
  int merge_shards = 0;              // > 0: the merge of this many shards: run nothing; the runs
                                     // not current are SweepResult::unfinished, and index.json is
                                     // written only when there are none
  std::vector<config::Override> extra;  // --set overrides applied after the sweep's own
  std::filesystem::path executable;  // the pbdbench binary that runs each child
  bool progress = false;             // print a line per finished run
};

struct SweepRunResult {
  std::filesystem::path file;
  std::string status;  // complete, exploded, failed, incomplete, refused, busy (another process is
                       // writing the file), pending (not started: the sweep was interrupted)
  bool skipped = false;  // already complete with the same configuration and build
  std::string message;   // the failure or refusal, when any
};

struct SweepResult {
  std::vector<SweepRunResult> runs;  // one per run of this shard, in the sweep's order
  std::vector<UnfinishedRun> unfinished;  // a merge: the runs not finished, by shard
  bool interrupted = false;          // a cancellation (core/cancel.hpp) stopped it
  bool ok() const;                   // every run complete or exploded, nothing unfinished
};

// Validates every run's configuration first (nothing starts if one is refused: the error names
// the sweep file and the run; a cancellation stops the check, interrupted, nothing started),
// then runs those not already complete, `jobs` at a time, appending a line per run to
// <out_dir>/index.jsonl as each ends, and writes <out_dir>/index.json at the end. Refuses
// (config::ConfigError, key "--out") an out_dir that holds the index of another sweep, or a run
// log that no index of this sweep accounts for. Messages go to `log`.
SweepResult run_sweep(const SweepSpec& spec, const SweepOptions& options, std::ostream& log);

// Runs in child processes, `executable run SCENARIO --set ... --out FILE --quiet`, `jobs` at a
// time, each child's output in FILE with the extension .log. on_done(index, status, message) is
// called as each ends: status complete, exploded, refused, failed or incomplete (from the exit
// code), or busy without starting it when another process holds the file's lock; the tail of
// the log as the message of a run neither complete nor exploded. Each child dies with the
// calling thread (SIGTERM). A cancellation (core/cancel.hpp) stops the launching, sends SIGTERM
// to the running children and waits for them; the function then returns false (runs not
// started get no call).
struct ChildRun {
  std::string scenario;                      // a file or a catalog name
  std::vector<config::Override> overrides;
  std::filesystem::path file;                // the run file to write (its folder is created)
};
bool run_children(const std::filesystem::path& executable, const std::vector<ChildRun>& runs, int jobs,
                  const std::function<void(size_t, const std::string&, const std::string&)>& on_done);

// True when `file` holds a finished run (complete or exploded) of exactly this configuration
// text, made by this build (same git commit).
bool run_is_current(const std::filesystem::path& file, const std::string& config_toml);

}  // namespace pbdbench
