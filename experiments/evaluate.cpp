#include "experiments/evaluate.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <ostream>
#include <set>

#include <unistd.h>

#include <fmt/format.h>

#include "harness/runner.hpp"
#include "harness/slurm.hpp"
#include "harness/sweep.hpp"
#include "experiments/sha256.hpp"
#include "runfile/run_file.hpp"

namespace pbdbench::experiments {

namespace fs = std::filesystem;

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The largest distance any particle with inverse mass 0 moves from its place in the first frame:
// 0 when pins hold. NaN without frames. Kinematic particles (attachments with a motion) have
// inverse mass 0 too and move by design.
double pinned_drift(const std::vector<Points>& frames, const std::vector<double>& inv_mass) {
  if (frames.empty() || static_cast<size_t>(frames.front().rows()) != inv_mass.size()) return kNaN;
  double drift = 0.0;
  for (size_t f = 1; f < frames.size(); ++f)
    for (size_t i = 0; i < inv_mass.size(); ++i) {
      if (inv_mass[i] != 0.0) continue;
      const auto row = static_cast<Eigen::Index>(i);
      double d2 = 0.0;
      for (int k = 0; k < 3; ++k) {
        const double d = frames[f](row, k) - frames.front()(row, k);
        d2 += d * d;
      }
      drift = std::max(drift, std::sqrt(d2));
    }
  return drift;
}

RunFileParts run_scope_parts() {
  RunFileParts parts;
  parts.frames = RunFileParts::Frames::All;
  parts.velocities = false;
  parts.model = true;
  return parts;
}

// One trial's run file as the scope of a measure's expression.
class RunScope final : public Scope {
 public:
  explicit RunScope(const fs::path& path) : data_(read_run_file(path, run_scope_parts())) {
    for (const auto& [name, rows] : data_.series3) {
      const char* comps[] = {".x", ".y", ".z"};
      for (int k = 0; k < 3; ++k) {
        std::vector<double>& v = components_[name + comps[k]];
        v.resize(static_cast<size_t>(rows.rows()));
        for (Eigen::Index i = 0; i < rows.rows(); ++i) v[static_cast<size_t>(i)] = rows(i, k);
      }
    }
    const std::string status = data_.status();
    auto number = [&](const char* key) {
      auto it = data_.numbers.find(key);
      return it == data_.numbers.end() ? kNaN : it->second;
    };
    scalars_["exploded"] = status == "exploded" ? 1.0 : 0.0;
    scalars_["complete"] = status == "complete" ? 1.0 : 0.0;
    scalars_["failed"] = status == "failed" ? 1.0 : 0.0;
    scalars_["warnings"] = static_cast<double>(data_.warnings().size());
    const double es = number("exploded_step");
    scalars_["exploded_step"] = es >= 0.0 ? es : kNaN;
    scalars_["exploded_time"] = es >= 0.0 ? number("exploded_time") : kNaN;
    scalars_["steps_planned"] = number("steps_planned");
    scalars_["steps_completed"] = number("steps_completed");
    scalars_["wall_time"] = number("wall_time");
    scalars_["dt"] = number("dt");
    const std::vector<double>& w = data_.model.inv_mass;
    auto count_kind = [&](ConstraintKind k) {
      return static_cast<double>(std::count_if(data_.model.constraints.begin(), data_.model.constraints.end(),
                                               [&](const Constraint& c) { return c.kind == k; }));
    };
    scalars_["constraints_distance"] = count_kind(ConstraintKind::Distance);
    scalars_["constraints_volume"] = count_kind(ConstraintKind::Volume);
    scalars_["constraints_bending"] = count_kind(ConstraintKind::Bending);
    scalars_["particles"] = static_cast<double>(w.size());
    scalars_["inv_mass_max"] = w.empty() ? kNaN : *std::max_element(w.begin(), w.end());
    scalars_["inv_mass_min"] = w.empty() ? kNaN : *std::min_element(w.begin(), w.end());
    scalars_["pinned_drift"] = pinned_drift(data_.frames, w);
    data_.frames = {};  // the positions are not kept: only the series and scalars are looked up
  }

  std::optional<double> scalar(const std::string& name) const override {
    auto it = scalars_.find(name);
    if (it == scalars_.end()) return std::nullopt;
    return it->second;
  }
  const std::vector<double>* series(const std::string& name) const override {
    if (auto it = data_.series.find(name); it != data_.series.end()) return &it->second;
    if (auto it = components_.find(name); it != components_.end()) return &it->second;
    return nullptr;
  }
  const std::vector<double>* times() const override { return series("time"); }
  const RunFileData& data() const { return data_; }

