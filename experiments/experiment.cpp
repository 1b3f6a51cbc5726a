#include "experiments/experiment.hpp"

#include <algorithm>
#include <cstdlib>
#include <limits>
#include <map>
#include <set>

#include <fmt/format.h>

#include "config/data_dir.hpp"
#include "config/toml_text.hpp"
#include "harness/runner.hpp"
#include "runfile/series.hpp"

namespace pbdbench::experiments {

namespace fs = std::filesystem;

const char* to_string(Tier tier) { return tier == Tier::Quick ? "quick" : "full"; }

const char* to_string(ExperimentKind kind) {
  return kind == ExperimentKind::Claim ? "claim" : "reproduction";
}

const char* to_string(SetupFrom from) {
  switch (from) {
    case SetupFrom::Paper: return "paper";
    case SetupFrom::Assumed: return "assumed";
    case SetupFrom::Derived: return "derived";
  }
  return "?";
}

const char* to_string(Judges judges) { return judges == Judges::Listing ? "listing" : "method"; }

const std::vector<std::string>& repaired_listing_fixes() {
  static const std::vector<std::string> fixes = {"D1", "D3", "D4", "D5", "D6", "D7", "D8", "D9"};
  return fixes;
}

namespace {

[[noreturn]] void fail(const fs::path& file, int line, const std::string& key,
                       const std::string& message) {
  std::string where = file.string();
  if (line > 0) where += fmt::format(":{}", line);
  throw ExperimentError(where + ": " + (key.empty() ? "" : key + ": ") + message);
}

int line_of(const toml::node& node) { return static_cast<int>(node.source().begin.line); }

// Reads the keys of one table, refusing the ones it does not know.
class TableReader {
 public:
  TableReader(const toml::table& table, fs::path file, std::string prefix,
              std::vector<std::string> known)
      : table_(table), file_(std::move(file)), prefix_(std::move(prefix)), known_(std::move(known)) {
    for (auto&& [key, node] : table_) {
      const std::string k(key.str());
      if (std::find(known_.begin(), known_.end(), k) == known_.end()) {
        std::string close;
        for (const std::string& c : known_)
          if (close.empty() && (c.find(k) != std::string::npos || k.find(c) != std::string::npos))
            close = c;
        fail(file_, static_cast<int>(key.source().begin.line), prefix_ + k,
             "unknown key" + (close.empty() ? "" : " (did you mean '" + prefix_ + close + "'?)") +
                 "; known: " + fmt::format("{}", fmt::join(known_, ", ")));
      }
    }
  }
  int line() const { return line_of(table_); }
  const toml::node* node(const std::string& key) const { return table_.get(key); }
  std::string string(const std::string& key, bool required, const std::string& fallback = "") const {
    const toml::node* n = node(key);
    if (n == nullptr) {
      if (required) fail(file_, line(), prefix_ + key, "missing");
      return fallback;
    }
    if (!n->is_string()) fail(file_, line_of(*n), prefix_ + key, "must be a string");
    return n->as_string()->get();
  }
  long integer(const std::string& key, long fallback, long min, long max = std::numeric_limits<long>::max()) const {
    const toml::node* n = node(key);
    if (n == nullptr) return fallback;
    if (!n->is_integer()) fail(file_, line_of(*n), prefix_ + key, "must be an integer");
    const long v = static_cast<long>(n->as_integer()->get());
    if (v < min) fail(file_, line_of(*n), prefix_ + key, fmt::format("{} is below the minimum {}", v, min));
    if (v > max) fail(file_, line_of(*n), prefix_ + key, fmt::format("{} is above the maximum {}", v, max));
    return v;
  }
  bool boolean(const std::string& key, bool fallback) const {
    const toml::node* n = node(key);
    if (n == nullptr) return fallback;
    if (!n->is_boolean()) fail(file_, line_of(*n), prefix_ + key, "must be true or false");
    return n->as_boolean()->get();
  }
  std::vector<std::string> strings(const std::string& key) const {
    const toml::node* n = node(key);
    std::vector<std::string> out;
    if (n == nullptr) return out;
    const toml::array* a = n->as_array();
    if (a == nullptr) fail(file_, line_of(*n), prefix_ + key, "must be an array of strings");
    for (auto&& v : *a) {
      if (!v.is_string()) fail(file_, line_of(v), prefix_ + key, "must be an array of strings");
      out.push_back(v.as_string()->get());
    }
    return out;
  }
  std::vector<config::Override> overrides(const std::string& key) const {
    const toml::node* n = node(key);
    std::vector<config::Override> out;
    if (n == nullptr) return out;
    const toml::table* t = n->as_table();
    if (t == nullptr)
      fail(file_, line_of(*n), prefix_ + key, "must be a table of overrides (\"path\" = value)");
    try {
      for (const config::FlatEntry& e : config::flatten_table(*t))
        out.push_back({e.path, config::toml_value_text(*e.node, file_)});
    } catch (const config::ConfigError& e) {
      fail(file_, e.source().line, prefix_ + key, e.what());
    }
    return out;
  }
  Expression expression(const std::string& key, bool required) const {
    const std::string text = string(key, required, "0");
    try {
      return Expression(text);
    } catch (const std::invalid_argument& e) {
      const toml::node* n = node(key);
      fail(file_, n != nullptr ? line_of(*n) : line(), prefix_ + key, e.what());
    }
  }

