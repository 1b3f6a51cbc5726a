// The options every command that makes many runs shares (paper, claims, regress, sweep), to split
// its runs into shards and to run them as a Slurm job array:
//
//   --shard I/N            make only the runs of shard I of N: one task of an array; shards are
//                          counted from 0, as Slurm's array task ids (0/N to N-1/N)
//   --merge N              after N shards: check that every run is finished (else exit 1, naming
//                          the shards that are not and how to make them) and write the report,
//                          index.json and the summary; it makes no run
//   --slurm N              submit the runs as a Slurm job array of N tasks and the merge after it
//                          (harness/slurm.hpp): scripts and logs in <run files>/slurm/
//   --slurm-opt OPTS       sbatch options for both jobs (repeatable): '--time=02:00:00 -p short'
//   --slurm-template FILE  #SBATCH lines and environment setup (module load ...) for both jobs
//   --no-submit            with --slurm: write the scripts and print how to submit them
//
// Every command gives its shards the same names: index.shard-I-of-N.json beside the run files,
// then index.json after the merge.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "harness/shards.hpp"

namespace pbdbench::app {

struct ArrayOptions {
  std::string shard;                      // --shard I/N
  int merge = 0;                          // --merge N
  int slurm = 0;                          // --slurm N
  std::vector<std::string> slurm_options;  // --slurm-opt
  std::string slurm_template;             // --slurm-template
  bool no_submit = false;                 // --no-submit
};

// Adds the options above to a subcommand.
void add_array_options(CLI::App* command, ArrayOptions& options);

// "--shard I/N" -> (I, N); throws config::ConfigError (bad input, naming the numbering from 0) unless
// 0 <= I < N, or when --shard, --merge and --slurm are mixed.
void parse_array_options(const ArrayOptions& options, int& shard_index, int& shard_count);

// --slurm N: writes the scripts to <run_files>/slurm and submits the shards that hold a run still
// to make (shard[k], to_make[k] for each run k; none: only the merge), or prints how with
// --no-submit. argv is the command line as typed (the scripts carry all of it but the Slurm
// options). Returns the exit code.
// `what`: what the units are, for the message ("runs").
int submit_to_slurm(const std::string& command, const ArrayOptions& options, const std::filesystem::path& run_files,
                    const std::vector<int>& shard, const std::vector<bool>& to_make, int argc, char** argv,
                    std::ostream& out, const std::string& what = "runs");

// The merge's refusal, printed to `err`: the unfinished runs by shard, then how to make them
// (resubmit with <run_files>/slurm/submit.sh when --slurm wrote it, else the --shard commands).
void report_unfinished(const std::string& command, const std::vector<UnfinishedRun>& runs, int shards,
                       const std::filesystem::path& run_files, std::ostream& err);

}  // namespace pbdbench::app
