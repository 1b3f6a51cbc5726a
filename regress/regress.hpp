// Regression of accuracy metrics: a registry of cases (regress/cases.toml: scenario x solver x
// settings, each a run), the summary metrics every case is measured by (declared once in the
// same file: an expression over the run file, its units, which way is worse, and its tolerance),
// and baselines stored in the repository (regress/baselines_<tier>.toml, written by --update,
// with the build that made them). A metric's verdict:
//
//   allowed = abs + rel * |baseline|
//   same     |now - baseline| <= allowed (both NaN counts as same)
//   worse    beyond it in the metric's bad direction, or NaN where the baseline was not
//   better   beyond it in the good direction
//   ratio    timing metrics: now / baseline is reported, never a verdict (machines are noisy)
//
// The bitwise tier: a 64-bit hash of each case's final positions and deterministic series
// (state_hash, runfile/run_file.hpp),
// compared with the baseline's when the build (compiler, flags, build type) is the same, and
// between two runs of the same build with --repeat (determinism).
#pragma once

#include <filesystem>
#include <functional>
#include <iosfwd>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "experiments/experiment.hpp"
#include "experiments/expression.hpp"
#include "config/config.hpp"
#include "harness/runner.hpp"

namespace pbdbench::regress {

enum class Worse { Higher, Lower, Either };  // which change is a regression

struct MetricSpec {
  std::string name;
  experiments::Expression value{"0"};  // over a run file (experiments/expression.hpp)
  std::string units;
  std::string doc;
  Worse worse = Worse::Higher;
  double rel = 0.0;   // relative tolerance
  double abs = 0.0;   // absolute tolerance, in the metric's units
  bool timing = false;  // a wall-clock metric: reported as a ratio, never a verdict
};

struct CaseSpec {
  std::string name;
  std::string scenario;
  std::vector<config::Override> set;
  bool quick = false;                 // in the quick tier (the test suite) too
  std::vector<std::string> metrics;   // the metrics this case is judged by (names)
  std::map<std::string, std::pair<double, double>> tolerance;  // per-case (rel, abs) overrides
};

struct Registry {
  std::filesystem::path file;
  std::vector<MetricSpec> metrics;
  std::vector<CaseSpec> cases;
  const MetricSpec* metric(const std::string& name) const;
};

// Reads and checks regress/cases.toml (unknown keys, unknown metrics or series, configurations
// the schema refuses): errors name the file, the line and the key (experiments::ExperimentError).
Registry load_registry(const std::filesystem::path& file);
std::filesystem::path registry_file();  // <data dir>/regress/cases.toml (config/data_dir.hpp)

// What one case measured.
struct CaseResult {
  std::string name;
  std::filesystem::path file;         // its run file
  std::string status;                 // complete, exploded, failed, ...
  std::map<std::string, double> values;  // metric -> value
  std::string hash;                   // the bitwise tier's hash (16 hex digits)
  std::vector<std::string> warnings;  // the run file's warnings (metrics/health.hpp)
};

// Runs a case (or reads its run file when current, unless force) and measures it. `make_solver`,
// when set, replaces the registry's solver (tests of broken variants).
CaseResult measure_case(const Registry& registry, const CaseSpec& c, const std::filesystem::path& dir,
                        bool force, const RunControl& control = {});

// A stored set of results: the baselines file, or another run's regress.json (--against).
struct Baseline {
  std::map<std::string, std::map<std::string, double>> values;  // case -> metric -> value
  std::map<std::string, std::string> hashes;                    // case -> hash
  std::string commit, compiler, build_type, cxx_flags;          // the build that made it
};
Baseline read_baseline(const std::filesystem::path& file);  // TOML (baselines) or JSON (regress.json)
std::string baseline_toml(const std::vector<CaseResult>& results, experiments::Tier tier);

enum class Verdict { Same, Better, Worse, Ratio, New };
const char* to_string(Verdict verdict);  // "same", "better", "worse", "ratio", "new"

struct Row {
  std::string case_name, metric, units;
  double baseline = 0.0, now = 0.0;
  double change = 0.0;  // now - baseline (timing: now / baseline)
  double allowed = 0.0;
  Verdict verdict = Verdict::Same;
};
// Compares one value with its baseline under the metric's tolerance (and the case's override).
Row compare_value(const MetricSpec& m, const CaseSpec& c, double baseline, double now);

struct Report {
  std::vector<Row> rows;
  std::vector<std::string> hash_lines;  // the bitwise tier, one line per case (regress.md)
  int worse = 0, better = 0, same = 0;
  // The bitwise tier for the terminal: the cases whose hash differs from the stored one (compared
  // only when compiler, flags and build type match), and whether the stored hashes come from
  // this very source (the same commit, no local changes on either side). Only then is a
  // difference a finding; from another commit, changed code may change the bits.
  std::vector<std::string> hash_differences;
  int hash_compared = 0;
  bool hash_same_source = false;
  std::string hash_stored_by;  // the commit of the stored hashes
};
Report compare(const Registry& registry, const std::vector<const CaseSpec*>& cases,
               const std::vector<CaseResult>& results, const Baseline& baseline);

std::string report_table(const Report& report);     // plain text, for the terminal
// The bitwise tier for the terminal: every case's line with `all` (--bitwise); else nothing when
// no hash differs, each differing case when the stored hashes come from this source, and one
// line saying how many differ and that they were stored by another commit otherwise.
std::string bitwise_text(const Report& report, bool all);
std::string report_markdown(const Report& report, const std::string& header);
std::string results_json(const std::vector<CaseResult>& results);
// regress.h5: the rows as columns (runfile/regress_file.hpp).
void write_report_h5(const std::filesystem::path& path, const Report& report);

}  // namespace pbdbench::regress