 private:
  const toml::table& table_;
  fs::path file_;
  std::string prefix_;
  std::vector<std::string> known_;
};

const toml::table& as_table(const toml::node& node, const fs::path& file, const std::string& key) {
  if (!node.is_table()) fail(file, line_of(node), key, "must be a table");
  return *node.as_table();
}

std::vector<const toml::table*> array_of_tables(const toml::table& root, const std::string& key,
                                                const fs::path& file) {
  std::vector<const toml::table*> out;
  const toml::node* n = root.get(key);
  if (n == nullptr) return out;
  const toml::array* a = n->as_array();
  if (a == nullptr) fail(file, line_of(*n), key, "must be an array of tables ([[" + key + "]])");
  for (auto&& t : *a) out.push_back(&as_table(t, file, key));
  return out;
}

bool is_series_name(const std::string& name, const std::vector<std::string>& series) {
  if (std::find(series.begin(), series.end(), name) != series.end()) return true;
  for (const GroupSeriesSpec& g : group_series_table())
    if (name.starts_with(g.prefix) && name.size() > g.prefix.size()) return true;
  return false;
}

}  // namespace

const std::vector<std::string>& run_scalar_names() {
  static const std::vector<std::string> names = {
      "exploded",      "exploded_step", "exploded_time", "complete",       "failed",
      "steps_planned", "steps_completed", "wall_time",   "inv_mass_max",   "inv_mass_min",
      "particles",     "dt",            "pinned_drift",  "constraints_distance", "constraints_volume",
      "constraints_bending", "warnings"};
  return names;
}

std::vector<std::string> run_series_names() {
  std::vector<std::string> out;
  for (const SeriesSpec& s : series_table()) {
    if (s.width == 1) {
      out.emplace_back(s.name);
    } else {
      for (const char* c : {".x", ".y", ".z"}) out.push_back(std::string(s.name) + c);
    }
  }
  return out;
}

const RunSpec* Experiment::find_run(const std::string& name) const {
  for (const RunSpec& r : runs)
    if (r.name == name) return &r;
  return nullptr;
}

const TimingSpec* Experiment::find_timing(const std::string& name) const {
  for (const TimingSpec& t : timings)
    if (t.name == name) return &t;
  return nullptr;
}

const MeasureSpec* Experiment::find_measure(const std::string& name) const {
  for (const MeasureSpec& m : measures)
    if (m.name == name) return &m;
  return nullptr;
}

std::vector<std::string> Experiment::runs_read(const MeasureSpec& measure) const {
  std::set<std::string> names;
  std::vector<const MeasureSpec*> todo = {&measure};
  std::set<std::string> seen;
  while (!todo.empty()) {
    const MeasureSpec* m = todo.back();
    todo.pop_back();
    if (!seen.insert(m->name).second) continue;
    if (!m->run.empty()) names.insert(m->run);
    if (const TimingSpec* t = m->timing.empty() ? nullptr : find_timing(m->timing))
      names.insert(t->runs.begin(), t->runs.end());
    if (m->run.empty() && m->timing.empty())
      for (const std::string& s : m->value.scalar_names())
        if (const MeasureSpec* d = find_measure(s)) todo.push_back(d);
  }
  std::vector<std::string> out;
  for (const RunSpec& r : runs)
    if (names.count(r.name)) out.push_back(r.name);
  return out;
}

std::vector<std::string> Experiment::measures_read(const PartSpec& part) const {
  std::vector<std::string> out;
  std::set<std::string> seen;
  std::vector<std::string> todo;
  if (part.rule) todo = part.rule->scalar_names();
  if (part.requires_)
    for (const std::string& s : part.requires_->scalar_names()) todo.push_back(s);
  while (!todo.empty()) {
    const std::string name = todo.front();
    todo.erase(todo.begin());
    if (!seen.insert(name).second) continue;
    const MeasureSpec* m = find_measure(name);
    if (m == nullptr) continue;
    out.push_back(name);
    if (m->run.empty() && m->timing.empty())
      for (const std::string& s : m->value.scalar_names()) todo.push_back(s);
  }
  return out;
}

bool Experiment::reads_timing(const MeasureSpec& measure) const {
  if (!measure.timing.empty()) return true;
  if (!measure.run.empty()) return false;
  for (const std::string& s : measure.value.scalar_names())
    if (const MeasureSpec* d = find_measure(s); d != nullptr && reads_timing(*d)) return true;
  return false;
}

bool Experiment::timing_only(const RunSpec& run) const {
  bool timed = false;
  for (const TimingSpec& t : timings)
    if (std::find(t.runs.begin(), t.runs.end(), run.name) != t.runs.end()) timed = true;
  if (!timed) return false;
  for (const MeasureSpec& m : measures)
    if (m.run == run.name) return false;
  if (figure.kind == "series" && std::find(figure.runs.begin(), figure.runs.end(), run.name) != figure.runs.end())
    return false;
  return true;
}

Experiment Experiment::with_variant(const std::vector<RunVariant>& variant) const {
  Experiment out = *this;
  for (const RunVariant& v : variant)
    for (RunSpec& run : out.runs) {
      if (run.name != v.run) continue;
      if (!v.scenario.empty()) run.scenario = v.scenario;
      // Last in both tiers: after the run's set, and after the quick sets in the quick tier.
      run.set.insert(run.set.end(), v.set.begin(), v.set.end());
      run.quick_set.insert(run.quick_set.end(), v.set.begin(), v.set.end());
    }
  return out;
}

std::vector<config::Override> Experiment::timing_overrides(const RunSpec& run, const TimingSpec& timing,
                                                           Tier tier) const {
  std::vector<config::Override> out = overrides(run, tier, 0);
  out.insert(out.end(), timing.set.begin(), timing.set.end());
  if (tier == Tier::Quick) out.insert(out.end(), timing.quick_set.begin(), timing.quick_set.end());
  return out;
}

int Experiment::trials(const RunSpec& run, Tier tier) const {
  return tier == Tier::Quick ? std::min(run.trials, quick_trials) : run.trials;
}

std::vector<config::Override> Experiment::overrides(const RunSpec& run, Tier tier, int trial) const {
  std::vector<config::Override> out = set;
  out.insert(out.end(), run.set.begin(), run.set.end());
  if (tier == Tier::Quick) {
    out.insert(out.end(), quick_set.begin(), quick_set.end());
    out.insert(out.end(), run.quick_set.begin(), run.quick_set.end());
  }
  for (const std::string& key : run.trial_keys)
    out.push_back({key, std::to_string(run.trial_base + trial)});
  return out;
}

std::string Experiment::scenario_of(const RunSpec& run) const {
  const std::string& s = run.scenario.empty() ? scenario : run.scenario;
  if (s.ends_with(".toml")) {
    const fs::path p(s);
    if (p.is_relative() && fs::exists(file.parent_path() / p)) return (file.parent_path() / p).string();
  }
  return s;
}

Experiment load_experiment(const fs::path& file, bool check_configs) {
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    fail(file, static_cast<int>(e.source().begin.line), "", std::string(e.description()));
  }
  Experiment ex;
  ex.file = file;
  const TableReader top(root, file, "",
                        {"kind", "paper", "id", "section", "claim", "experiment", "scenario", "set",
                         "quick", "setup", "run", "timing", "measure", "part", "figure"});
  const std::string kind = top.string("kind", false, "claim");
  if (kind != "claim" && kind != "reproduction")
    fail(file, top.line(), "kind", "'" + kind + "' is not one of claim, reproduction");
  ex.kind = kind == "claim" ? ExperimentKind::Claim : ExperimentKind::Reproduction;
  ex.paper = top.string("paper", ex.kind == ExperimentKind::Reproduction);
  ex.id = top.string("id", true);
  ex.section = top.string("section", true);
  ex.claim = top.string("claim", ex.kind == ExperimentKind::Reproduction);
  ex.experiment = top.string("experiment", true);
  ex.scenario = top.string("scenario", false);
  ex.set = top.overrides("set");
  if (const toml::node* q = root.get("quick")) {
    const TableReader quick(as_table(*q, file, "quick"), file, "quick.", {"trials", "set"});
    ex.quick_trials = static_cast<int>(quick.integer("trials", ex.quick_trials, 1, kMaxTrials));
    ex.quick_set = quick.overrides("set");
  }
  if (file.stem().string() != ex.id)
    fail(file, 1, "id", "'" + ex.id + "' does not match the file name '" + file.stem().string() + "'");

