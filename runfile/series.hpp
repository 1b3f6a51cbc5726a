// The logged series, declared once. The HDF5 writer creates one dataset per entry under /series
// with the entry's units and doc as attributes; the reader, the Python loader
// (scripts/runfile.py) and results/README.md all follow from this table.
#pragma once

#include <span>
#include <string>
#include <string_view>

#include "metrics/metrics.hpp"
#include "metrics/shadow.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

// Everything one row of the series is taken from.
struct SeriesRow {
  double time = 0.0;           // s, simulated time after the step (0 for the initial row)
  long step = 0;               // steps taken
  double wall_step = 0.0;      // s, wall-clock time of solver.step() (0 for the initial row)
  const Sample* sample = nullptr;
  const StepReport* report = nullptr;  // a default StepReport for the initial row
  const ShadowSample* shadow = nullptr;  // NaN fields where no shadow was solved; may be null
};

struct SeriesSpec {
  std::string_view name;   // dataset name under /series
  std::string_view units;  // "s", "J", "1", "kg m/s", ...
  std::string_view doc;    // one line
  int width = 1;           // 1: shape (rows,); 3: shape (rows, 3)
  bool deterministic = true;  // false for wall-clock timings (excluded from determinism checks)
  void (*read)(const SeriesRow& row, double* out) = nullptr;  // writes `width` values
};

// Every series, in a stable order; "time" first.
std::span<const SeriesSpec> series_table();

// Series repeated for each constraint group of the model: dataset name = prefix + group name,
// e.g. "constraint_error_max_stretch".
struct GroupSeriesSpec {
  std::string_view prefix;  // "constraint_error_max_", "constraint_error_rms_"
  std::string_view units;
  std::string_view doc;
  double (*read)(const GroupError& group);
};
std::span<const GroupSeriesSpec> group_series_table();

// The table as Markdown (name, shape, units, doc), for results/README.md; a test checks that
// the README contains it verbatim.
std::string series_markdown();

}  // namespace pbdbench
