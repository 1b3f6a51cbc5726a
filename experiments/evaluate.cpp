#include "experiments/evaluate.hpp"

#include <H5Cpp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <ostream>

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

// The inverse masses of the run file's model (/model/inv_mass).
std::vector<double> read_inv_mass(const fs::path& path) {
  std::vector<double> out;
  try {
    H5::Exception::dontPrint();
    H5::H5File file(path.string(), H5F_ACC_RDONLY);
    if (!file.nameExists("/model/inv_mass")) return out;
    H5::DataSet ds = file.openDataSet("/model/inv_mass");
    out.resize(static_cast<size_t>(ds.getSpace().getSimpleExtentNpoints()));
    if (!out.empty()) ds.read(out.data(), H5::PredType::NATIVE_DOUBLE);
  } catch (const H5::Exception&) {
    out.clear();
  }
  return out;
}

// The largest distance any particle with inverse mass 0 moves from its place in the first frame
// (/frames/positions): 0 when pins hold. NaN without frames. Kinematic particles (attachments
// with a motion) have inverse mass 0 too and move by design.
double read_pinned_drift(const fs::path& path, const std::vector<double>& inv_mass) {
  try {
    H5::Exception::dontPrint();
    H5::H5File file(path.string(), H5F_ACC_RDONLY);
    if (!file.nameExists("/frames/positions")) return kNaN;
    H5::DataSet ds = file.openDataSet("/frames/positions");
    hsize_t dims[3] = {0, 0, 0};
    if (ds.getSpace().getSimpleExtentNdims() != 3) return kNaN;
    ds.getSpace().getSimpleExtentDims(dims);
    if (dims[0] == 0 || dims[1] != inv_mass.size()) return kNaN;
    std::vector<double> x(static_cast<size_t>(dims[0] * dims[1] * dims[2]));
    ds.read(x.data(), H5::PredType::NATIVE_DOUBLE);
    double drift = 0.0;
    const size_t n = static_cast<size_t>(dims[1]);
    for (size_t f = 1; f < dims[0]; ++f)
      for (size_t i = 0; i < n; ++i) {
        if (inv_mass[i] != 0.0) continue;
        double d2 = 0.0;
        for (size_t k = 0; k < 3; ++k) {
          const double d = x[(f * n + i) * 3 + k] - x[i * 3 + k];
          d2 += d * d;
        }
        drift = std::max(drift, std::sqrt(d2));
      }
    return drift;
  } catch (const H5::Exception&) {
    return kNaN;
  }
}