 private:
  RunFileData data_;
  std::map<std::string, std::vector<double>> components_;
  std::map<std::string, double> scalars_;
};

// The measures computed so far, as the scope of derived measures and rules. An interval measure
// named in `corner` takes its low end when its bit in `mask` is 0 and its high end when 1.
class MeasureScope final : public Scope {
 public:
  explicit MeasureScope(const std::vector<MeasureResult>& measures) : measures_(measures) {}
  MeasureScope(const std::vector<MeasureResult>& measures, const std::vector<std::string>& corner, unsigned mask)
      : measures_(measures), corner_(corner), mask_(mask) {}
  std::optional<double> scalar(const std::string& name) const override {
    for (size_t k = 0; k < corner_.size(); ++k)
      if (corner_[k] == name)
        for (const MeasureResult& m : measures_)
          if (m.name == name) return (mask_ >> k) & 1u ? m.hi : m.lo;
    for (const MeasureResult& m : measures_)
      if (m.name == name) return m.value;
    return std::nullopt;
  }
  const std::vector<double>* series(const std::string&) const override { return nullptr; }
  const std::vector<double>* times() const override { return nullptr; }

 private:
  const std::vector<MeasureResult>& measures_;
  std::vector<std::string> corner_;
  unsigned mask_ = 0;
};

// The interval measures an expression reads directly.
std::vector<std::string> interval_inputs(const Expression& e, const std::vector<MeasureResult>& measures) {
  std::vector<std::string> out;
  for (const std::string& name : e.scalar_names())
    for (const MeasureResult& m : measures)
      if (m.name == name && m.interval) out.push_back(name);
  return out;
}

// The values of an expression at every corner of the intervals it reads (at most 2^12 corners).
std::vector<double> corner_values(const Expression& e, const std::vector<MeasureResult>& measures,
                                  const std::vector<std::string>& inputs) {
  if (inputs.size() > 12) throw std::invalid_argument("an expression reads more than 12 timing intervals");
  std::vector<double> out;
  for (unsigned mask = 0; mask < (1u << inputs.size()); ++mask)
    out.push_back(e.evaluate(MeasureScope(measures, inputs, mask)));
  return out;
}

// A timing measure's expression over one repeat: each run of the group is its solver time per
// step (s) in that repeat.
class RepeatScope final : public Scope {
 public:
  RepeatScope(const TimingResult& t, size_t repeat, const std::vector<MeasureResult>& measures)
      : t_(t), repeat_(repeat), measures_(measures) {}
  std::optional<double> scalar(const std::string& name) const override {
    for (size_t k = 0; k < t_.runs.size(); ++k)
      if (t_.runs[k] == name) return t_.seconds_per_step[repeat_][k];
    for (const MeasureResult& m : measures_)  // measures above it, as constants
      if (m.name == name) return m.value;
    return std::nullopt;
  }
  const std::vector<double>* series(const std::string&) const override { return nullptr; }
  const std::vector<double>* times() const override { return nullptr; }