  // Setup rows (reproductions label every setup value: from the paper, assumed or derived).
  for (const toml::table* t : array_of_tables(root, "setup", file)) {
    const TableReader r(*t, file, "setup.", {"what", "value", "from", "source", "why"});
    SetupSpec row;
    row.line = r.line();
    row.what = r.string("what", true);
    row.value = r.string("value", true);
    const std::string from = r.string("from", true);
    if (from == "paper") row.from = SetupFrom::Paper;
    else if (from == "assumed") row.from = SetupFrom::Assumed;
    else if (from == "derived") row.from = SetupFrom::Derived;
    else fail(file, row.line, "setup.from", "'" + from + "' is not one of paper, assumed, derived");
    row.source = r.string("source", row.from == SetupFrom::Paper);
    row.why = r.string("why", row.from != SetupFrom::Paper);
    ex.setup.push_back(std::move(row));
  }
  if (ex.kind == ExperimentKind::Reproduction && ex.setup.empty())
    fail(file, 0, "setup", "a reproduction labels its setup: at least one [[setup]] row (from = paper | assumed | derived)");

  // Runs.
  for (const toml::table* t : array_of_tables(root, "run", file)) {
    const TableReader r(*t, file, "run.",
                        {"name", "scenario", "set", "quick_set", "trials", "trial_key", "trial_base"});
    RunSpec run;
    run.line = r.line();
    run.name = r.string("name", true);
    run.scenario = r.string("scenario", false);
    run.set = r.overrides("set");
    run.quick_set = r.overrides("quick_set");
    run.trials = static_cast<int>(r.integer("trials", 1, 1, kMaxTrials));
    if (const toml::node* k = r.node("trial_key"); k != nullptr && k->is_array())
      run.trial_keys = r.strings("trial_key");
    else if (k != nullptr)
      run.trial_keys = {r.string("trial_key", true)};
    run.trial_base = r.integer("trial_base", 1, 0);
    if (run.trials > 1 && run.trial_keys.empty())
      fail(file, run.line, "run.trial_key", "run '" + run.name + "' has trials but no trial_key");
    if (ex.find_run(run.name) != nullptr)
      fail(file, run.line, "run.name", "two runs are named '" + run.name + "'");
    if (run.scenario.empty() && ex.scenario.empty())
      fail(file, run.line, "run.scenario", "run '" + run.name + "' has no scenario (and the experiment none)");
    ex.runs.push_back(std::move(run));
  }
  if (ex.runs.empty() && !root.contains("part"))
    fail(file, 0, "run", "an experiment needs at least one [[run]] or one untestable [[part]]");

