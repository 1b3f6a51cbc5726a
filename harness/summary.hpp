// A table of what a set of runs measured, read back from their run files: the summary the
// command line prints after a run, a sweep or the default study.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace pbdbench {

struct SummaryEntry {
  std::string label;             // how the run is named in the table
  std::filesystem::path file;    // its run file
};

// One row per entry: status, steps, constraint error (final and peak max, final RMS), volume
// drift, energy change, peak penetration, solver milliseconds per step; a status "complete !2"
// has 2 warnings (metrics/health.hpp), listed under the table after a line naming what they saw
// ("run: seen: a link stretched beyond twice its rest length (overstretched)"; docs/failures.md),
// after why each run's steps stopped
// (its stop_reason series counted by reason: "488 converged, 12 iteration_limit (not trusted) of
// 500 steps"). Unreadable files get a row saying so.
std::string summary_table(const std::vector<SummaryEntry>& entries);

// The same as comma-separated values with a header row and full precision; the last column,
// "stop reasons", the counts of the table's note.
std::string summary_csv(const std::vector<SummaryEntry>& entries);

}  // namespace pbdbench