 private:
  const TimingResult& t_;
  size_t repeat_;
  const std::vector<MeasureResult>& measures_;
};

double combine(const std::string& mode, std::vector<double> values) {
  if (values.empty()) return kNaN;
  if (std::any_of(values.begin(), values.end(), [](double v) { return std::isnan(v); })) return kNaN;
  if (mode == "max") return *std::max_element(values.begin(), values.end());
  if (mode == "min") return *std::min_element(values.begin(), values.end());
  double sum = 0.0;
  for (double v : values) sum += v;
  if (mode == "sum") return sum;
  if (mode == "median") {
    std::sort(values.begin(), values.end());
    const size_t n = values.size();
    return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  }
  return sum / static_cast<double>(values.size());  // mean
}

std::string trial_stem(const RunSpec& run, int trials, int trial, const std::string& name) {
  return trials > 1 || !run.trial_keys.empty() ? fmt::format("{}-{:03d}", name, trial) : name;
}

// A run's trials, made or read: their files are <dir>/<stem>[-<trial>].h5.
RunResult make_run(const Experiment& ex, const RunSpec& run, const fs::path& dir, const std::string& stem,
                   const EvaluateOptions& options) {
  RunResult rr;
  rr.name = run.name;
  rr.timing_only = ex.timing_only(run);
  {
    const config::Config cfg = config::load(ex.scenario_of(run), ex.overrides(run, options.tier, 0));
    rr.solver = cfg.get_string("solver.name");
    if (rr.solver == "pbd-seed") rr.seed_fixes = cfg.get_strings("solver.seed.fixes");
  }
  const int trials = rr.timing_only ? 0 : ex.trials(run, options.tier);
  for (int trial = 0; trial < trials; ++trial) {
    const fs::path file = dir / (trial_stem(run, trials, trial, stem) + ".h5");
    const config::Config cfg = config::load(ex.scenario_of(run), ex.overrides(run, options.tier, trial));
    rr.files.push_back(file);
    if (!options.force && run_is_current(file, cfg.to_toml())) {
      ++rr.reused;
    } else {
      const auto tr = std::chrono::steady_clock::now();
      const RunOutcome outcome = run_config(cfg, file);
      rr.wall_time += seconds_since(tr);
      if (outcome.status == RunStatus::Failed && rr.first_failure.empty()) rr.first_failure = outcome.reason;
    }
    const RunFileData header = read_run_file(file, false);
    const std::string status = header.status();
    if (const std::vector<std::string> w = header.warnings(); !w.empty()) {
      if (rr.warned++ == 0) rr.first_warning = w.front();
    }
    if (status == "complete") ++rr.complete;
    else if (status == "exploded") ++rr.exploded;
    else if (status == "failed") ++rr.failed;
    else ++rr.incomplete;
  }
  if (options.log != nullptr && !rr.timing_only) {
    *options.log << fmt::format("  {} {}: {} trial{} ({} complete, {} exploded, {} failed{}), {:.2f} s{}\n",
                                ex.id, stem, trials, trials == 1 ? "" : "s", rr.complete, rr.exploded, rr.failed,
                                rr.incomplete > 0 ? fmt::format(", {} incomplete", rr.incomplete) : "",
                                rr.wall_time, rr.reused > 0 ? fmt::format(" ({} reused)", rr.reused) : "");
    if (!rr.first_failure.empty()) *options.log << "    first failure: " << rr.first_failure << "\n";
    if (rr.warned > 0)
      *options.log << fmt::format("    {} trial{} with warnings; first: {}\n", rr.warned, rr.warned == 1 ? "" : "s",
                                  rr.first_warning);
  }
  return rr;
}

std::string variant_text(const RunVariant& v) {
  std::vector<std::string> items;
  if (!v.scenario.empty()) items.push_back("scenario = " + v.scenario);
  for (const config::Override& o : v.set) items.push_back(o.path + " = " + o.value_text);
  return fmt::format("{}: {}", v.run, fmt::join(items, ", "));
}

}  // namespace

SessionLauncher session_launcher(const fs::path& executable, const Experiment& ex, const TimingSpec& timing, Tier tier,
                                 int part) {
  if (executable.empty()) return {};
  // This very binary, even when a rebuild replaced the file meanwhile: a session timed by another
  // build would not be this build's record (its build is part of the record).
  fs::path self = executable;
  std::error_code ec;
  if (const fs::path proc = fs::path("/proc") / std::to_string(::getpid()) / "exe"; fs::exists(proc, ec)) self = proc;
  const std::string base = fmt::format("{} time-session {} {} --tier {}", slurm::shell_quote(self.string()),
                                       slurm::shell_quote(fs::absolute(ex.file).string()), slurm::shell_quote(timing.name),
                                       to_string(tier));
  return [base, part](const fs::path& runs_dir) {
    std::string cmd = base + " --runs " + slurm::shell_quote(fs::absolute(runs_dir).string());
    if (part >= 0) cmd += fmt::format(" --part {}", part + 1);
    return std::system(cmd.c_str()) == 0;
  };
}

std::unique_ptr<Scope> run_scope(const fs::path& run_file) { return std::make_unique<RunScope>(run_file); }

const char* to_string(Verdict verdict) {
  switch (verdict) {
    case Verdict::Supported: return "supported";
    case Verdict::Contradicted: return "contradicted";
    case Verdict::Mixed: return "mixed";
    case Verdict::Inconclusive: return "inconclusive";
    case Verdict::NotTestable: return "not testable";
    case Verdict::SetupUnknown: return "setup unknown";
    case Verdict::Identity: return "identity";
    case Verdict::NotShown: return "not shown able to fail";
  }
  return "?";
}

const char* to_string(CanFail c) {
  switch (c) {
    case CanFail::NotDecided: return "not decided";
    case CanFail::Shown: return "yes";
    case CanFail::NotFlipped: return "no: its counterfactual did not flip the rule";
    case CanFail::NoVariation: return "no: the measures it compares do not vary beyond round-off";
    case CanFail::ByConstruction: return "no: an identity by construction";
    case CanFail::NoCounterfactual: return "not shown: no counterfactual";
  }
  return "?";
}

const char* verdict_word(Verdict verdict, ExperimentKind kind) {
  if (kind == ExperimentKind::Reproduction) {
    if (verdict == Verdict::Supported) return "reproduced";
    if (verdict == Verdict::Contradicted) return "not reproduced";
  }
  return to_string(verdict);
}