  // Timing groups.
  for (const toml::table* t : array_of_tables(root, "timing", file)) {
    const TableReader r(*t, file, "timing.", {"name", "runs", "repeats", "set", "quick_set"});
    TimingSpec timing;
    timing.line = r.line();
    timing.name = r.string("name", true);
    timing.runs = r.strings("runs");
    timing.repeats = static_cast<int>(r.integer("repeats", timing.repeats, kMinTimingRepeats, kMaxTimingRepeats));
    timing.set = r.overrides("set");
    timing.quick_set = r.overrides("quick_set");
    if (timing.runs.empty()) fail(file, timing.line, "timing.runs", "a timing group times at least one run");
    for (const std::string& name : timing.runs) {
      if (ex.find_run(name) == nullptr) fail(file, timing.line, "timing.runs", "no run named '" + name + "'");
      if (std::count(timing.runs.begin(), timing.runs.end(), name) > 1)
        fail(file, timing.line, "timing.runs", "run '" + name + "' is listed twice");
    }
    if (ex.find_timing(timing.name) != nullptr || ex.find_run(timing.name) != nullptr)
      fail(file, timing.line, "timing.name", "'" + timing.name + "' is already a timing group or a run");
    ex.timings.push_back(std::move(timing));
  }

  // Measures.
  const std::vector<std::string> series = run_series_names();
  const std::vector<std::string>& scalars = run_scalar_names();
  std::set<std::string> measure_names;
  for (const toml::table* t : array_of_tables(root, "measure", file)) {
    const TableReader r(*t, file, "measure.", {"name", "run", "timing", "value", "over_trials", "units", "doc"});
    MeasureSpec m;
    m.line = r.line();
    m.name = r.string("name", true);
    m.run = r.string("run", false);
    m.timing = r.string("timing", false);
    m.value = r.expression("value", true);
    m.over_trials = r.string("over_trials", false, "mean");
    m.units = r.string("units", false);
    m.doc = r.string("doc", true);
    if (measure_names.count(m.name) || std::find(scalars.begin(), scalars.end(), m.name) != scalars.end())
      fail(file, m.line, "measure.name", "'" + m.name + "' is already a measure or a run scalar");
    const std::vector<std::string> modes = {"mean", "max", "min", "sum", "median"};
    if (std::find(modes.begin(), modes.end(), m.over_trials) == modes.end())
      fail(file, m.line, "measure.over_trials", "'" + m.over_trials + "' is not one of mean, max, min, sum, median");
    if (!m.run.empty() && !m.timing.empty())
      fail(file, m.line, "measure", "a measure reads a run or a timing group, not both");
    if (!m.timing.empty()) {
      const TimingSpec* timing = ex.find_timing(m.timing);
      if (timing == nullptr) fail(file, m.line, "measure.timing", "no timing group named '" + m.timing + "'");
      if (!m.value.series_names().empty())
        fail(file, m.line, "measure.value", "a timing measure reads its group's runs by name, not series");
      for (const std::string& s : m.value.scalar_names())
        if (std::find(timing->runs.begin(), timing->runs.end(), s) == timing->runs.end() && !measure_names.count(s))
          fail(file, m.line, "measure.value",
               "'" + s + "' is neither a run of timing group '" + m.timing + "' (" +
                   fmt::format("{}", fmt::join(timing->runs, ", ")) + ") nor a measure defined above");
    } else if (!m.run.empty()) {
      if (ex.find_run(m.run) == nullptr)
        fail(file, m.line, "measure.run", "no run named '" + m.run + "'");
      for (const std::string& s : m.value.series_names())
        for (const SeriesSpec& spec : series_table())
          if (spec.name == s && !spec.deterministic)
            fail(file, m.line, "measure.value",
                 "'" + s + "' is a wall-clock series: costs are measured by a [[timing]] group "
                 "(repeated and interleaved), not from one run");
      const std::vector<std::string> used = m.value.scalar_names();
      if (std::find(used.begin(), used.end(), std::string("wall_time")) != used.end())
        fail(file, m.line, "measure.value",
             "'wall_time' is a wall-clock time: costs are measured by a [[timing]] group");
      for (const std::string& s : m.value.series_names())
        if (!is_series_name(s, series))
          fail(file, m.line, "measure.value", "no series named '" + s + "' (pbdbench series lists them)");
      for (const std::string& s : m.value.scalar_names())
        if (std::find(scalars.begin(), scalars.end(), s) == scalars.end())
          fail(file, m.line, "measure.value",
               "'" + s + "' is not a run scalar (" + fmt::format("{}", fmt::join(scalars, ", ")) +
                   "); series are read through a reduction such as final(" + s + ")");
    } else {
      if (!m.value.series_names().empty())
        fail(file, m.line, "measure.value", "a measure without a run cannot reduce series");
      for (const std::string& s : m.value.scalar_names())
        if (!measure_names.count(s))
          fail(file, m.line, "measure.value", "'" + s + "' is not a measure defined above");
    }
    measure_names.insert(m.name);
    ex.measures.push_back(std::move(m));
  }

