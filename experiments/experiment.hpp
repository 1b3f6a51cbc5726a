// An experiment: one TOML file, written and registered (experiments/registry.hpp) before its result
// is known, so that a verdict can change only when a measurement changes. Claims of the seed
// article live in claims/experiments/, paper reproductions in reproductions/experiments/. The file
// says which runs to make (scenario, solver variants, seeded trials), what to measure from their
// run files, which costs to time like a benchmark, and the rule that decides each part.
//
//   kind = "claim"                     # or "reproduction" (then `paper` cites the publication,
//                                      #   `claim` says what it reports, and [[setup]] rows label
//                                      #   every setup value as taken from the paper or assumed)
//   id = "S5.4"                        # claims: the id of the claims index (claims/index.toml)
//   section = "5.4"
//   experiment = "..."                 # what is run and why, in a few sentences
//   scenario = "failures/cyclic_penetration"   # default scenario of the runs
//   [set]                              # overrides for every run, both tiers
//   "time.duration" = 0.1
//   [quick]                            # the quick tier (the test suite): fewer trials, shorter runs
//   trials = 10                        # at most this many trials per run
//   set = { "time.duration" = 0.05 }   # overrides for every run, quick tier only
//   [[setup]]                          # reproductions: one row per setup value
//   what = "chain"
//   value = "20 particles of 1 kg"
//   from = "paper"                     # paper | assumed | derived
//   source = "sec. 6.2"                # required with from = "paper"
//   why = "..."                        # required with from = "assumed" or "derived"
//   [[run]]
//   name = "sequential"
//   scenario = "..."                   # optional, else the experiment's
//   set = { "solver.name" = "pbd", "solver.order" = "sequential" }
//   quick_set = { ... }                # optional, quick tier only
//   trials = 100                       # seeded trials: trial i sets trial_key = trial_base + i
//   trial_key = "scene.seed"           # or several keys: ["scene.seed", "solver.shuffle_seed"]
//   [[timing]]                         # costs measured like a benchmark (experiments/timing.hpp)
//   name = "cost"
//   runs = ["sequential", "global_cg"] # timed together: every repeat runs each once, interleaved
//   repeats = 9                        # >= 7, after one warm-up repeat
//   set = { "time.duration" = 0.25 }   # optional overrides of the timed runs (quick_set too)
//   [[measure]]
//   name = "rate_sequential"
//   run = "sequential"                 # a measure of a run: `value` over its series, per trial,
//   value = "final(penetration_max) > 0.0005"   # combined over trials by `over_trials`
//   over_trials = "mean"               # mean | max | min | sum | median
//   units = "1"
//   doc = "fraction of trials still penetrating by more than 1 % of the radius"
//   [[measure]]
//   name = "cost_ratio"                # a measure of a timing group: `value` over the group's
//   timing = "cost"                    #   runs' solver time per step (s) in one repeat (and the
//   value = "global_cg / sequential"   #   measures above it, as constants); its value is the
//                                      #   median over the repeats, with a 95 % interval
//   [[measure]]
//   name = "gain"                      # a measure without `run` or `timing` is computed from
//   value = "rate_sequential - rate_shuffled"   # earlier measures (intervals carried through)
//   [[part]]
//   says = "shuffled groups take the penetration rate from 100 % to 3 %"
//   quote = "..."                      # claims: the article's sentence, verbatim (Chinese)
//   translation = "..."                # claims: in English
//   judges = "method"                  # claims: listing (the printed code) | method (repaired
//                                      #   listing or pbd: the loader checks the fixes)
//   regime = "article"                 # claims: article (default) | beyond (beyond its regime)
//   reading = "..."                    # claims, optional: which reading is tested, and why
//   truth = "..."                      # claims, optional: what the part is judged against (a
//                                      #   closed form, the contact reference, a converged run)
//   rule = "rate_sequential >= 0.9 and rate_grouped <= 0.1"
//   requires = "exploded_baseline == 0"   # optional: else the part is inconclusive
//   requires_why = "the baseline must not explode"
//   published = "6 %"                  # reproductions: the published number, as printed,
//   source = "sec. 6.2, fig. 5"        #   where it is printed,
//   ours = "rate_sequential"           #   and the measure shown beside it
//   identity = "why"                   # holds by construction (shown, not counted)
//   [part.counterfactual]              # the variant that should give the other verdict (a
//   why = "..."                        #   counted part needs one that flips: CounterfactualSpec)
//   runs = { sequential = { "solver.order" = "shuffled" } }
//   setup_unknown = "what"             # reproductions: the paper's setup cannot be recovered
//   # untestable = "why"               # instead of a rule: not testable here, and why
//   [figure]
//   kind = "series"                    # series: one series of several runs against time
//   series = "kinetic_energy"          # bars: the measures listed, one bar each
//   runs = ["seed", "pbd"]
//   log = true
//   ylabel = "kinetic energy (J)"
//
// Expressions are experiments/expression.hpp's. Every error names the file, the line and the key.
#pragma once

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "experiments/expression.hpp"
#include "config/config.hpp"