bool parse_verdict(const std::string& text, Verdict& out) {
  for (int k = 0; k < kVerdictCount; ++k) {
    const Verdict v = static_cast<Verdict>(k);
    if (text == to_string(v) || text == verdict_word(v, ExperimentKind::Reproduction)) {
      out = v;
      return true;
    }
  }
  return false;
}

// The runs of one run of `source` (the experiment or one of its variants), under `key` in `dir`.
static void plan_trials(const Experiment& ex, const Experiment& source, const RunSpec& run, const std::string& key,
                 const fs::path& dir, const EvaluateOptions& options, std::vector<PlannedRun>& out) {
  if (source.timing_only(run)) return;
  const int trials = source.trials(run, options.tier);
  for (int trial = 0; trial < trials; ++trial) {
    PlannedRun p;
    p.experiment = ex.id;
    p.run = key;
    p.trial = trial;
    p.scenario = config::resolve_scenario(source.scenario_of(run)).string();
    p.overrides = source.overrides(run, options.tier, trial);
    p.file = dir / (trial_stem(run, trials, trial, key) + ".h5");
    const config::Config cfg = config::load(p.scenario, p.overrides);
    check_solver_names(cfg);
    p.config_toml = cfg.to_toml();
    p.current = run_is_current(p.file, p.config_toml);
    out.push_back(std::move(p));
  }
}

std::vector<PlannedRun> plan_runs(const Experiment& ex, const EvaluateOptions& options) {
  std::vector<PlannedRun> out;
  for (const RunSpec& run : ex.runs) plan_trials(ex, ex, run, run.name, options.runs_dir / ex.id, options, out);
  for (const VariedRun& v : varied_runs(ex)) {
    const Experiment variant = ex.with_variant({*v.variant});
    plan_trials(ex, variant, *variant.find_run(v.run), v.key, options.runs_dir / ex.id / "counterfactual", options, out);
  }
  return out;
}

std::string variant_key(const RunVariant& v) {
  std::string text = v.scenario + "\n";
  for (const config::Override& o : v.set) text += o.path + "=" + o.value_text + "\n";
  return v.run + "-" + sha256_hex(text).substr(0, 12);
}

std::vector<VariedRun> varied_runs(const Experiment& ex) {
  std::vector<VariedRun> out;
  for (const PartSpec& p : ex.parts) {
    if (!p.counterfactual) continue;
    for (const RunVariant& v : p.counterfactual->runs) {
      const std::string key = variant_key(v);
      if (std::none_of(out.begin(), out.end(), [&](const VariedRun& o) { return o.key == key; }))
        out.push_back({v.run, key, &v});
    }
  }
  return out;
}

Verdict combine_verdicts(const std::vector<PartResult>& parts) {
  bool supported = false, contradicted = false, inconclusive = false, unknown = false, identity = false;
  bool not_shown = false;
  for (const PartResult& p : parts) {
    if (p.beyond) continue;
    supported = supported || p.verdict == Verdict::Supported;
    contradicted = contradicted || p.verdict == Verdict::Contradicted;
    inconclusive = inconclusive || p.verdict == Verdict::Inconclusive;
    unknown = unknown || p.verdict == Verdict::SetupUnknown;
    identity = identity || p.verdict == Verdict::Identity;
    not_shown = not_shown || p.verdict == Verdict::NotShown;
  }
  if (supported && contradicted) return Verdict::Mixed;
  if (supported) return Verdict::Supported;
  if (contradicted) return Verdict::Contradicted;
  if (inconclusive) return Verdict::Inconclusive;
  if (unknown) return Verdict::SetupUnknown;
  if (not_shown) return Verdict::NotShown;
  if (identity) return Verdict::Identity;
  return Verdict::NotTestable;
}

int PartCounts::decided() const {
  return article[static_cast<int>(Verdict::Supported)] + article[static_cast<int>(Verdict::Contradicted)];
}

PartCounts count_parts(const std::vector<ClaimResult>& results) {
  PartCounts c;
  for (const ClaimResult& r : results)
    for (const PartResult& p : r.parts) ++(p.beyond ? c.beyond : c.article)[static_cast<int>(p.verdict)];
  return c;
}

namespace {

std::string number_text(double v) {
  if (std::isnan(v)) return "NaN";
  return fmt::format("{:.3g}", v);
}

}  // namespace

