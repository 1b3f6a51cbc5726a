// `pbdbench regress`: run the registry's cases, compare every metric with the stored baselines,
// print the table and write it (Markdown, HDF5, and the results as JSON for --against).
//
//   pbdbench regress                     quick tier against regress/baselines_quick.toml
//   pbdbench regress --tier full         every case against regress/baselines_full.toml
//   pbdbench regress --update            rewrite the tier's baselines (with the build that made them)
//   pbdbench regress --against DIR       compare with another run's DIR/regress.json (two builds,
//                                        two branches) instead of the stored baselines
//   pbdbench regress --repeat            run every case twice: the bitwise tier (determinism)
//   pbdbench regress --bitwise           print every case's hash against the stored one (else only
//                                        differences, in one line when another commit stored them)
//
//   pbdbench regress --shard 1/4         only the runs of shard 1/4 (counted from 0; one case a unit), no report
//   pbdbench regress --merge 4           after the shards: check every run, then compare and report
//   pbdbench regress --slurm 4           the shards as a Slurm job array, then the merge
//
// Output in results/regress/<tier>/ (or --out), relative to the working folder: regress.md,
// regress.h5, regress.json, the run files in runs/ (and repeat/ with --repeat). The exit code is
// non-zero when a metric is worse beyond its tolerance or a repeated run differs in a bit. The
// baselines are read from the data folder (config/data_dir.hpp); --update writes them there only
// when it is a source checkout (else give --baselines FILE).
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "experiments/experiment.hpp"
#include "harness/runner.hpp"
#include "harness/shards.hpp"

namespace pbdbench::regress {

struct RegressCommand {
  experiments::Tier tier = experiments::Tier::Quick;
  std::vector<std::string> cases;   // only these (default: the tier's)
  std::filesystem::path registry;   // default: regress/cases.toml
  std::filesystem::path baselines;  // default: regress/baselines_<tier>.toml
  std::filesystem::path against;    // compare with DIR/regress.json instead
  std::filesystem::path out;        // default: results/regress/<tier>
  bool update = false;
  bool repeat = false;
  bool bitwise = false;             // print the bitwise tier's line of every case
  bool force = false;               // run again even when current run files exist
  RunControl control;               // tests: a broken solver variant
  int jobs = 0;                     // > 1: the runs in child processes (a shard: 0 is the
                                    // allocation's cores); else in this process
  int shard_index = 0;              // with shard_count > 1: only these cases' runs, no report
  int shard_count = 1;
  int merge_shards = 0;             // > 0: the merge of this many shards (makes no run)
  std::filesystem::path executable;  // the pbdbench binary for child processes
};

struct RegressOutcome {
  std::filesystem::path out;        // "" for a shard or a refused merge
  std::filesystem::path runs;       // the run files' folder (<out>/runs)
  int failed_runs = 0;              // a shard's runs that failed
  std::vector<UnfinishedRun> unfinished;  // a merge: the runs not finished
  int worse = 0;
  int better = 0;
  int bit_differences = 0;  // --repeat
  bool updated = false;
};

// Throws experiments::ExperimentError for a bad registry or an unknown case, std::runtime_error for
// a missing or unreadable baseline.
RegressOutcome run_regress(const RegressCommand& command, std::ostream& out, std::ostream& log);

// For --slurm: the output folder, and every selected case's shard of `shards` with whether its
// runs are still to be made.
std::filesystem::path regress_out(const RegressCommand& command);
struct RegressShards {
  std::vector<int> shard;     // per case
  std::vector<bool> to_make;  // a run (or its --repeat) not current, or --force
};
RegressShards regress_shards(const RegressCommand& command, int shards);

}  // namespace pbdbench::regress
