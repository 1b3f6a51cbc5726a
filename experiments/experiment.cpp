#include "experiments/experiment.hpp"

#include <algorithm>
#include <cstdlib>
#include <map>
#include <set>

#include <fmt/format.h>

#include "config/data_dir.hpp"
#include "config/toml_text.hpp"
#include "runfile/series.hpp"

namespace pbdbench::experiments {

namespace fs = std::filesystem;

const char* to_string(Tier tier) { return tier == Tier::Quick ? "quick" : "full"; }

const char* to_string(ExperimentKind kind) {
  return kind == ExperimentKind::Claim ? "claim" : "reproduction";
}

namespace {

[[noreturn]] void fail(const fs::path& file, int line, const std::string& key,
                       const std::string& message) {
  std::string where = file.string();
  if (line > 0) where += ":" + std::to_string(line);
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
  long integer(const std::string& key, long fallback, long min) const {
    const toml::node* n = node(key);
    if (n == nullptr) return fallback;
    if (!n->is_integer()) fail(file_, line_of(*n), prefix_ + key, "must be an integer");
    const long v = static_cast<long>(n->as_integer()->get());
    if (v < min) fail(file_, line_of(*n), prefix_ + key, fmt::format("{} is below the minimum {}", v, min));
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
      "particles",     "dt",            "pinned_drift"};
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
                         "quick", "run", "measure", "part", "figure"});
  const std::string kind = top.string("kind", false, "claim");
  if (kind != "claim" && kind != "reproduction")
    fail(file, top.line(), "kind", "'" + kind + "' is not one of claim, reproduction");
  ex.kind = kind == "claim" ? ExperimentKind::Claim : ExperimentKind::Reproduction;
  ex.paper = top.string("paper", ex.kind == ExperimentKind::Reproduction);
  ex.id = top.string("id", true);
  ex.section = top.string("section", true);
  ex.claim = top.string("claim", true);
  ex.experiment = top.string("experiment", true);
  ex.scenario = top.string("scenario", false);
  ex.set = top.overrides("set");
  if (const toml::node* q = root.get("quick")) {
    const TableReader quick(as_table(*q, file, "quick"), file, "quick.", {"trials", "set"});
    ex.quick_trials = static_cast<int>(quick.integer("trials", ex.quick_trials, 1));
    ex.quick_set = quick.overrides("set");
  }
  if (file.stem().string() != ex.id)
    fail(file, 1, "id", "'" + ex.id + "' does not match the file name '" + file.stem().string() + "'");

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
    run.trials = static_cast<int>(r.integer("trials", 1, 1));
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

  // Measures.
  const std::vector<std::string> series = run_series_names();
  const std::vector<std::string>& scalars = run_scalar_names();
  std::set<std::string> measure_names;
  for (const toml::table* t : array_of_tables(root, "measure", file)) {
    const TableReader r(*t, file, "measure.", {"name", "run", "value", "over_trials", "units", "doc"});
    MeasureSpec m;
    m.line = r.line();
    m.name = r.string("name", true);
    m.run = r.string("run", false);
    m.value = r.expression("value", true);
    m.over_trials = r.string("over_trials", false, "mean");
    m.units = r.string("units", false);
    m.doc = r.string("doc", true);
    if (measure_names.count(m.name) || std::find(scalars.begin(), scalars.end(), m.name) != scalars.end())
      fail(file, m.line, "measure.name", "'" + m.name + "' is already a measure or a run scalar");
    const std::vector<std::string> modes = {"mean", "max", "min", "sum", "median"};
    if (std::find(modes.begin(), modes.end(), m.over_trials) == modes.end())
      fail(file, m.line, "measure.over_trials", "'" + m.over_trials + "' is not one of mean, max, min, sum, median");
    if (!m.run.empty()) {
      if (ex.find_run(m.run) == nullptr)
        fail(file, m.line, "measure.run", "no run named '" + m.run + "'");
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
  for (const toml::table* t : array_of_tables(root, "part", file)) {
    const TableReader r(*t, file, "part.",
                        {"says", "rule", "untestable", "timing", "published", "source", "ours"});
    PartSpec p;
    p.line = r.line();
    p.says = r.string("says", true);
    p.published = r.string("published", false);
    p.source = r.string("source", false);
    p.ours = r.string("ours", false);
    if (!p.ours.empty() && !measure_names.count(p.ours))
      fail(file, p.line, "part.ours", "no measure named '" + p.ours + "'");
    p.untestable = r.string("untestable", false);
    p.timing = r.boolean("timing", false);
    const bool has_rule = r.node("rule") != nullptr;
    if (has_rule == !p.untestable.empty())
      fail(file, p.line, "part", "a part has either a rule or an untestable reason, not both or neither");
    if (has_rule) {
      p.rule = r.expression("rule", true);
      if (!p.rule->series_names().empty())
        fail(file, p.line, "part.rule", "a rule reads measures, not series");
      for (const std::string& s : p.rule->scalar_names())
        if (!measure_names.count(s)) fail(file, p.line, "part.rule", "no measure named '" + s + "'");
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
          (void)config::load(ex.scenario_of(run), ex.overrides(run, tier, 0));
        } catch (const config::ConfigError& e) {
          fail(file, run.line, "run", fmt::format("run '{}' ({} tier): {}", run.name, to_string(tier), e.what()));
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
