// The regression report's HDF5 file (regress.h5, written by `pbdbench regress`): one row per
// (case, metric), stored as columns at the root, declared once as a table (regress_file.cpp):
//
//   /case, /metric, /units, /verdict   (rows,) variable-length strings
//   /baseline, /now, /change, /allowed (rows,) float64
//
// No attributes: the columns are the file. regress/regress.hpp says what each value means.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace pbdbench {

struct RegressFileRow {
  std::string case_name;  // column "case"
  std::string metric;
  std::string units;
  std::string verdict;    // "same", "better", "worse", "ratio", "new"
  double baseline = 0.0;  // in the metric's units
  double now = 0.0;
  double change = 0.0;    // now - baseline (timing metrics: now / baseline)
  double allowed = 0.0;   // the tolerance: abs + rel * |baseline|
};

// True when `path` is a regular file holding a regress file (an HDF5 file of the columns below).
bool is_regress_file(const std::filesystem::path& path);

// Throws std::runtime_error naming the path on failure.
void write_regress_file(const std::filesystem::path& path, const std::vector<RegressFileRow>& rows);
// Throws std::runtime_error naming the path when the file cannot be read or a column is missing
// or of another length.
std::vector<RegressFileRow> read_regress_file(const std::filesystem::path& path);

}  // namespace pbdbench