  // Parts.
  const bool claim = ex.kind == ExperimentKind::Claim;
  auto check_reads_measures = [&](const Expression& e, int line, const std::string& key) {
    if (!e.series_names().empty()) fail(file, line, key, "a rule reads measures, not series");
    for (const std::string& s : e.scalar_names())
      if (!measure_names.count(s)) fail(file, line, key, "no measure named '" + s + "'");
  };
  for (const toml::table* t : array_of_tables(root, "part", file)) {
    std::vector<std::string> known = {"says", "rule", "untestable", "requires", "requires_why", "identity",
                                      "counterfactual"};
    const std::vector<std::string> only = claim ? std::vector<std::string>{"quote", "translation", "judges", "regime", "reading", "truth"}
                                                : std::vector<std::string>{"published", "source", "ours", "setup_unknown"};
    known.insert(known.end(), only.begin(), only.end());
    const TableReader r(*t, file, "part.", known);
    PartSpec p;
    p.line = r.line();
    p.says = r.string("says", true);
    p.untestable = r.string("untestable", false);
    const bool has_rule = r.node("rule") != nullptr;
    if (has_rule == !p.untestable.empty())
      fail(file, p.line, "part", "a part has either a rule or an untestable reason, not both or neither");
    if (has_rule) {
      p.rule = r.expression("rule", true);
      check_reads_measures(*p.rule, p.line, "part.rule");
    }
    if (r.node("requires") != nullptr) {
      p.requires_ = r.expression("requires", true);
      check_reads_measures(*p.requires_, p.line, "part.requires");
      p.requires_why = r.string("requires_why", true);
    } else if (r.node("requires_why") != nullptr) {
      fail(file, p.line, "part.requires_why", "a reason without a `requires` condition");
    }
    p.identity = r.string("identity", false);
    if (!p.identity.empty() && !has_rule)
      fail(file, p.line, "part.identity", "an identity still has a rule (it is run and shown, never counted)");
    if (const toml::node* c = r.node("counterfactual")) {
      if (!has_rule) fail(file, line_of(*c), "part.counterfactual", "an untestable part has no rule to flip");
      if (!p.identity.empty())
        fail(file, line_of(*c), "part.counterfactual",
             "a part is an identity by construction or has a counterfactual, not both");
      const TableReader cr(as_table(*c, file, "part.counterfactual"), file, "part.counterfactual.",
                           {"why", "runs", "expect"});
      CounterfactualSpec cf;
      cf.line = cr.line();
      cf.why = cr.string("why", true);
      cf.expect = cr.string("expect", false, "flip");
      if (cf.expect != "flip")
        fail(file, cf.line, "part.counterfactual.expect", "'" + cf.expect + "' is not one of flip");
      const toml::node* runs_node = cr.node("runs");
      if (runs_node == nullptr) fail(file, cf.line, "part.counterfactual.runs", "missing");
      const toml::table& runs_table = as_table(*runs_node, file, "part.counterfactual.runs");
      if (runs_table.empty())
        fail(file, line_of(*runs_node), "part.counterfactual.runs", "a counterfactual varies at least one run");
      for (auto&& [key, node] : runs_table) {
        const std::string name(key.str());
        const int line = static_cast<int>(key.source().begin.line);
        const std::string where = "part.counterfactual.runs." + name;
        if (ex.find_run(name) == nullptr) fail(file, line, where, "no run named '" + name + "'");
        if (!node.is_table())
          fail(file, line, where, "must be a table of overrides (\"path\" = value, \"scenario\" = name)");
        RunVariant v;
        v.run = name;
        try {
          for (const config::FlatEntry& e : config::flatten_table(*node.as_table())) {
            if (e.path == "scenario") {
              if (!e.node->is_string()) fail(file, e.line, where + ".scenario", "must be a string");
              v.scenario = e.node->as_string()->get();
            } else {
              v.set.push_back({e.path, config::toml_value_text(*e.node, file)});
            }
          }
        } catch (const config::ConfigError& e) {
          fail(file, e.source().line, where, e.what());
        }
        if (v.set.empty() && v.scenario.empty()) fail(file, line, where, "varies nothing");
        cf.runs.push_back(std::move(v));
      }
      // The variant must change a run the part reads, or it cannot change the verdict.
      bool reads = false;
      std::set<std::string> read_runs;
      for (const std::string& m : ex.measures_read(p))
        for (const std::string& rn : ex.runs_read(*ex.find_measure(m))) read_runs.insert(rn);
      for (const RunVariant& v : cf.runs) reads = reads || read_runs.count(v.run) > 0;
      if (!reads)
        fail(file, cf.line, "part.counterfactual.runs",
             "varies no run the part reads (" + fmt::format("{}", fmt::join(read_runs, ", ")) + ")");
      p.counterfactual = std::move(cf);
    }
    if (claim) {
      p.quote = r.string("quote", true);
      p.translation = r.string("translation", true);
      p.reading = r.string("reading", false);
      p.truth = r.string("truth", false);
      const std::string judges = r.string("judges", true);
      if (judges == "listing") p.judges = Judges::Listing;
      else if (judges == "method") p.judges = Judges::Method;
      else fail(file, p.line, "part.judges", "'" + judges + "' is not one of listing, method");
      const std::string regime = r.string("regime", false, "article");
      if (regime != "article" && regime != "beyond")
        fail(file, p.line, "part.regime", "'" + regime + "' is not one of article, beyond");
      p.beyond = regime == "beyond";
    } else {
      p.published = r.string("published", true);
      p.source = r.string("source", true);
      p.ours = r.string("ours", false);
      if (!p.ours.empty() && !measure_names.count(p.ours))
        fail(file, p.line, "part.ours", "no measure named '" + p.ours + "'");
      p.setup_unknown = r.string("setup_unknown", false);
      if (!p.identity.empty() && !p.setup_unknown.empty())
        fail(file, p.line, "part", "a part is an identity or has an unknown setup, not both");
      if (!p.setup_unknown.empty() && !has_rule)
        fail(file, p.line, "part", "a part with an unknown setup still has a rule (it is run and shown)");
    }
    ex.parts.push_back(std::move(p));
  }
  if (ex.parts.empty()) fail(file, 0, "part", "an experiment needs at least one [[part]]");

