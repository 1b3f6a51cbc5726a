// Shards: the runs of a sweep, of the claims, the reproductions or the regression split into N
// parts that separate processes (a Slurm job array's tasks, or machines) make independently, and
// the merge that checks they did.
//
// The unit of a shard is a group of runs that must stay in one task (the runs whose costs a
// timing rule compares: wall-clock times from two nodes are not comparable); a command makes its
// units, deal_units() gives each a shard. Every task and the merge compute the same assignment,
// from the sizes alone. A run is finished when its file holds the planned configuration, made by
// this build, complete or exploded (run_is_current); the merge lists every other one by shard,
// with what the file says, and writes nothing else.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace pbdbench {

// Deals units of the given sizes (runs) to `shards` shards: the largest unit first (ties: the
// earlier unit), each to the shard with the fewest runs so far (ties: the lowest index). Equal
// sizes deal in turn (unit k to shard k % shards). Returns each unit's shard.
std::vector<int> deal_units(const std::vector<std::size_t>& sizes, int shards);

// What a run file says against the configuration planned for it:
//   current     complete or exploded, this configuration, this build (nothing to do)
//   missing     no file (the task never reached it, or did not start)
//   incomplete  the run was interrupted (the task was cancelled, timed out or killed)
//   failed      the run failed (its .log beside the file says why)
//   stale       a finished run of another configuration or another build
//   unreadable  not a run file pbdbench can read
std::string run_state(const std::filesystem::path& file, const std::string& config_toml);

// A run of a shard that is not current.
struct UnfinishedRun {
  int shard = 0;
  std::string label;  // what the user knows it by: "S5.4/bowl_sequential-003", a sweep's stem
  std::filesystem::path file;
  std::string state;  // run_state()
};

// How every message names shard `index` of `count`, as --shard takes it: "shard 1/4". Shards are
// counted from 0 (0/4 to 3/4), as a Slurm job array's task ids are.
std::string shard_name(int index, int count);

// The numbering of `count` shards, for a message: "counted from 0: 0/4 to 3/4" ("0/1" alone).
std::string shard_numbering(int count);

// Shards (sorted, once each) that hold at least one of `runs`.
std::vector<int> shards_of(const std::vector<UnfinishedRun>& runs);

// The merge's refusal: how many runs of which shards are not finished, each with its state and
// log, then `next_steps` (how to make them: resubmit, or rerun the shards by hand).
std::string unfinished_report(const std::vector<UnfinishedRun>& runs, int shards, const std::string& next_steps);

// Shards as a Slurm --array list: {0, 1, 2, 5, 7, 8} -> "0-2,5,7-8".
std::string array_list(const std::vector<int>& shards);

}  // namespace pbdbench
