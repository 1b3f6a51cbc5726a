// `pbdbench regress`: run the registry's cases, compare every metric with the stored baselines,
// print the table and write it (Markdown, HDF5, and the results as JSON for --against).
//
//   pbdbench regress                     quick tier against regress/baselines_quick.toml
//   pbdbench regress --tier full         every case against regress/baselines_full.toml
//   pbdbench regress --update            rewrite the tier's baselines (with the build that made them)
//   pbdbench regress --against DIR       compare with another run's DIR/regress.json (two builds,
//                                        two branches) instead of the stored baselines
//   pbdbench regress --repeat            run every case twice: the bitwise tier (determinism)
//
// Output in results/regress/<tier>/ (or --out): regress.md, regress.h5, regress.json, the run
// files in runs/. The exit code is non-zero when a metric is worse beyond its tolerance or a
// repeated run differs in a bit.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "experiments/experiment.hpp"
#include "harness/runner.hpp"

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
  bool force = false;               // run again even when current run files exist
  RunControl control;               // tests: a broken solver variant
};

struct RegressOutcome {
  std::filesystem::path out;
  int worse = 0;
  int better = 0;
  int bit_differences = 0;  // --repeat
  bool updated = false;
};

// Throws experiments::ExperimentError for a bad registry or an unknown case, std::runtime_error for
// a missing or unreadable baseline.
RegressOutcome run_regress(const RegressCommand& command, std::ostream& out, std::ostream& log);

}  // namespace pbdbench::regress