namespace pbdbench::experiments {

enum class Tier { Quick, Full };
const char* to_string(Tier tier);  // "quick", "full"

// What an experiment tests: a claim of the seed article (verdicts supported / contradicted), or a
// published result it reproduces (reproduced / not reproduced, each part beside the published
// number). The two differ only in wording and in the fields a reproduction's parts carry.
enum class ExperimentKind { Claim, Reproduction };
const char* to_string(ExperimentKind kind);  // "claim", "reproduction"

struct RunSpec {
  std::string name;
  std::string scenario;  // catalog name or path (relative paths: to the experiment file)
  std::vector<config::Override> set;        // both tiers
  std::vector<config::Override> quick_set;  // quick tier only
  int trials = 1;                           // full tier
  std::vector<std::string> trial_keys;      // each set to trial_base + i in trial i (none: no
                                            // trials); trial_key = "a" or ["a", "b"]
  long trial_base = 1;
  int line = 0;
};

struct MeasureSpec {
  std::string name;
  std::string run;     // a measure of a run's trials; "" otherwise
  std::string timing;  // a measure of a timing group's repeats; "" otherwise
  Expression value{"0"};
  std::string over_trials = "mean";  // mean | max | min | sum | median
  std::string units;
  std::string doc;
  int line = 0;
};

// Costs measured like a benchmark: the runs of a group are timed together, interleaved, `repeats`
// times after a warm-up repeat (experiments/timing.hpp).
struct TimingSpec {
  std::string name;
  std::vector<std::string> runs;            // runs of the experiment
  int repeats = 9;                          // >= kMinTimingRepeats
  std::vector<config::Override> set;        // overrides of the timed runs, both tiers
  std::vector<config::Override> quick_set;  // quick tier only
  int line = 0;
};
inline constexpr int kMinTimingRepeats = 7;
// The most repeats of a timing group and trials of a run a file may ask for: ten times the most
// any file of claims/ and reproductions/ asks (9 repeats, 100 trials), so that a slip such as
// 1000000000 is refused (exit 2, the file, key and line) rather than run without end. 1000
// trials also keep a trial's file name to three digits (name-000 to name-999).
inline constexpr int kMaxTimingRepeats = 1000;
inline constexpr int kMaxTrials = 1000;

// A setup value of a reproduction and where it comes from.
enum class SetupFrom { Paper, Assumed, Derived };
const char* to_string(SetupFrom from);  // "paper", "assumed", "derived"

struct SetupSpec {
  std::string what;
  std::string value;
  SetupFrom from = SetupFrom::Paper;
  std::string source;  // where the paper gives it (from = paper)
  std::string why;     // why this value (assumed, derived)
  int line = 0;
};

// What a claim's part judges: the article's code as printed, or the method it describes (run by
// the repaired listing or by pbd).
enum class Judges { Listing, Method };
const char* to_string(Judges judges);  // "listing", "method"

// The seed listing's departures that are defects (docs/seed-departures.md): a part that judges the
// method reads pbd-seed only with every one of them fixed. D2 (position damping), D10 (float) and
// D11 (collisions tested in every iteration) are the article's design, kept.
const std::vector<std::string>& repaired_listing_fixes();

// A part's counterfactual: the variant of its runs under which its rule should give the other
// verdict, so that a counted verdict is one that could have failed (docs/experiments.md).
//   [part.counterfactual]
//   why = "one sentence: why this variant should give the other verdict"
//   runs = { e0 = { "solver.seed.fixes" = ["D8"] }, e01 = { "scenario" = "other" } }
//   expect = "flip"                  # optional; the only expectation so far
// Each named run is the experiment's run with these overrides applied last (after its own set
// and, in the quick tier, its quick sets; the key "scenario" replaces its scenario); the runs
// not named are read unchanged.
struct RunVariant {
  std::string run;
  std::string scenario;                // "" keeps the run's
  std::vector<config::Override> set;
};
struct CounterfactualSpec {
  std::string why;
  std::vector<RunVariant> runs;
  std::string expect = "flip";
  int line = 0;
};

struct PartSpec {
  std::string says;
  // Claims: the article's words and how they are read.
  std::string quote;        // the sentence(s), verbatim, in the article's language
  std::string translation;  // in English
  Judges judges = Judges::Method;
  bool beyond = false;      // regime = "beyond": goes beyond the regime the article means
  std::string reading;      // which reading of the sentence is tested, and why
  std::string truth;        // what the part is judged against, and why that ("" not stated)
  // Reproductions.
  std::string published;  // the published number or relation, as printed
  std::string source;     // where it is printed (paper, section, figure or table)
  std::string ours;       // the measure shown beside the published number
  std::string setup_unknown;   // what of the paper's setup cannot be recovered
  // Both.
  std::string identity;        // why the check holds by construction ("" when it does not)
  std::optional<CounterfactualSpec> counterfactual;  // the variant that should flip the rule
  std::optional<Expression> rule;  // absent when untestable
  std::string untestable;          // the reason, when the part cannot be tested here
  std::optional<Expression> requires_;  // must hold for the part to be decided
  std::string requires_why;
  int line = 0;
};
struct FigureSpec {
  std::string kind = "none";  // none | series | bars
  std::string series;         // series: the series plotted
  std::vector<std::string> runs;      // series: the runs (trial 0 of each)
  std::vector<std::string> measures;  // bars: the measures
  bool log = false;
  std::string ylabel;
  std::string title;
};

struct Experiment {
  std::filesystem::path file;
  ExperimentKind kind = ExperimentKind::Claim;
  std::string paper;  // reproductions: the publication reproduced ("Macklin et al. 2016")
  std::string id;
  std::string section;
  std::string claim;
  std::string experiment;
  std::string scenario;
  std::vector<config::Override> set;
  std::vector<config::Override> quick_set;
  int quick_trials = 10;  // cap on the trials of each run in the quick tier
  std::vector<SetupSpec> setup;
  std::vector<RunSpec> runs;
  std::vector<TimingSpec> timings;
  std::vector<MeasureSpec> measures;
  std::vector<PartSpec> parts;
  FigureSpec figure;

