#include "regress/regress.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "experiments/evaluate.hpp"
#include "config/data_dir.hpp"
#include "config/toml_text.hpp"
#include "harness/runner.hpp"
#include "harness/sweep.hpp"
#include "runfile/build_info.hpp"
#include "runfile/regress_file.hpp"
#include "runfile/run_file.hpp"
#include "runfile/series.hpp"

namespace pbdbench::regress {

namespace fs = std::filesystem;
using experiments::ExperimentError;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

[[noreturn]] void fail(const fs::path& file, int line, const std::string& key, const std::string& message) {
  throw ExperimentError(fmt::format("{}{}: {}{}", file.string(), line > 0 ? ":" + std::to_string(line) : "",
                                    key.empty() ? "" : key + ": ", message));
}
int line_of(const toml::node& n) { return static_cast<int>(n.source().begin.line); }

void check_keys(const toml::table& t, const fs::path& file, const std::string& prefix,
                const std::vector<std::string>& known) {
  for (auto&& [key, node] : t) {
    const std::string k(key.str());
    if (std::find(known.begin(), known.end(), k) == known.end())
      fail(file, static_cast<int>(key.source().begin.line), prefix + k,
           fmt::format("unknown key; known: {}", fmt::join(known, ", ")));
  }
}
std::string str(const toml::table& t, const std::string& key, const fs::path& file, const std::string& prefix,
                bool required, const std::string& fallback = "") {
  const toml::node* n = t.get(key);
  if (n == nullptr) {
    if (required) fail(file, line_of(t), prefix + key, "missing");
    return fallback;
  }
  if (!n->is_string()) fail(file, line_of(*n), prefix + key, "must be a string");
  return n->as_string()->get();
}
double num(const toml::table& t, const std::string& key, const fs::path& file, const std::string& prefix,
           double fallback) {
  const toml::node* n = t.get(key);
  if (n == nullptr) return fallback;
  const std::optional<double> v = n->value<double>();
  if (!v || !(*v >= 0.0) || !std::isfinite(*v)) fail(file, line_of(*n), prefix + key, "must be a finite number >= 0");
  return *v;
}

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string number(double v) {
  if (std::isnan(v)) return "NaN";
  return fmt::format("{:.6g}", v);
}

}  // namespace

const MetricSpec* Registry::metric(const std::string& name) const {
  for (const MetricSpec& m : metrics)
    if (m.name == name) return &m;
  return nullptr;
}

fs::path registry_file() { return config::data_dir() / "regress" / "cases.toml"; }