namespace {
PartResult decide_on_runs(const Experiment& ex, const PartSpec& p, const ClaimResult& result);

// The measures a rule compares: those it reads (through derived measures) that take the same
// value over different runs (the same expression, combined the same way), in groups of two or
// more. Returns "" when some group varies beyond round-off (or there is none), else the groups
// with their values and spread.
std::string compared_without_variation(const Experiment& ex, const PartSpec& p, const ClaimResult& result) {
  if (!p.rule) return "";
  PartSpec rule_only;
  rule_only.rule = p.rule;
  std::map<std::string, std::vector<const MeasureResult*>> groups;
  // A run's status (exploded, failed, ...) alike in every run is a condition each run meets, not
  // a quantity compared across them.
  const std::set<std::string> status = {"exploded", "complete", "failed", "warnings", "exploded_step", "exploded_time"};
  for (const std::string& name : ex.measures_read(rule_only)) {
    const MeasureSpec& m = *ex.find_measure(name);
    if (m.run.empty()) continue;
    const std::vector<std::string> reads = m.value.scalar_names();
    if (m.value.series_names().empty() &&
        std::all_of(reads.begin(), reads.end(), [&](const std::string& n) { return status.count(n) > 0; }))
      continue;
    for (const MeasureResult& mr : result.measures)
      if (mr.name == name) groups[m.value.text() + "|" + m.over_trials].push_back(&mr);
  }
  std::vector<std::string> flat;
  bool any = false;
  for (const auto& [key, members] : groups) {
    std::set<std::string> runs;
    for (const MeasureResult* m : members) runs.insert(m->run);
    if (members.size() < 2 || runs.size() < 2) continue;
    double lo = members.front()->value, hi = lo, scale = 0.0;
    for (const MeasureResult* m : members) {
      if (!std::isfinite(m->value)) return "";
      lo = std::min(lo, m->value), hi = std::max(hi, m->value), scale = std::max(scale, std::abs(m->value));
    }
    if (hi - lo > kRoundOff * scale) return "";  // this comparison varies
    any = true;
    std::vector<std::string> shown;
    for (const MeasureResult* m : members) shown.push_back(fmt::format("{} = {}", m->name, number_text(m->value)));
    flat.push_back(fmt::format("{} (spread {:.2g})", fmt::join(shown, ", "), hi - lo));
  }
  return any ? fmt::format("{}", fmt::join(flat, "; ")) : "";
}

// The measures a rule reads on a result, as "name = value; ...".
std::string rule_measures(const PartSpec& p, const ClaimResult& result) {
  std::vector<std::string> shown;
  if (!p.rule) return "";
  std::vector<std::string> names = p.rule->scalar_names();
  if (p.requires_)
    for (const std::string& n : p.requires_->scalar_names())
      if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  for (const std::string& n : names)
    for (const MeasureResult& m : result.measures)
      if (m.name == n)
        shown.push_back(m.interval ? fmt::format("{} = {} [{}, {}]", n, number_text(m.value), number_text(m.lo),
                                                 number_text(m.hi))
                                   : fmt::format("{} = {}", n, number_text(m.value)));
  return fmt::format("{}", fmt::join(shown, "; "));
}
}  // namespace

PartResult decide_part(const Experiment& ex, const PartSpec& p, const ClaimResult& result) {
  PartResult pr = decide_on_runs(ex, p, result);
  pr.measured = pr.verdict;
  return pr;
}

void check_can_fail(const Experiment& ex, const PartSpec& p, const ClaimResult& result, const PartResult* variant,
                    PartResult& pr) {
  const bool decided = pr.measured == Verdict::Supported || pr.measured == Verdict::Contradicted;
  if (p.counterfactual) {
    std::vector<std::string> texts;
    for (const RunVariant& v : p.counterfactual->runs) texts.push_back(variant_text(v));
    pr.has_counterfactual = true;
    pr.counterfactual_why = p.counterfactual->why;
    pr.counterfactual_variant = fmt::format("{}", fmt::join(texts, "; "));
  }
  if (variant != nullptr) {
    pr.counterfactual_verdict = variant->measured;
    pr.counterfactual_outcome = variant->outcome;
    pr.counterfactual_reason = variant->reason;
  }
  if (!p.identity.empty() && (pr.verdict == Verdict::Identity || decided)) {
    pr.can_fail = CanFail::ByConstruction;
    return;
  }
  if (!decided) {
    pr.can_fail = CanFail::NotDecided;
    return;
  }
  if (!p.counterfactual) {
    pr.can_fail = CanFail::NoCounterfactual;
    if (pr.verdict == Verdict::Supported || pr.verdict == Verdict::Contradicted) {
      pr.verdict = Verdict::NotShown;
      pr.reason = fmt::format("the rule {} here, but no counterfactual shows that it could have {}",
                              pr.measured == Verdict::Supported ? "holds" : "does not hold",
                              pr.measured == Verdict::Supported ? "failed" : "held");
    }
    return;
  }
  const bool flipped = variant != nullptr &&
                       (variant->measured == Verdict::Supported || variant->measured == Verdict::Contradicted) &&
                       variant->measured != pr.measured;
  if (!flipped) {
    pr.can_fail = CanFail::NotFlipped;
    if (pr.verdict == Verdict::Supported || pr.verdict == Verdict::Contradicted) {
      pr.verdict = Verdict::Identity;
      pr.reason = fmt::format(
          "its counterfactual ({}) leaves the rule {}{}: not shown able to fail", pr.counterfactual_variant,
          variant == nullptr ? "unevaluated"
          : variant->measured == pr.measured ? (pr.measured == Verdict::Supported ? "holding" : "not holding")
                                             : std::string("undecided (") + to_string(variant->measured) + ")",
          variant != nullptr && !variant->reason.empty() ? ", " + variant->reason : "");
    }
    return;
  }
  const std::string flat = compared_without_variation(ex, p, result);
  if (!flat.empty()) {
    pr.can_fail = CanFail::NoVariation;
    pr.compared_spread = flat;
    if (pr.verdict == Verdict::Supported || pr.verdict == Verdict::Contradicted) {
      pr.verdict = Verdict::Identity;
      pr.reason = "the measures its rule compares do not vary beyond round-off across their runs: " + flat;
    }
    return;
  }
  pr.can_fail = CanFail::Shown;
}