  // Figure.
  if (const toml::node* f = root.get("figure")) {
    const TableReader r(as_table(*f, file, "figure"), file, "figure.",
                        {"kind", "series", "runs", "measures", "log", "ylabel", "title"});
    ex.figure.kind = r.string("kind", true);
    ex.figure.series = r.string("series", false);
    ex.figure.runs = r.strings("runs");
    ex.figure.measures = r.strings("measures");
    ex.figure.log = r.boolean("log", false);
    ex.figure.ylabel = r.string("ylabel", false);
    ex.figure.title = r.string("title", false);
    if (ex.figure.kind == "series") {
      if (!is_series_name(ex.figure.series, series))
        fail(file, r.line(), "figure.series", "no series named '" + ex.figure.series + "'");
      for (const std::string& name : ex.figure.runs)
        if (ex.find_run(name) == nullptr) fail(file, r.line(), "figure.runs", "no run named '" + name + "'");
    } else if (ex.figure.kind == "bars") {
      for (const std::string& name : ex.figure.measures)
        if (!measure_names.count(name)) fail(file, r.line(), "figure.measures", "no measure named '" + name + "'");
    } else if (ex.figure.kind != "none") {
      fail(file, r.line(), "figure.kind", "'" + ex.figure.kind + "' is not one of series, bars, none");
    }
  }