Registry load_registry(const fs::path& file) {
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    fail(file, static_cast<int>(e.source().begin.line), "", std::string(e.description()));
  }
  Registry reg;
  reg.file = file;
  check_keys(root, file, "", {"metric", "case"});
  const std::vector<std::string> series = experiments::run_series_names();
  const std::vector<std::string>& scalars = experiments::run_scalar_names();
  auto is_series = [&](const std::string& s) {
    if (std::find(series.begin(), series.end(), s) != series.end()) return true;
    for (const GroupSeriesSpec& g : group_series_table())
      if (s.starts_with(g.prefix)) return true;
    return false;
  };
  if (const toml::array* a = root["metric"].as_array()) {
    for (auto&& node : *a) {
      const toml::table* t = node.as_table();
      if (t == nullptr) fail(file, line_of(node), "metric", "must be an array of tables ([[metric]])");
      check_keys(*t, file, "metric.", {"name", "value", "units", "doc", "worse", "rel", "abs", "timing"});
      MetricSpec m;
      m.name = str(*t, "name", file, "metric.", true);
      try {
        m.value = experiments::Expression(str(*t, "value", file, "metric.", true));
      } catch (const std::invalid_argument& e) {
        fail(file, line_of(*t), "metric.value", e.what());
      }
      for (const std::string& s : m.value.series_names())
        if (!is_series(s)) fail(file, line_of(*t), "metric.value", "no series named '" + s + "'");
      for (const std::string& s : m.value.scalar_names())
        if (std::find(scalars.begin(), scalars.end(), s) == scalars.end())
          fail(file, line_of(*t), "metric.value", "'" + s + "' is not a run scalar");
      m.units = str(*t, "units", file, "metric.", false);
      m.doc = str(*t, "doc", file, "metric.", true);
      const std::string worse = str(*t, "worse", file, "metric.", false, "higher");
      if (worse == "higher") m.worse = Worse::Higher;
      else if (worse == "lower") m.worse = Worse::Lower;
      else if (worse == "either") m.worse = Worse::Either;
      else fail(file, line_of(*t), "metric.worse", "'" + worse + "' is not one of higher, lower, either");
      m.rel = num(*t, "rel", file, "metric.", 0.0);
      m.abs = num(*t, "abs", file, "metric.", 0.0);
      m.timing = t->get("timing") != nullptr && t->get("timing")->value_or(false);
      if (reg.metric(m.name) != nullptr) fail(file, line_of(*t), "metric.name", "two metrics are named '" + m.name + "'");
      reg.metrics.push_back(std::move(m));
    }
  }
  if (const toml::array* a = root["case"].as_array()) {
    for (auto&& node : *a) {
      const toml::table* t = node.as_table();
      if (t == nullptr) fail(file, line_of(node), "case", "must be an array of tables ([[case]])");
      check_keys(*t, file, "case.", {"name", "scenario", "set", "quick", "metrics", "tolerance"});
      CaseSpec c;
      c.name = str(*t, "name", file, "case.", true);
      c.scenario = str(*t, "scenario", file, "case.", true);
      if (const toml::node* s = t->get("set")) {
        if (!s->is_table()) fail(file, line_of(*s), "case.set", "must be a table of overrides");
        try {
          for (const config::FlatEntry& e : config::flatten_table(*s->as_table()))
            c.set.push_back({e.path, config::toml_value_text(*e.node, file)});
        } catch (const config::ConfigError& e) {
          fail(file, e.source().line, "case.set", e.what());
        }
      }
      c.quick = t->get("quick") != nullptr && t->get("quick")->value_or(false);
      if (const toml::array* ms = (*t)["metrics"].as_array()) {
        for (auto&& mn : *ms) {
          const std::string name = mn.value_or(std::string());
          if (reg.metric(name) == nullptr) fail(file, line_of(mn), "case.metrics", "no metric named '" + name + "'");
          c.metrics.push_back(name);
        }
      } else {
        for (const MetricSpec& m : reg.metrics) c.metrics.push_back(m.name);
      }
      if (const toml::table* tol = (*t)["tolerance"].as_table()) {
        for (auto&& [key, v] : *tol) {
          const std::string name(key.str());
          if (reg.metric(name) == nullptr) fail(file, line_of(v), "case.tolerance", "no metric named '" + name + "'");
          const toml::array* pair = v.as_array();
          if (pair == nullptr || pair->size() != 2) fail(file, line_of(v), "case.tolerance." + name, "must be [rel, abs]");
          c.tolerance[name] = {pair->get(0)->value_or(0.0), pair->get(1)->value_or(0.0)};
        }
      }
      for (const CaseSpec& other : reg.cases)
        if (other.name == c.name) fail(file, line_of(*t), "case.name", "two cases are named '" + c.name + "'");
      try {
        check_solver_names(config::load(c.scenario, c.set));
      } catch (const config::ConfigError& e) {
        fail(file, line_of(*t), "case", fmt::format("case '{}': {}", c.name, e.what()));
      }
      reg.cases.push_back(std::move(c));
    }
  }
  if (reg.cases.empty()) fail(file, 0, "case", "the registry has no [[case]]");
  return reg;
}

CaseResult measure_case(const Registry& reg, const CaseSpec& c, const fs::path& dir, bool force,
                        const RunControl& control) {
  CaseResult r;
  r.name = c.name;
  r.file = dir / (c.name + ".h5");
  const config::Config cfg = config::load(c.scenario, c.set);
  if (force || control.make_solver || !run_is_current(r.file, cfg.to_toml())) run_config(cfg, r.file, control);
  const RunFileData header = read_run_file(r.file, false);
  r.status = header.status();
  r.warnings = header.warnings();
  const std::unique_ptr<experiments::Scope> scope = experiments::run_scope(r.file);
  for (const std::string& name : c.metrics) r.values[name] = reg.metric(name)->value.evaluate(*scope);
  r.hash = state_hash(r.file);
  return r;
}

const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::Same: return "same";
    case Verdict::Better: return "better";
    case Verdict::Worse: return "worse";
    case Verdict::Ratio: return "ratio";
    case Verdict::New: return "new";
  }
  return "?";
}

