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
//               identity                      the check holds by construction (the part says
//                                             why), its counterfactual did not flip its rule, or
//                                             the measures its rule compares do not vary beyond
//                                             round-off across their runs (shown, never counted)
//               not shown able to fail        decided, but the part has no counterfactual yet
//                                             (shown, never counted)
//               setup unknown                 (reproductions) the paper's setup is not known
//   counterfactuals  each part's [part.counterfactual]: the runs it names made again with its
//             overrides (each distinct variant once per experiment, shared between parts), the
//             timing groups that time a varied run timed again, the measures recomputed, the rule
//             and `requires` decided on the variant. A decided verdict counts only when the
//             variant gives the other decided verdict (docs/experiments.md).
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

enum class Verdict { Supported, Contradicted, Mixed, Inconclusive, NotTestable, SetupUnknown, Identity, NotShown };
inline constexpr int kVerdictCount = 8;
const char* to_string(Verdict verdict);  // "supported", "contradicted", "mixed", "inconclusive",
                                         // "not testable", "setup unknown", "identity",
                                         // "not shown able to fail"
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

// Whether a decided part was shown able to fail.
enum class CanFail {
  NotDecided,        // the part's own verdict is not supported or contradicted
  Shown,             // its counterfactual gave the other verdict
  NotFlipped,        // its counterfactual gave the same verdict, or none
  NoVariation,       // the measures its rule compares agree to round-off across their runs
  ByConstruction,    // the part says it is an identity
  NoCounterfactual,  // it has none yet
};
const char* to_string(CanFail can_fail);  // "not decided", "yes", "no: ...", ...

// Two values of a measure differ "beyond round-off" when they differ by more than this, relative
// to the larger magnitude (a double's rounding accumulated over a run is far below it; a float
// solver's is near 1e-7).
inline constexpr double kRoundOff = 1e-6;

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
  // The rule's verdict on the runs before the counterfactual's check (supported, contradicted,
  // inconclusive, ...); `verdict` is what is counted.
  Verdict measured = Verdict::NotTestable;
  // The counterfactual ("" / false when the part has none).
  bool has_counterfactual = false;
  std::string counterfactual_why;
  std::string counterfactual_variant;       // "run: key = value, ...; run: scenario = ..."
  Verdict counterfactual_verdict = Verdict::NotTestable;  // the rule on the variant
  double counterfactual_outcome = 0.0;      // 1 holds, 0 does not, NaN not measured
  std::string counterfactual_reason;        // why the variant's verdict is not decided
  std::string counterfactual_measured;      // the variant's measures the rule reads
  CanFail can_fail = CanFail::NotDecided;
  std::string compared_spread;              // NoVariation: the measures and their spread
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
  // pbdbench, to time each session of a timing group in a process of its own
  // (`pbdbench time-session`); "" times them in this process, and a part that reads them is then
  // inconclusive (experiments/timing.hpp: kTimingSessions processes).
  std::filesystem::path executable;
  bool timings_made = false;  // the experiments' timing groups were just timed: read, even when forced
};

// Launches `pbdbench time-session FILE GROUP --tier T --runs DIR [--part K]` (K from 1: the
// group of part K's counterfactual variant); empty when `executable` is.
SessionLauncher session_launcher(const std::filesystem::path& executable, const Experiment& experiment,
                                 const TimingSpec& timing, Tier tier, int part = -1);

ClaimResult evaluate_claim(const Experiment& experiment, const EvaluateOptions& options);

// Decides one part of `experiment` from the runs, timings and measures already in `measured` (what
// evaluate_claim() does for each part once they are in).
PartResult decide_part(const Experiment& experiment, const PartSpec& part, const ClaimResult& measured);

// Applies the counterfactual check to a part decided on the runs (`decided` from decide_part()):
// sets its counterfactual fields from `variant` (the part decided on its counterfactual's
// variant; nullptr when it has none) and turns a decided verdict into an identity or "not shown
// able to fail" when it was not shown able to fail.
void check_can_fail(const Experiment& experiment, const PartSpec& part, const ClaimResult& measured,
                    const PartResult* variant, PartResult& decided);

// The measures an experiment computes from its runs' files and its timing groups (in file order).
std::vector<MeasureResult> compute_measures(const Experiment& experiment, const std::vector<RunResult>& runs,
                                            const std::vector<TimingResult>& timings);

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
// The runs of the counterfactuals' variants come after, in <runs_dir>/<id>/counterfactual/.
std::vector<PlannedRun> plan_runs(const Experiment& experiment, const EvaluateOptions& options);

// The distinct variants of an experiment's counterfactuals, each varied run once: its key (the
// run's name and a hash of its scenario and overrides), used for the file names.
struct VariedRun {
  std::string run;
  std::string key;  // "<run>-<12 hex digits>"
  const RunVariant* variant = nullptr;
};
std::vector<VariedRun> varied_runs(const Experiment& experiment);
std::string variant_key(const RunVariant& variant);

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