namespace {
PartResult decide_on_runs(const Experiment& ex, const PartSpec& p, const ClaimResult& result) {
  PartResult pr;
  pr.says = p.says;
  pr.quote = p.quote;
  pr.translation = p.translation;
  pr.reading = p.reading;
  pr.truth = p.truth;
  pr.judges = p.judges;
  pr.beyond = p.beyond;
  pr.published = p.published;
  pr.source = p.source;
  pr.identity = p.identity;
  pr.setup_unknown = p.setup_unknown;
  pr.ours = p.ours;
  pr.outcome = kNaN;
  if (!p.ours.empty())
    for (const MeasureResult& m : result.measures)
      if (m.name == p.ours) pr.ours_value = m.value, pr.ours_units = m.units;

  // The runs the part reads, and whether its measures account for an explosion of each.
  const std::vector<std::string> measures = ex.measures_read(p);
  std::vector<std::string> runs;
  std::set<std::string> accounted;
  for (const std::string& name : measures) {
    const MeasureSpec& m = *ex.find_measure(name);
    for (const std::string& r : ex.runs_read(m))
      if (std::find(runs.begin(), runs.end(), r) == runs.end()) runs.push_back(r);
    if (!m.run.empty())
      for (const std::string& s : m.value.scalar_names())
        if (s == "exploded" || s == "exploded_step" || s == "exploded_time") accounted.insert(m.run);
    pr.timing = pr.timing || ex.reads_timing(m);
  }
  std::sort(runs.begin(), runs.end(), [&](const std::string& a, const std::string& b) {
    return ex.find_run(a) < ex.find_run(b);
  });
  for (const std::string& name : runs) {
    for (const RunResult& r : result.runs) {
      if (r.name != name) continue;
      std::string with = r.solver;
      if (r.solver == "pbd-seed")
        with += r.seed_fixes.empty() ? ", the listing to the letter"
                                     : fmt::format(", fixes {}", fmt::join(r.seed_fixes, " "));
      pr.judged_with.push_back(fmt::format("{} ({})", name, with));
    }
  }

  if (!p.rule) {
    pr.verdict = Verdict::NotTestable;
    pr.reason = p.untestable;
    return pr;
  }
  pr.rule = p.rule->text();
  if (p.requires_) pr.requires_ = p.requires_->text();
  const MeasureScope scope(result.measures);
  const Expression::Checked checked = p.rule->evaluate_checked(scope);
  pr.outcome = checked.value;

  auto inconclusive = [&](std::string why) {
    pr.verdict = Verdict::Inconclusive;
    pr.reason = std::move(why);
    return pr;
  };
  // Runs that failed (the harness's fault, or a run that did not finish) decide nothing.
  for (const std::string& name : runs) {
    for (const RunResult& r : result.runs) {
      if (r.name != name) continue;
      if (r.failed + r.incomplete > 0)
        return inconclusive(fmt::format("run {} did not finish ({} failed{})", name, r.failed + r.incomplete,
                                        r.first_failure.empty() ? "" : ": " + r.first_failure));
      if (r.exploded > 0 && !accounted.count(name))
        return inconclusive(fmt::format("run {} exploded ({} of {} trials) and the part does not account for it",
                                        name, r.exploded, r.files.size()));
    }
  }
  for (const TimingResult& t : result.timings)
    for (size_t k = 0; k < t.runs.size(); ++k)
      if (std::find(runs.begin(), runs.end(), t.runs[k]) != runs.end() && t.status[k] != "complete")
        return inconclusive(fmt::format("the timed run {} ended {}", t.runs[k], t.status[k]));
  // A timing verdict needs the spread between processes (experiments/timing.hpp).
  for (const std::string& name : measures) {
    const MeasureSpec& m = *ex.find_measure(name);
    if (m.timing.empty()) continue;
    for (const TimingResult& t : result.timings)
      if (t.group == m.timing && t.processes < kTimingSessions)
        return inconclusive(fmt::format("timing group {} was timed in {} separate process{}; a timing verdict "
                                        "needs {}",
                                        t.group, t.processes, t.processes == 1 ? "" : "es", kTimingSessions));
  }
  if (p.requires_) {
    const double ok = p.requires_->evaluate(scope);
    if (std::isnan(ok) || ok == 0.0)
      return inconclusive(fmt::format("{} (requires `{}`{})", p.requires_why, p.requires_->text(),
                                      std::isnan(ok) ? ": not measured" : ": false"));
  }
  if (std::isnan(pr.outcome)) {
    // A non-finite value (1/0, log10(0), an overflow) is no measurement: it would decide the
    // part as ±inf compares, so it makes the part inconclusive, saying where it came from.
    if (!checked.nonfinite.empty()) return inconclusive("the rule's value is not finite: " + checked.nonfinite);
    std::vector<std::string> nan = p.rule->nan_names(scope);
    for (std::string& name : nan)
      for (const MeasureResult& m : result.measures)
        if (m.name == name && !m.nonfinite.empty()) name += " (not finite: " + m.nonfinite + ")";
    return inconclusive(nan.empty() ? std::string("the rule evaluates to NaN")
                                    : fmt::format("not measured (NaN): {}", fmt::join(nan, ", ")));
  }
  const std::vector<std::string> intervals = interval_inputs(*p.rule, result.measures);
  if (!intervals.empty()) {
    const bool holds = pr.outcome != 0.0;
    for (double v : corner_values(*p.rule, result.measures, intervals)) {
      if (std::isnan(v) || (v != 0.0) != holds) {
        std::vector<std::string> shown;
        for (const std::string& name : intervals)
          for (const MeasureResult& m : result.measures)
            if (m.name == name)
              shown.push_back(fmt::format("{} in [{}, {}]", name, number_text(m.lo), number_text(m.hi)));
        return inconclusive(fmt::format("the 95 % interval straddles the threshold: {}", fmt::join(shown, ", ")));
      }
    }
  }
  if (!p.identity.empty()) {
    pr.verdict = Verdict::Identity;
    pr.reason = p.identity;
    return pr;
  }
  if (!p.setup_unknown.empty()) {
    pr.verdict = Verdict::SetupUnknown;
    pr.reason = p.setup_unknown;
    return pr;
  }
  pr.verdict = pr.outcome != 0.0 ? Verdict::Supported : Verdict::Contradicted;
  return pr;
}

}  // namespace

