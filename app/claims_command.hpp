// `pbdbench claims [ID...]` and `pbdbench paper [ID...]`: run the experiments, decide the
// verdicts and write the report.
//
//   pbdbench claims                      every claim, full tier -> paper/claims/
//   pbdbench claims S5.4                 one claim, full tier   -> results/claims/full/
//   pbdbench claims --tier quick --expect claims/verdicts_quick.toml   (the test suite)
//   pbdbench paper                       every reproduction, full tier -> paper/
//   pbdbench paper --jobs 8              the runs 8 at a time in child processes, then the report
//   pbdbench paper --shard 3/16          only the runs of shard 3 of 16 (a job array), no report
//   pbdbench paper --slurm 16            print a Slurm job-array script for 16 shards
//
// Run files go to results/<claims|paper>/<tier>/runs/<id>/ unless --runs says otherwise; a run
// file already holding the same finished configuration from the same build is read, not run again
// (--force runs everything again), so shards merge by running the command once more without
// --shard: it finds every shard's files, runs what is missing and writes the report and
// <runs>/index.json (every run file with its status).
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "experiments/experiment.hpp"

namespace pbdbench::experiments {

struct ClaimsCommand {
  ExperimentKind kind = ExperimentKind::Claim;  // claims, or the paper's reproductions
  std::vector<std::string> ids;        // empty: every experiment
  Tier tier = Tier::Full;
  std::filesystem::path experiments;   // default: experiments_dir() or reproductions_dir()
  std::filesystem::path out;           // default: see above
  std::filesystem::path runs;          // default: results/<claims|paper>/<tier>/runs
  bool force = false;
  int jobs = 1;                        // > 1: the runs in child processes, this many at a time
  int shard_index = 0;                 // with shard_count > 1: only these runs, no report
  int shard_count = 1;
  std::filesystem::path executable;    // the pbdbench binary for child processes
  std::filesystem::path record;        // write the verdicts here
  std::filesystem::path expect;        // compare the verdicts with this record
  std::string command_line;            // as typed, for the report
};

struct ClaimsOutcome {
  std::filesystem::path out;             // the folder written ("" for a shard)
  std::vector<std::string> differences;  // from --expect
  int failed_runs = 0;                   // runs that failed in child processes
};

// Throws ExperimentError for a bad experiment file or an unknown id.
ClaimsOutcome run_claims(const ClaimsCommand& command, std::ostream& out, std::ostream& log);

// `pbdbench register claims|paper [IDS] [--note TEXT]`: records the SHA-256 of each experiment file
// whose content is not registered yet in the registry beside its folder (experiments/registry.hpp).
// When the committed report already holds results for an experiment, the registration is a
// revision after results: the note is required, and the earlier verdicts and rules are kept in
// the entry. Returns the number of experiments registered. Throws ExperimentError for bad input.
struct RegisterCommand {
  ExperimentKind kind = ExperimentKind::Claim;
  std::vector<std::string> ids;       // empty: every experiment of the folder
  std::string note;
  std::filesystem::path experiments;  // default: experiments_dir() or reproductions_dir()
  std::filesystem::path results;      // the report's JSON (default paper/claims/claims.json or
                                      // paper/reproductions.json)
};
int run_register(const RegisterCommand& command, std::ostream& out);

// A Slurm job-array script that runs `command` (its kind, tier, ids and runs folder) as
// `shards` array tasks, then the report in a job that depends on the array.
std::string slurm_script(const ClaimsCommand& command, int shards);

}  // namespace pbdbench::experiments