  const RunSpec* find_run(const std::string& name) const;
  const TimingSpec* find_timing(const std::string& name) const;
  const MeasureSpec* find_measure(const std::string& name) const;
  // The trials of a run in a tier, and the overrides of its trial i, in the order they apply:
  // the experiment's set, the run's set, (quick) the experiment's and the run's quick sets, the
  // trial key.
  int trials(const RunSpec& run, Tier tier) const;
  std::vector<config::Override> overrides(const RunSpec& run, Tier tier, int trial) const;
  // The overrides of a run timed in `timing`: the run's (trial 0), then the group's.
  std::vector<config::Override> timing_overrides(const RunSpec& run, const TimingSpec& timing,
                                                 Tier tier) const;
  // The scenario a run loads, resolved against the experiment file's folder.
  std::string scenario_of(const RunSpec& run) const;
  // The runs a measure reads, through the measures it is computed from (a timing measure reads
  // its group's runs), each once, in the experiment's order.
  std::vector<std::string> runs_read(const MeasureSpec& measure) const;
  // The measures a part's rule and `requires` read, through derived measures, each once.
  std::vector<std::string> measures_read(const PartSpec& part) const;
  // Whether a measure reads a timing group (directly or through derived measures).
  bool reads_timing(const MeasureSpec& measure) const;
  // Runs that only timing groups read: their accuracy runs are not made.
  bool timing_only(const RunSpec& run) const;
  // The experiment with the runs of a counterfactual varied: each named run's overrides applied
  // after its own (both tiers), its scenario replaced when the variant names one.
  Experiment with_variant(const std::vector<RunVariant>& variant) const;
};

class ExperimentError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads and checks an experiment file: unknown keys, wrong types, duplicate names, expressions
// that do not parse or name unknown series, runs or measures (a measure may only use measures
// defined above it). With `check_configs`, every run's configuration in both tiers is loaded
// and validated too (nothing runs). Throws ExperimentError "file:line: key: message".
Experiment load_experiment(const std::filesystem::path& file, bool check_configs = true);

// Every *.toml in `dir`, in the order of the claims index (S1, S2.1a, S2.1b, ..., S5.4); ids that
// are not claim ids sort by their text after them.
std::vector<Experiment> load_experiments(const std::filesystem::path& dir,
                                         bool check_configs = true);

// Orders claim ids as the index does: by section numbers, then by letter ("S3.1" < "S3.1a").
bool claim_id_less(const std::string& a, const std::string& b);

// Where the experiments live: $PBDBENCH_CLAIMS when set, else <data dir>/claims/experiments;
// the reproductions: <data dir>/reproductions/experiments (config/data_dir.hpp). Each folder's
// parent holds the registry (registry.toml) and, for claims, the claims index (index.toml).
std::filesystem::path experiments_dir();
std::filesystem::path reproductions_dir();

// Names a measure expression may use: the width-1 series, the components of the width-3 series
// (name.x, name.y, name.z), and the run's scalars (run_scalar_names()):
//   exploded, complete, failed  1 or 0 by the run's status
//   warnings  the number of warnings the run file carries (metrics/health.hpp)
//   exploded_step, exploded_time  when the run exploded (NaN when it did not)
//   steps_planned, steps_completed, wall_time (s), dt (s)
//   particles, inv_mass_max, inv_mass_min  of the run's model (1/kg)
//   pinned_drift  m, the largest distance a particle with inverse mass 0 moved from its place in
//                 the first frame, over the written frames (kinematic particles move by design)
//   constraints_distance, constraints_volume, constraints_bending  the model's constraints of
//                 each kind
std::vector<std::string> run_series_names();
const std::vector<std::string>& run_scalar_names();

}  // namespace pbdbench::experiments
