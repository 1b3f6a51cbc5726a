// Running a claim's experiment and deciding its verdict:
//
//   runs      each [[run]] of the experiment, each trial, through the harness's run loop
//             (harness/runner.hpp), one run file each; a file already holding the same finished
//             configuration from the same build is read instead of run again (unless forced)
//   measures  each [[measure]]: its value per trial from the run file, combined over the trials;
//             or computed from the measures above it
//   parts     each [[part]]'s rule over the measures: supported (true), contradicted (false), or
//             not testable here (the part says why, or a measure it reads is NaN)
//   verdict   of the claim: contradicted when a part is, else supported when a part is, else not
//             testable here
#pragma once

#include <filesystem>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "experiments/experiment.hpp"

namespace pbdbench::experiments {

enum class Verdict { Supported, Contradicted, NotTestable };
const char* to_string(Verdict verdict);  // "supported", "contradicted", "not testable"
// The word a report uses: a claim is "supported" or "contradicted", a reproduction "reproduced"
// or "not reproduced"; "not testable" either way.
const char* verdict_word(Verdict verdict, ExperimentKind kind);
// Parses the names above; returns false when unknown.
bool parse_verdict(const std::string& text, Verdict& out);

struct RunResult {
  std::string name;
  std::vector<std::filesystem::path> files;  // one per trial
  int complete = 0, exploded = 0, failed = 0, incomplete = 0;  // trials by status
  int reused = 0;                  // trials read from an existing run file
  std::string first_failure;       // the reason of the first failed trial, if any
  double wall_time = 0.0;          // s, summed over the trials run now
};

struct MeasureResult {
  std::string name;
  std::string run;  // "" for a measure computed from other measures
  std::string units;
  std::string doc;
  std::string expression;
  std::string over_trials;
  double value = 0.0;
  std::vector<double> trials;  // per trial (a measure of a run)
};

struct PartResult {
  std::string says;
  std::string published;  // reproductions: as printed
  std::string source;
  std::string ours;       // the measure beside it ("" when none)
  double ours_value = 0.0;
  std::string ours_units;
  std::string rule;  // "" when untestable
  bool timing = false;
  Verdict verdict = Verdict::NotTestable;
  std::string reason;  // why not testable
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
  std::vector<RunResult> runs;
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

// The run files an experiment needs in a tier, in a stable order (runs, then trials), with the
// configuration each must hold; `current` when the file already holds it from this build.
// `group`: runs of one group must be made in one process of one task when the runs are split
// into shards (a job array): every run read by a measure that a `timing = true` part uses (its
// wall-clock times are compared) is in one group; every other trial is a group of its own.
// Groups are numbered from 0 within the experiment, in the order of the plan.
struct PlannedRun {
  std::string experiment;  // id
  std::string run;         // name
  int trial = 0;
  std::string scenario;    // what `pbdbench run` loads
  std::vector<config::Override> overrides;
  std::filesystem::path file;
  std::string config_toml;  // the configuration the file must hold
  bool current = false;
  int group = 0;
};

// The names of the runs whose measures the experiment's `timing = true` parts read (through
// the measures computed from other measures).
std::vector<std::string> timed_runs(const Experiment& experiment);
std::vector<PlannedRun> plan_runs(const Experiment& experiment, const EvaluateOptions& options);

// A run file as the scope of a measure's expression: its series (width-3 ones by component,
// name.x), and the run scalars of experiments/experiment.hpp (exploded, wall_time, ...). Throws
// std::runtime_error naming the path when the file cannot be read.
std::unique_ptr<Scope> run_scope(const std::filesystem::path& run_file);

// The claim's verdict from its parts' (see the top of this file).
Verdict combine_verdicts(const std::vector<PartResult>& parts);

}  // namespace pbdbench::experiments