  if (check_configs) {
    for (const RunSpec& run : ex.runs) {
      for (Tier tier : {Tier::Full, Tier::Quick}) {
        try {
          check_solver_names(config::load(ex.scenario_of(run), ex.overrides(run, tier, 0)));
        } catch (const config::ConfigError& e) {
          fail(file, run.line, "run", fmt::format("run '{}' ({} tier): {}", run.name, to_string(tier), e.what()));
        }
      }
    }
    // Each counterfactual's varied runs load and validate in both tiers (a variant may break the
    // listing on purpose: the judges check below is not theirs).
    for (const PartSpec& p : ex.parts) {
      if (!p.counterfactual) continue;
      const Experiment variant = ex.with_variant(p.counterfactual->runs);
      for (const RunVariant& v : p.counterfactual->runs) {
        const RunSpec& run = *variant.find_run(v.run);
        for (Tier tier : {Tier::Full, Tier::Quick}) {
          try {
            check_solver_names(config::load(variant.scenario_of(run), variant.overrides(run, tier, 0)));
          } catch (const config::ConfigError& e) {
            fail(file, p.counterfactual->line, "part.counterfactual.runs." + v.run,
                 fmt::format("the variant of run '{}' ({} tier): {}", v.run, to_string(tier), e.what()));
          }
        }
      }
    }
    // A part that judges the method reads the listing only repaired (one fault, one verdict: the
    // listing's defects are judged by the parts that judge the listing).
    if (claim) {
      for (const PartSpec& p : ex.parts) {
        if (p.judges != Judges::Method) continue;
        std::set<std::string> runs;
        for (const std::string& name : ex.measures_read(p))
          for (const std::string& run : ex.runs_read(*ex.find_measure(name))) runs.insert(run);
        for (const std::string& name : runs) {
          const RunSpec& run = *ex.find_run(name);
          const config::Config cfg = config::load(ex.scenario_of(run), ex.overrides(run, Tier::Full, 0));
          if (cfg.get_string("solver.name") != "pbd-seed") continue;
          const std::vector<std::string>& fixes = cfg.get_strings("solver.seed.fixes");
          std::vector<std::string> missing;
          for (const std::string& d : repaired_listing_fixes())
            if (std::find(fixes.begin(), fixes.end(), d) == fixes.end()) missing.push_back(d);
          if (!missing.empty())
            fail(file, p.line, "part.judges",
                 fmt::format("the part judges the method but reads run '{}', the listing without the fixes {}: "
                             "judge the listing's defects once, in a part with judges = \"listing\", and "
                             "run the method with the listing repaired (solver.seed.fixes = [{}]) or with pbd",
                             name, fmt::join(missing, ", "), fmt::join(repaired_listing_fixes(), ", ")));
        }
      }
    }
  }
  return ex;
}