std::vector<MeasureResult> compute_measures(const Experiment& ex, const std::vector<RunResult>& runs,
                                            const std::vector<TimingResult>& timings) {
  std::vector<MeasureResult> measures;
  // In file order: a derived measure reads only those above it.
  for (const MeasureSpec& m : ex.measures) {
    MeasureResult mr;
    mr.name = m.name;
    mr.run = m.run;
    mr.timing = m.timing;
    mr.units = m.units;
    mr.doc = m.doc;
    mr.expression = m.value.text();
    mr.over_trials = m.over_trials;
    if (!m.timing.empty()) {
      const auto it = std::find_if(timings.begin(), timings.end(),
                                   [&](const TimingResult& t) { return t.group == m.timing; });
      for (size_t r = 0; r < it->seconds_per_step.size(); ++r) {
        Expression::Checked c = m.value.evaluate_checked(RepeatScope(*it, r, measures));
        if (mr.nonfinite.empty()) mr.nonfinite = std::move(c.nonfinite);
        mr.trials.push_back(c.value);
      }
      const bool any_nan = std::any_of(mr.trials.begin(), mr.trials.end(), [](double v) { return std::isnan(v); });
      const MedianInterval mi = timing_interval(*it, mr.trials);
      mr.interval = true;
      mr.value = any_nan ? kNaN : mi.median;
      mr.lo = any_nan ? kNaN : mi.lo;
      mr.hi = any_nan ? kNaN : mi.hi;
      mr.coverage = mi.coverage;
    } else if (m.run.empty()) {
      Expression::Checked c = m.value.evaluate_checked(MeasureScope(measures));
      mr.value = c.value;
      mr.nonfinite = std::move(c.nonfinite);
      const std::vector<std::string> inputs = interval_inputs(m.value, measures);
      if (!inputs.empty()) {
        mr.interval = true;
        mr.lo = mr.hi = mr.value;
        for (double v : corner_values(m.value, measures, inputs)) {
          if (std::isnan(v)) {
            mr.lo = mr.hi = kNaN;
            break;
          }
          mr.lo = std::min(mr.lo, v);
          mr.hi = std::max(mr.hi, v);
        }
      }
    } else {
      const auto it = std::find_if(runs.begin(), runs.end(), [&](const RunResult& r) { return r.name == m.run; });
      for (const fs::path& file : it->files) {
        Expression::Checked c = m.value.evaluate_checked(RunScope(file));
        if (mr.nonfinite.empty()) mr.nonfinite = std::move(c.nonfinite);
        mr.trials.push_back(c.value);
      }
      mr.value = combine(m.over_trials, mr.trials);
    }
    measures.push_back(std::move(mr));
  }
  return measures;
}