Row compare_value(const MetricSpec& m, const CaseSpec& c, double base, double now) {
  Row row;
  row.case_name = c.name;
  row.metric = m.name;
  row.units = m.units;
  row.baseline = base;
  row.now = now;
  if (m.timing) {
    row.change = now / base;
    row.verdict = Verdict::Ratio;
    return row;
  }
  double rel = m.rel, abs = m.abs;
  if (auto it = c.tolerance.find(m.name); it != c.tolerance.end()) rel = it->second.first, abs = it->second.second;
  row.change = now - base;
  row.allowed = abs + rel * std::abs(base);
  if (std::isnan(base) && std::isnan(now)) return row;  // same
  if (std::isnan(base) != std::isnan(now)) {
    row.verdict = Verdict::Worse;  // a value appeared or vanished: the run changed its nature
    return row;
  }
  if (std::abs(row.change) <= row.allowed) return row;
  const bool up = row.change > 0.0;
  const bool bad = m.worse == Worse::Either || (m.worse == Worse::Higher) == up;
  row.verdict = bad ? Verdict::Worse : Verdict::Better;
  return row;
}

Report compare(const Registry& reg, const std::vector<const CaseSpec*>& cases,
               const std::vector<CaseResult>& results, const Baseline& base) {
  Report rep;
  const BuildInfo& b = build_info();
  const bool same_build = base.compiler == b.compiler && base.cxx_flags == b.cxx_flags && base.build_type == b.build_type;
  const std::string commit = b.git_commit;
  rep.hash_same_source = !commit.empty() && base.commit == commit && !commit.ends_with("+dirty");
  rep.hash_stored_by = base.commit.empty() ? "an unknown build" : base.commit;
  for (size_t k = 0; k < cases.size(); ++k) {
    const CaseSpec& c = *cases[k];
    const CaseResult& r = results[k];
    const auto bv = base.values.find(c.name);
    for (const std::string& name : c.metrics) {
      const MetricSpec& m = *reg.metric(name);
      const double now = r.values.at(name);
      if (bv == base.values.end() || !bv->second.count(name)) {
        Row row;
        row.case_name = c.name;
        row.metric = name;
        row.units = m.units;
        row.baseline = kNaN;
        row.now = now;
        row.change = kNaN;
        row.verdict = Verdict::New;
        rep.rows.push_back(row);
        continue;
      }
      rep.rows.push_back(compare_value(m, c, bv->second.at(name), now));
      const Verdict v = rep.rows.back().verdict;
      if (v == Verdict::Worse) ++rep.worse;
      else if (v == Verdict::Better) ++rep.better;
      else if (v == Verdict::Same) ++rep.same;
    }
    const auto h = base.hashes.find(c.name);
    if (h == base.hashes.end()) {
      rep.hash_lines.push_back(fmt::format("{}: {} (no stored hash)", c.name, r.hash));
    } else if (!same_build) {
      rep.hash_lines.push_back(fmt::format("{}: {} (stored {} by another build: not compared)", c.name, r.hash, h->second));
    } else {
      rep.hash_lines.push_back(fmt::format("{}: {} {}", c.name, r.hash,
                                           h->second == r.hash ? "bit for bit as stored" : "differs from the stored " + h->second));
      ++rep.hash_compared;
      if (h->second != r.hash) rep.hash_differences.push_back(rep.hash_lines.back());
    }
  }
  return rep;
}