// One trial's run file as the scope of a measure's expression.
class RunScope final : public Scope {
 public:
  explicit RunScope(const fs::path& path) : data_(read_run_file(path)) {
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
    const double es = number("exploded_step");
    scalars_["exploded_step"] = es >= 0.0 ? es : kNaN;
    scalars_["exploded_time"] = es >= 0.0 ? number("exploded_time") : kNaN;
    scalars_["steps_planned"] = number("steps_planned");
    scalars_["steps_completed"] = number("steps_completed");
    scalars_["wall_time"] = number("wall_time");
    scalars_["dt"] = number("dt");
    const std::vector<double> w = read_inv_mass(path);
    scalars_["particles"] = static_cast<double>(w.size());
    scalars_["inv_mass_max"] = w.empty() ? kNaN : *std::max_element(w.begin(), w.end());
    scalars_["inv_mass_min"] = w.empty() ? kNaN : *std::min_element(w.begin(), w.end());
    scalars_["pinned_drift"] = read_pinned_drift(path, w);
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

// The measures computed so far, as the scope of derived measures and rules.
class MeasureScope final : public Scope {
 public:
  explicit MeasureScope(const std::vector<MeasureResult>& measures) : measures_(measures) {}
  std::optional<double> scalar(const std::string& name) const override {
    for (const MeasureResult& m : measures_)
      if (m.name == name) return m.value;
    return std::nullopt;
  }
  const std::vector<double>* series(const std::string&) const override { return nullptr; }
  const std::vector<double>* times() const override { return nullptr; }

 private:
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
    case Verdict::NotTestable: return "not testable";
  }
  return "?";
}

const char* verdict_word(Verdict verdict, ExperimentKind kind) {
  if (kind == ExperimentKind::Reproduction && verdict != Verdict::NotTestable)
    return verdict == Verdict::Supported ? "reproduced" : "not reproduced";
  return to_string(verdict);
}

std::vector<std::string> timed_runs(const Experiment& ex) {
  std::vector<std::string> pending, seen, runs;
  for (const PartSpec& p : ex.parts)
    if (p.timing && p.rule)
      for (const std::string& n : p.rule->scalar_names()) pending.push_back(n);
  while (!pending.empty()) {
    const std::string name = pending.back();
    pending.pop_back();
    if (std::find(seen.begin(), seen.end(), name) != seen.end()) continue;
    seen.push_back(name);
    for (const MeasureSpec& m : ex.measures) {
      if (m.name != name) continue;
      if (!m.run.empty()) {
        if (std::find(runs.begin(), runs.end(), m.run) == runs.end()) runs.push_back(m.run);
      } else {
        for (const std::string& n : m.value.scalar_names()) pending.push_back(n);
      }
    }
  }
  std::vector<std::string> in_order;  // the experiment's order of runs
  for (const RunSpec& r : ex.runs)
    if (std::find(runs.begin(), runs.end(), r.name) != runs.end()) in_order.push_back(r.name);
  return in_order;
}

std::vector<PlannedRun> plan_runs(const Experiment& ex, const EvaluateOptions& options) {
  std::vector<PlannedRun> out;
  const std::vector<std::string> timed = timed_runs(ex);
  int groups = 0, timed_group = -1;
  for (const RunSpec& run : ex.runs) {
    const int trials = ex.trials(run, options.tier);
    const bool is_timed = std::find(timed.begin(), timed.end(), run.name) != timed.end();
    for (int trial = 0; trial < trials; ++trial) {
      PlannedRun p;
      p.experiment = ex.id;
      p.run = run.name;
      p.trial = trial;
      p.scenario = config::resolve_scenario(ex.scenario_of(run)).string();
      p.overrides = ex.overrides(run, options.tier, trial);
      p.file = options.runs_dir / ex.id / (trial_stem(run, trials, trial) + ".h5");
      const config::Config cfg = config::load(p.scenario, p.overrides);
      p.config_toml = cfg.to_toml();
      p.current = run_is_current(p.file, p.config_toml);
      if (is_timed && timed_group < 0) timed_group = groups++;
      p.group = is_timed ? timed_group : groups++;
      out.push_back(std::move(p));
    }
  }
  return out;
}

bool parse_verdict(const std::string& text, Verdict& out) {
  for (Verdict v : {Verdict::Supported, Verdict::Contradicted, Verdict::NotTestable}) {
    if (text == to_string(v)) {
      out = v;
      return true;
    }
  }
  return false;
}

Verdict combine_verdicts(const std::vector<PartResult>& parts) {
  bool supported = false;
  for (const PartResult& p : parts) {
    if (p.verdict == Verdict::Contradicted) return Verdict::Contradicted;
    supported = supported || p.verdict == Verdict::Supported;
  }
  return supported ? Verdict::Supported : Verdict::NotTestable;
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
  const fs::path dir = options.runs_dir / ex.id;

  // The runs, trial by trial.
  for (const RunSpec& run : ex.runs) {
    RunResult rr;
    rr.name = run.name;
    const int trials = ex.trials(run, options.tier);
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
      const std::string status = read_run_file(file, false).status();
      if (status == "complete") ++rr.complete;
      else if (status == "exploded") ++rr.exploded;
      else if (status == "failed") ++rr.failed;
      else ++rr.incomplete;
    }
    if (options.log != nullptr) {
      *options.log << fmt::format("  {} {}: {} trial{} ({} complete, {} exploded, {} failed{}), {:.2f} s{}\n",
                                  ex.id, run.name, trials, trials == 1 ? "" : "s", rr.complete,
                                  rr.exploded, rr.failed,
                                  rr.incomplete > 0 ? fmt::format(", {} incomplete", rr.incomplete) : "",
                                  rr.wall_time, rr.reused > 0 ? fmt::format(" ({} reused)", rr.reused) : "");
      if (!rr.first_failure.empty()) *options.log << "    first failure: " << rr.first_failure << "\n";
    }
    result.runs.push_back(std::move(rr));
  }

  // The measures, in file order (a derived measure reads only those above it).
  for (const MeasureSpec& m : ex.measures) {
    MeasureResult mr;
    mr.name = m.name;
    mr.run = m.run;
    mr.units = m.units;
    mr.doc = m.doc;
    mr.expression = m.value.text();
    mr.over_trials = m.over_trials;
    if (m.run.empty()) {
      mr.value = m.value.evaluate(MeasureScope(result.measures));
    } else {
      const auto it = std::find_if(result.runs.begin(), result.runs.end(),
                                   [&](const RunResult& r) { return r.name == m.run; });
      for (const fs::path& file : it->files) mr.trials.push_back(m.value.evaluate(RunScope(file)));
      mr.value = combine(m.over_trials, mr.trials);
    }
    result.measures.push_back(std::move(mr));
  }

  // The parts.
  const MeasureScope scope(result.measures);
  for (const PartSpec& p : ex.parts) {
    PartResult pr;
    pr.says = p.says;
    pr.timing = p.timing;
    pr.published = p.published;
    pr.source = p.source;
    pr.ours = p.ours;
    if (!p.ours.empty()) {
      for (const MeasureResult& m : result.measures)
        if (m.name == p.ours) pr.ours_value = m.value, pr.ours_units = m.units;
    }
    if (!p.rule) {
      pr.verdict = Verdict::NotTestable;
      pr.reason = p.untestable;
    } else {
      pr.rule = p.rule->text();
      const double v = p.rule->evaluate(scope);
      if (std::isnan(v)) {
        pr.verdict = Verdict::NotTestable;
        const std::vector<std::string> nan = p.rule->nan_names(scope);
        pr.reason = nan.empty() ? "the rule evaluates to NaN"
                                : fmt::format("not measured (NaN): {}", fmt::join(nan, ", "));
      } else {
        pr.verdict = v != 0.0 ? Verdict::Supported : Verdict::Contradicted;
      }
    }
    result.parts.push_back(std::move(pr));
  }
  result.verdict = combine_verdicts(result.parts);
  result.wall_time = seconds_since(t0);
  return result;
}

}  // namespace pbdbench::experiments
