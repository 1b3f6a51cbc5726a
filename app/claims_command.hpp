// `pbdbench claims [ID...]` and `pbdbench paper [ID...]`: run the experiments, decide the
// verdicts and write the report.
//
//   pbdbench claims                      every claim, full tier -> paper/claims/
//   pbdbench claims S5.4                 one claim, full tier   -> results/claims/full/
//   pbdbench claims --tier quick --expect claims/verdicts_quick.toml   (the test suite)
//   pbdbench paper                       every reproduction, full tier -> paper/
//   pbdbench paper --jobs 8              the runs 8 at a time in child processes, then the report
//   pbdbench paper --shard 3/16          only the runs of shard 3/16 (counted from 0), no report
//   pbdbench paper --merge 16            after the 16 shards: check every run, write the report
//   pbdbench paper --slurm 16            submit the shards as a Slurm job array, then the merge
//                                        (app/slurm_command.hpp, docs/cluster.md)
//
// Default folders are relative to the working folder, like every command's: run files in
// results/<claims|paper>/<tier>/runs/<id>/ (--runs), the report in results/<claims|paper>/<tier>
// (--out), or paper/ and paper/claims/ for every experiment of the full tier. A run file already
// holding the same finished configuration from the same build is read, not run again (--force
// runs everything again). Shards: every run is a unit of its own, every [[timing]] group one unit
// timed whole in one task (experiments/timing.hpp: its costs are compared with each other); a shard
// writes <runs>/index.shard-I-of-N.json, the merge (and --jobs) <runs>/index.json (every run file
// with its status).
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "experiments/experiment.hpp"
#include "harness/shards.hpp"

namespace pbdbench::experiments {

struct ClaimsCommand {
  ExperimentKind kind = ExperimentKind::Claim;  // claims, or the paper's reproductions
  std::vector<std::string> ids;        // empty: every experiment
  Tier tier = Tier::Full;
  std::filesystem::path experiments;   // default: experiments_dir() or reproductions_dir()
  std::filesystem::path out;           // default: see above
  std::filesystem::path runs;          // default: results/<claims|paper>/<tier>/runs
  bool force = false;
  int jobs = 0;                        // > 1: the runs in child processes, this many at a time;
                                       // 0: in this process, or a shard's: the allocation's cores
  int shard_index = 0;                 // with shard_count > 1: only these runs, no report
  int shard_count = 1;
  int merge_shards = 0;                // > 0: the merge of this many shards (makes no run)
  std::filesystem::path executable;    // the pbdbench binary for child processes
  std::filesystem::path record;        // write the verdicts here
  std::filesystem::path expect;        // compare the verdicts with this record
  std::string command_line;            // as typed, for the report
};

struct ClaimsOutcome {
  std::filesystem::path out;             // the folder written ("" for a shard, or a merge refused)
  std::filesystem::path runs;            // the run files' folder
  std::vector<std::string> differences;  // from --expect
  int failed_runs = 0;                   // runs that failed in child processes
  std::vector<UnfinishedRun> unfinished;  // a merge: the runs not finished (then nothing written)
};

// Throws ExperimentError for a bad experiment file or an unknown id.
ClaimsOutcome run_claims(const ClaimsCommand& command, std::ostream& out, std::ostream& log);

// The run files' folder: --runs, else results/<claims|paper>/<tier>/runs.
std::filesystem::path runs_folder(const ClaimsCommand& command);

// For --slurm: the shard of every unit of `shards` (each planned run, each [[timing]] group),
// and whether it is still to be made.
struct ShardPlan {
  std::vector<int> shard;     // per unit
  std::vector<bool> to_make;  // not current, or --force
};
ShardPlan shard_plan(const ClaimsCommand& command, int shards);

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

}  // namespace pbdbench::experiments