Baseline read_baseline(const fs::path& file) {
  Baseline out;
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw std::runtime_error(file.string() + ": no such baseline file");
  toml::table root;
  try {
    if (file.extension() == ".json") {
      // regress.json is written by results_json in a TOML-compatible subset: {"case": {...}}
      std::ifstream in(file);
      std::stringstream text;
      text << in.rdbuf();
      std::string t = text.str();
      // JSON objects of numbers and strings read as TOML inline tables once ':' becomes '='.
      std::string toml_text;
      bool in_string = false;
      for (char ch : t) {
        if (ch == '"') in_string = !in_string;
        if (!in_string && (ch == '\n' || ch == '\r')) continue;  // TOML inline tables are one line
        toml_text += (!in_string && ch == ':') ? '=' : ch;
      }
      toml::table wrapped = toml::parse("results = " + toml_text);
      const toml::table* inner = wrapped["results"].as_table();
      if (inner == nullptr) throw std::runtime_error(file.string() + ": not a JSON object of results");
      root = *inner;
    } else {
      root = toml::parse_file(file.string());
    }
  } catch (const toml::parse_error& e) {
    throw std::runtime_error(file.string() + ":" + std::to_string(e.source().begin.line) + ": " + std::string(e.description()));
  }
  for (auto&& [key, node] : root) {
    const std::string k(key.str());
    const toml::table* t = node.as_table();
    if (t == nullptr) continue;
    if (k == "build") {
      out.commit = (*t)["commit"].value_or(std::string());
      out.compiler = (*t)["compiler"].value_or(std::string());
      out.build_type = (*t)["build_type"].value_or(std::string());
      out.cxx_flags = (*t)["cxx_flags"].value_or(std::string());
      continue;
    }
    for (auto&& [mk, mv] : *t) {
      const std::string m(mk.str());
      if (m == "hash") {
        out.hashes[k] = mv.value_or(std::string());
      } else if (m == "status") {
        continue;
      } else if (const auto d = mv.value<double>()) {
        out.values[k][m] = *d;
      } else if (const auto s = mv.value<std::string>(); s && *s == "nan") {
        out.values[k][m] = kNaN;
      }
    }
  }
  return out;
}

namespace {
std::string toml_number(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::string s = fmt::format("{}", v);
  if (s.find_first_of(".en") == std::string::npos) s += ".0";
  return s;
}
}  // namespace

std::string baseline_toml(const std::vector<CaseResult>& results, experiments::Tier tier) {
  const BuildInfo& b = build_info();
  std::ostringstream out;
  out << "# Baselines of the regression, " << experiments::to_string(tier) << " tier: every case's metrics as\n"
      << "# measured by the build below, written by `pbdbench regress --tier " << experiments::to_string(tier)
      << " --update`.\n# The tolerances and directions are in regress/cases.toml; the policy on changing a\n"
      << "# baseline is in docs/regress.md. Review a change here as a diff: each line is one number.\n\n"
      << "[build]\n"
      << "commit = " << json_string(b.git_commit) << "\ncompiler = " << json_string(b.compiler)
      << "\nbuild_type = " << json_string(b.build_type) << "\ncxx_flags = " << json_string(b.cxx_flags) << "\n";
  for (const CaseResult& r : results) {
    out << "\n[" << r.name << "]\nstatus = " << json_string(r.status) << "\nhash = " << json_string(r.hash) << "\n";
    for (const auto& [name, v] : r.values) out << name << " = " << toml_number(v) << "\n";
  }
  return out.str();
}

std::string results_json(const std::vector<CaseResult>& results) {
  const BuildInfo& b = build_info();
  std::ostringstream js;
  js << "{\"build\": {\"commit\": " << json_string(b.git_commit) << ", \"compiler\": " << json_string(b.compiler)
     << ", \"build_type\": " << json_string(b.build_type) << ", \"cxx_flags\": " << json_string(b.cxx_flags) << "}";
  for (const CaseResult& r : results) {
    js << ",\n " << json_string(r.name) << ": {\"status\": " << json_string(r.status) << ", \"hash\": "
       << json_string(r.hash);
    for (const auto& [name, v] : r.values)
      js << ", " << json_string(name) << ": " << (std::isfinite(v) ? toml_number(v) : "\"nan\"");
    js << "}";
  }
  js << "\n}\n";
  return js.str();
}

std::string bitwise_text(const Report& rep, bool all) {
  std::string out;
  if (all) {
    for (const std::string& l : rep.hash_lines) out += "bitwise: " + l + "\n";
    return out;
  }
  // A repeated run (--repeat) that changed its bits is a finding whatever the baselines.
  for (const std::string& l : rep.hash_lines)
    if (l.find("different bits") != std::string::npos) out += "bitwise: " + l + "\n";
  if (rep.hash_differences.empty()) return out;
  if (rep.hash_same_source) {
    for (const std::string& l : rep.hash_differences) out += "bitwise: " + l + "\n";
  } else {
    // A commit is shown by its first 12 hex digits, its "+dirty" in words.
    std::string by = rep.hash_stored_by;
    if (by.find_first_not_of("0123456789abcdef+dirty") == std::string::npos)
      by = by.substr(0, std::min<size_t>(by.find('+'), 12));
    out += fmt::format(
        "bitwise: {} of {} cases differ from the hashes stored by {}{}, not this source (changed code may change "
        "the bits; the metrics above are the comparison; --bitwise lists them)\n",
        rep.hash_differences.size(), rep.hash_compared, by,
        rep.hash_stored_by.ends_with("+dirty") ? " with local changes" : "");
  }
  return out;
}

