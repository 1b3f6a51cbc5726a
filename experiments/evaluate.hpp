// Running an experiment and deciding its verdicts:
//
//   runs      each [[run]] of the experiment, each trial, through the harness's run loop
//             (harness/runner.hpp), one run file each; a file already holding the same finished
//             configuration from the same build is read instead of run again (unless forced).
//             Runs that only timing groups read are not made.
//   timings   each [[timing]] group, timed like a benchmark (experiments/timing.hpp)
//   measures  each [[measure]]: its value per trial from the run file, combined over the trials;
//             or per repeat of a timing group (the median, with a 95 % interval); or computed
//             from the measures above it (an interval carried through, evaluated at its ends)
//   parts     each [[part]], decided by its rule over the measures:
//               supported / reproduced        the rule holds
//               contradicted / not reproduced the rule does not hold
//               inconclusive                  `requires` fails; a run the part reads exploded or
//                                             failed and the part does not account for it; or the
//                                             rule's outcome changes within the 95 % interval of a
//                                             timing measure it reads
//               not testable                  the part says why, or a measure it reads is NaN
//               identity                      (reproductions) the check holds by construction
//               setup unknown                 (reproductions) the paper's setup is not known
//   verdict   of the experiment, from its decided parts in the article's regime (regime =
//             "article"): supported when all are supported, contradicted when all are
//             contradicted, mixed when both occur, else inconclusive or not testable
#pragma once

#include <filesystem>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "experiments/experiment.hpp"
#include "experiments/timing.hpp"

namespace pbdbench::experiments {

enum class Verdict { Supported, Contradicted, Mixed, Inconclusive, NotTestable, SetupUnknown, Identity };
inline constexpr int kVerdictCount = 7;
const char* to_string(Verdict verdict);  // "supported", "contradicted", "mixed", "inconclusive",
                                         // "not testable", "setup unknown", "identity"
// The word a report uses: a claim is "supported" or "contradicted", a reproduction "reproduced"
// or "not reproduced"; the other words are the same for both.
const char* verdict_word(Verdict verdict, ExperimentKind kind);
// Parses to_string()'s names and the reproduction words; returns false when unknown.
bool parse_verdict(const std::string& text, Verdict& out);

struct RunResult {
  std::string name;
  std::vector<std::filesystem::path> files;  // one per trial (none for a run only timed)
  int complete = 0, exploded = 0, failed = 0, incomplete = 0;  // trials by status
  int reused = 0;                  // trials read from an existing run file
  bool timing_only = false;        // made only by timing groups
  std::string first_failure;       // the reason of the first failed trial, if any
  int warned = 0;                  // trials whose run file carries warnings (metrics/health.hpp)
  std::string first_warning;       // the first warning of the first such trial
  double wall_time = 0.0;          // s, summed over the trials run now
  std::string solver;              // solver.name of trial 0
  std::vector<std::string> seed_fixes;  // solver.seed.fixes of trial 0 (pbd-seed)
};

struct MeasureResult {
  std::string name;
  std::string run;     // the run it reads ("" otherwise)
  std::string timing;  // the timing group it reads ("" otherwise)
  std::string units;
  std::string doc;
  std::string expression;
  std::string over_trials;
  double value = 0.0;
  std::vector<double> trials;  // per trial (a measure of a run), per repeat (a timing measure)
  // A timing measure, or one computed from one: a 95 % interval (lo <= value <= hi).
  bool interval = false;
  double lo = 0.0, hi = 0.0;
  double coverage = 0.0;       // of a timing measure's interval (order statistics)
  // Why the value is NaN when a non-finite step made it so ("`a / b` (column 1) is inf (of 1 /
  // 0)", from Expression::evaluate_checked, the first trial's or repeat's), "" otherwise.
  std::string nonfinite;
};

struct PartResult {
  std::string says;
  std::string quote, translation, reading;  // claims
  std::string truth;                        // claims: what the part is judged against
  Judges judges = Judges::Method;
  bool beyond = false;
  std::string published, source, identity, setup_unknown;  // reproductions
  std::string ours;       // the measure beside the published number ("" when none)
  double ours_value = 0.0;
  std::string ours_units;
  std::string rule;       // "" when untestable
  std::string requires_;  // "" when none
  bool timing = false;    // the rule reads a timing measure
  double outcome = 0.0;   // the rule's value (1 holds, 0 does not, NaN not measured)
  Verdict verdict = Verdict::NotTestable;
  std::string reason;     // why inconclusive, not testable, an identity or setup unknown
  std::vector<std::string> judged_with;  // the runs it reads: "name (solver, fixes)"
};

struct ClaimResult {
  ExperimentKind kind = ExperimentKind::Claim;
  std::string paper;
  std::string id;
  std::string section;
  std::string claim;
  std::string experiment;
  std::filesystem::path file;
  FigureSpec figure;
  std::vector<SetupSpec> setup;
  std::vector<RunResult> runs;
  std::vector<TimingResult> timings;
  std::vector<MeasureResult> measures;
  std::vector<PartResult> parts;
  Verdict verdict = Verdict::NotTestable;
  double wall_time = 0.0;  // s
};

struct EvaluateOptions {
  Tier tier = Tier::Full;
  std::filesystem::path runs_dir;  // run files go to <runs_dir>/<id>/<run>[-<trial>].h5
  bool force = false;              // run again even when a current run file exists
  std::ostream* log = nullptr;     // a line per run
};

ClaimResult evaluate_claim(const Experiment& experiment, const EvaluateOptions& options);

// Decides one part of `experiment` from the runs, timings and measures already in `measured` (what
// evaluate_claim() does for each part once they are in).
PartResult decide_part(const Experiment& experiment, const PartSpec& part, const ClaimResult& measured);

// The run files an experiment needs in a tier, in a stable order (runs, then trials), with the
// configuration each must hold; `current` when the file already holds it from this build. (When
// the runs are split into shards, each is a unit of its own; each [[timing]] group is one unit,
// timed in one task: app/claims_command.cpp.)
struct PlannedRun {
  std::string experiment;  // id
  std::string run;         // name
  int trial = 0;
  std::string scenario;    // what `pbdbench run` loads
  std::vector<config::Override> overrides;
  std::filesystem::path file;
  std::string config_toml;  // the configuration the file must hold
  bool current = false;
};
std::vector<PlannedRun> plan_runs(const Experiment& experiment, const EvaluateOptions& options);

// A run file as the scope of a measure's expression: its series (width-3 ones by component,
// name.x), and the run scalars of experiments/experiment.hpp (exploded, wall_time, ...). Throws
// std::runtime_error naming the path when the file cannot be read.
std::unique_ptr<Scope> run_scope(const std::filesystem::path& run_file);

// The experiment's verdict from its parts (see the top of this file).
Verdict combine_verdicts(const std::vector<PartResult>& parts);

// Counts of parts by verdict (indexed by Verdict), in the article's regime or beyond it.
struct PartCounts {
  int article[kVerdictCount] = {};
  int beyond[kVerdictCount] = {};
  int decided() const;  // supported + contradicted in the article's regime
};
PartCounts count_parts(const std::vector<ClaimResult>& results);

}  // namespace pbdbench::experiments
