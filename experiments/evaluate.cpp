#include "experiments/evaluate.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <ostream>
#include <set>

#include <fmt/format.h>

#include "harness/runner.hpp"
#include "harness/sweep.hpp"
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

std::string trial_stem(const RunSpec& run, int trials, int trial) {
  return trials > 1 || !run.trial_keys.empty() ? fmt::format("{}-{:03d}", run.name, trial) : run.name;
}

}  // namespace

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

std::vector<PlannedRun> plan_runs(const Experiment& ex, const EvaluateOptions& options) {
  std::vector<PlannedRun> out;
  for (const RunSpec& run : ex.runs) {
    if (ex.timing_only(run)) continue;
    const int trials = ex.trials(run, options.tier);
    for (int trial = 0; trial < trials; ++trial) {
      PlannedRun p;
      p.experiment = ex.id;
      p.run = run.name;
      p.trial = trial;
      p.scenario = config::resolve_scenario(ex.scenario_of(run)).string();
      p.overrides = ex.overrides(run, options.tier, trial);
      p.file = options.runs_dir / ex.id / (trial_stem(run, trials, trial) + ".h5");
      const config::Config cfg = config::load(p.scenario, p.overrides);
      check_solver_names(cfg);
      p.config_toml = cfg.to_toml();
      p.current = run_is_current(p.file, p.config_toml);
      out.push_back(std::move(p));
    }
  }
  return out;
}

Verdict combine_verdicts(const std::vector<PartResult>& parts) {
  bool supported = false, contradicted = false, inconclusive = false, unknown = false, identity = false;
  for (const PartResult& p : parts) {
    if (p.beyond) continue;
    supported = supported || p.verdict == Verdict::Supported;
    contradicted = contradicted || p.verdict == Verdict::Contradicted;
    inconclusive = inconclusive || p.verdict == Verdict::Inconclusive;
    unknown = unknown || p.verdict == Verdict::SetupUnknown;
    identity = identity || p.verdict == Verdict::Identity;
  }
  if (supported && contradicted) return Verdict::Mixed;
  if (supported) return Verdict::Supported;
  if (contradicted) return Verdict::Contradicted;
  if (inconclusive) return Verdict::Inconclusive;
  if (unknown) return Verdict::SetupUnknown;
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

PartResult decide_part(const Experiment& ex, const PartSpec& p, const ClaimResult& result) {
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

  // The runs, trial by trial.
  for (const RunSpec& run : ex.runs) {
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
      const fs::path file = dir / (trial_stem(run, trials, trial) + ".h5");
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
                                  ex.id, run.name, trials, trials == 1 ? "" : "s", rr.complete,
                                  rr.exploded, rr.failed,
                                  rr.incomplete > 0 ? fmt::format(", {} incomplete", rr.incomplete) : "",
                                  rr.wall_time, rr.reused > 0 ? fmt::format(" ({} reused)", rr.reused) : "");
      if (!rr.first_failure.empty()) *options.log << "    first failure: " << rr.first_failure << "\n";
      if (rr.warned > 0)
        *options.log << fmt::format("    {} trial{} with warnings; first: {}\n", rr.warned,
                                    rr.warned == 1 ? "" : "s", rr.first_warning);
    }
    result.runs.push_back(std::move(rr));
  }

  // The timing groups.
  for (const TimingSpec& t : ex.timings)
    result.timings.push_back(time_group(ex, t, options.tier, options.runs_dir, options.force, options.log));

  // The measures, in file order (a derived measure reads only those above it).
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
      const auto it = std::find_if(result.timings.begin(), result.timings.end(),
                                   [&](const TimingResult& t) { return t.group == m.timing; });
      for (size_t r = 0; r < it->seconds_per_step.size(); ++r) {
        Expression::Checked c = m.value.evaluate_checked(RepeatScope(*it, r, result.measures));
        if (mr.nonfinite.empty()) mr.nonfinite = std::move(c.nonfinite);
        mr.trials.push_back(c.value);
      }
      const bool any_nan = std::any_of(mr.trials.begin(), mr.trials.end(), [](double v) { return std::isnan(v); });
      const MedianInterval mi = median_interval(mr.trials);
      mr.interval = true;
      mr.value = any_nan ? kNaN : mi.median;
      mr.lo = any_nan ? kNaN : mi.lo;
      mr.hi = any_nan ? kNaN : mi.hi;
      mr.coverage = mi.coverage;
    } else if (m.run.empty()) {
      Expression::Checked c = m.value.evaluate_checked(MeasureScope(result.measures));
      mr.value = c.value;
      mr.nonfinite = std::move(c.nonfinite);
      const std::vector<std::string> inputs = interval_inputs(m.value, result.measures);
      if (!inputs.empty()) {
        mr.interval = true;
        mr.lo = mr.hi = mr.value;
        for (double v : corner_values(m.value, result.measures, inputs)) {
          if (std::isnan(v)) {
            mr.lo = mr.hi = kNaN;
            break;
          }
          mr.lo = std::min(mr.lo, v);
          mr.hi = std::max(mr.hi, v);
        }
      }
    } else {
      const auto it = std::find_if(result.runs.begin(), result.runs.end(),
                                   [&](const RunResult& r) { return r.name == m.run; });
      for (const fs::path& file : it->files) {
        Expression::Checked c = m.value.evaluate_checked(RunScope(file));
        if (mr.nonfinite.empty()) mr.nonfinite = std::move(c.nonfinite);
        mr.trials.push_back(c.value);
      }
      mr.value = combine(m.over_trials, mr.trials);
    }
    result.measures.push_back(std::move(mr));
  }

  for (const PartSpec& p : ex.parts) result.parts.push_back(decide_part(ex, p, result));
  result.verdict = combine_verdicts(result.parts);
  result.wall_time = seconds_since(t0);
  return result;
}

}  // namespace pbdbench::experiments