std::string report_table(const Report& rep) {
  // The verdicts first (what changed beyond its tolerance, and the new metrics), then the timings
  // under their own heading: a ratio of wall-clock times is never a verdict.
  std::ostringstream out;
  const auto row = [&](const std::string& c, const std::string& m, const std::string& base, const std::string& now,
                       const std::string& change, const std::string& allowed, const std::string& verdict) {
    out << fmt::format("{:<26} {:<26} {:>13} {:>13} {:>11} {:>10}  {}\n", c, m, base, now, change, allowed, verdict);
  };
  const auto shown = [](const Row& r) { return r.verdict != Verdict::Same && r.verdict != Verdict::Ratio; };
  const bool any_change = std::any_of(rep.rows.begin(), rep.rows.end(), shown);
  if (any_change) {
    row("case", "metric", "baseline", "now", "change", "allowed", "verdict");
    for (const Row& r : rep.rows)
      if (shown(r))
        row(r.case_name, r.metric, number(r.baseline), number(r.now), number(r.change), number(r.allowed),
            to_string(r.verdict));
  }
  const auto timings =
      std::count_if(rep.rows.begin(), rep.rows.end(), [](const Row& r) { return r.verdict == Verdict::Ratio; });
  out << fmt::format("{} metrics: {} same, {} better, {} worse{} (timings and new metrics aside)\n", rep.rows.size(),
                     rep.same, rep.better, rep.worse, any_change ? "" : "; none changed beyond its tolerance");
  if (timings > 0) {
    out << fmt::format("\ntimings ({}): now / baseline, never a verdict (wall-clock times vary with the machine "
                       "and its load)\n",
                       timings);
    const auto timing = [&](const std::string& c, const std::string& m, const std::string& base,
                            const std::string& now, const std::string& ratio) {
      out << fmt::format("{:<26} {:<26} {:>13} {:>13} {:>11}\n", c, m, base, now, ratio);
    };
    timing("case", "metric", "baseline", "now", "ratio");
    for (const Row& r : rep.rows)
      if (r.verdict == Verdict::Ratio)
        timing(r.case_name, r.metric, number(r.baseline), number(r.now), fmt::format("x{}", number(r.change)));
  }
  return out.str();
}

std::string report_markdown(const Report& rep, const std::string& header) {
  std::ostringstream md;
  md << "# Regression\n\n" << header << "\n\n"
     << fmt::format("**{} metrics: {} same, {} better, {} worse.**\n\n", rep.rows.size(), rep.same, rep.better, rep.worse)
     << "| case | metric | baseline | now | change | allowed | verdict |\n|---|---|---|---|---|---|---|\n";
  for (const Row& r : rep.rows)
    if (r.verdict != Verdict::Ratio)
      md << fmt::format("| {} | {} | {} | {} | {} | {} | {} |\n", r.case_name, r.metric,
                        number(r.baseline) + (r.units.empty() ? "" : " " + r.units), number(r.now), number(r.change),
                        number(r.allowed), r.verdict == Verdict::Worse ? "**worse**" : to_string(r.verdict));
  if (std::any_of(rep.rows.begin(), rep.rows.end(), [](const Row& r) { return r.verdict == Verdict::Ratio; })) {
    md << "\n## Timings\n\nNow / baseline, never a verdict: wall-clock times vary with the machine and its load.\n\n"
       << "| case | metric | baseline | now | ratio |\n|---|---|---|---|---|\n";
    for (const Row& r : rep.rows)
      if (r.verdict == Verdict::Ratio)
        md << fmt::format("| {} | {} | {} | {} | x{} |\n", r.case_name, r.metric,
                          number(r.baseline) + (r.units.empty() ? "" : " " + r.units), number(r.now), number(r.change));
  }
  md << "\n## Bitwise tier\n\n";
  for (const std::string& l : rep.hash_lines) md << "- " << l << "\n";
  return md.str();
}

void write_report_h5(const fs::path& path, const Report& rep) {
  std::vector<RegressFileRow> rows;
  for (const Row& r : rep.rows)
    rows.push_back({r.case_name, r.metric, r.units, to_string(r.verdict), r.baseline, r.now, r.change,
                    r.allowed});
  write_regress_file(path, rows);
}

}  // namespace pbdbench::regress