namespace {
// "S3.1a" -> ({3, 1}, "a")
std::pair<std::vector<int>, std::string> id_key(const std::string& id) {
  std::vector<int> numbers;
  std::string suffix;
  size_t i = (!id.empty() && id[0] == 'S') ? 1 : 0;
  while (i < id.size()) {
    if (std::isdigit(static_cast<unsigned char>(id[i]))) {
      int v = 0;
      while (i < id.size() && std::isdigit(static_cast<unsigned char>(id[i]))) v = v * 10 + (id[i++] - '0');
      numbers.push_back(v);
    } else if (id[i] == '.') {
      ++i;
    } else {
      suffix = id.substr(i);
      break;
    }
  }
  return {numbers, suffix};
}
}  // namespace

bool claim_id_less(const std::string& a, const std::string& b) {
  const bool ca = !a.empty() && a[0] == 'S', cb = !b.empty() && b[0] == 'S';
  if (ca != cb) return ca;
  if (!ca) return a < b;
  return id_key(a) < id_key(b);
}

std::vector<Experiment> load_experiments(const fs::path& dir, bool check_configs) {
  std::vector<Experiment> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw ExperimentError(dir.string() + ": no such folder of experiments");
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ".toml") files.push_back(e.path());
  for (const fs::path& f : files) out.push_back(load_experiment(f, check_configs));
  std::sort(out.begin(), out.end(),
            [](const Experiment& a, const Experiment& b) { return claim_id_less(a.id, b.id); });
  return out;
}

fs::path reproductions_dir() { return config::data_dir() / "reproductions" / "experiments"; }

fs::path experiments_dir() {
  if (const char* env = std::getenv("PBDBENCH_CLAIMS"); env != nullptr && *env != '\0') return env;
  return config::data_dir() / "claims" / "experiments";
}

}  // namespace pbdbench::experiments