ClaimResult evaluate_claim(const Experiment& ex, const EvaluateOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  ClaimResult result;
  result.kind = ex.kind;
  result.paper = ex.paper;
  result.id = ex.id;
  result.section = ex.section;
  result.claim = ex.claim;
  result.experiment = ex.experiment;
  result.file = ex.file;
  result.figure = ex.figure;
  result.setup = ex.setup;
  const fs::path dir = options.runs_dir / ex.id;

  for (const RunSpec& run : ex.runs) result.runs.push_back(make_run(ex, run, dir, run.name, options));
  for (const TimingSpec& t : ex.timings)
    result.timings.push_back(time_group(ex, t, options.tier, options.runs_dir, options.force && !options.timings_made,
                                        options.log,
                                        session_launcher(options.executable, ex, t, options.tier)));
  result.measures = compute_measures(ex, result.runs, result.timings);
  for (const PartSpec& p : ex.parts) result.parts.push_back(decide_part(ex, p, result));

  // The counterfactuals: each varied run made once, shared between the parts that vary it alike;
  // a timing group timed again under each distinct set of varied runs it times.
  std::map<std::string, RunResult> varied;
  std::map<std::string, TimingResult> retimed;
  for (size_t k = 0; k < ex.parts.size(); ++k) {
    const PartSpec& p = ex.parts[k];
    if (!p.counterfactual || !p.rule) {
      check_can_fail(ex, p, result, nullptr, result.parts[k]);
      continue;
    }
    const Experiment variant = ex.with_variant(p.counterfactual->runs);
    ClaimResult vr = result;
    std::map<std::string, std::string> keys;  // run -> variant key
    for (const RunVariant& v : p.counterfactual->runs) {
      const std::string key = variant_key(v);
      keys[v.run] = key;
      auto it = varied.find(key);
      if (it == varied.end())
        it = varied.emplace(key, make_run(variant, *variant.find_run(v.run), dir / "counterfactual", key, options)).first;
      for (RunResult& r : vr.runs)
        if (r.name == v.run) r = it->second;
    }
    // The timing groups the part reads (through derived measures): only those are timed again.
    std::set<std::string> timed;
    for (const std::string& name : ex.measures_read(p))
      if (const MeasureSpec* m = ex.find_measure(name); m != nullptr && !m->timing.empty()) timed.insert(m->timing);
    for (size_t t = 0; t < ex.timings.size(); ++t) {
      const TimingSpec& spec = ex.timings[t];
      if (!timed.count(spec.name)) continue;
      std::string group_key;
      for (const std::string& r : spec.runs)
        if (keys.count(r)) group_key += keys[r] + "+";
      if (group_key.empty()) continue;
      group_key = spec.name + "-" + sha256_hex(group_key).substr(0, 12);
      auto it = retimed.find(group_key);
      if (it == retimed.end())
        it = retimed.emplace(group_key, time_group(variant, spec, options.tier, dir / "counterfactual" / group_key,
                                                   options.force, options.log,
                                                   session_launcher(options.executable, ex, spec, options.tier,
                                                                    static_cast<int>(k)))).first;
      vr.timings[t] = it->second;
    }
    vr.measures = compute_measures(variant, vr.runs, vr.timings);
    const PartResult decided = decide_part(variant, p, vr);
    result.parts[k].counterfactual_measured = rule_measures(p, vr);
    check_can_fail(ex, p, result, &decided, result.parts[k]);
  }
  result.verdict = combine_verdicts(result.parts);
  result.wall_time = seconds_since(t0);
  return result;
}

}  // namespace pbdbench::experiments
