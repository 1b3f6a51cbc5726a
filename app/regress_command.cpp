#include "app/regress_command.hpp"

#include <algorithm>
#include <fstream>
#include <ostream>
#include <sstream>

#include <fmt/format.h>

#include "config/data_dir.hpp"
#include "harness/shards.hpp"
#include "harness/slurm.hpp"
#include "harness/sweep.hpp"
#include "regress/regress.hpp"
#include "runfile/build_info.hpp"
#include "runfile/output_guard.hpp"
#include "runfile/regress_file.hpp"
#include "runfile/run_file.hpp"

namespace pbdbench::regress {

namespace fs = std::filesystem;

namespace {
// The text outputs, each known by a line of its own (runfile/output_guard.hpp: only an earlier
// output of the same kind is replaced).
struct TextOutput {
  const char* kind;
  const char* marker;
};
constexpr TextOutput kIndex = {"index of run files", "{\n  \"runs\": [\n"};
constexpr TextOutput kResults = {"regression result (regress.json)", "{\"build\": {\"commit\": "};
constexpr TextOutput kReport = {"regression report (regress.md)", "# Regression\n\n`pbdbench regress` ("};
constexpr TextOutput kBaselines = {"baselines file", "# Baselines of the regression, "};

OutputTarget target(const std::string& argument, const TextOutput& t) {
  const std::string marker = t.marker;
  return OutputTarget{argument, t.kind, [marker](const fs::path& p) { return has_marker(p, marker); }, {}};
}

// What names the regression's folder in a refusal.
std::string out_argument(const RegressCommand& cmd) { return cmd.out.empty() ? "the regression's folder" : "--out"; }

void write_text(const fs::path& path, const std::string& text, const std::string& argument, const TextOutput& t) {
  check_output(path, target(argument, t));
  write_text_output(path, text, argument);
}

// Every output of the command, checked before any run is made: the folders, the report's files
// and, with --update, the baselines.
void check_outputs(const RegressCommand& cmd, const fs::path& baselines) {
  const fs::path out = regress_out(cmd);
  const std::string arg = out_argument(cmd);
  const std::vector<OutputInput> inputs = {{cmd.registry, "the case registry"}, {cmd.against, "the --against folder"}};
  check_output_folder(out, arg, inputs);
  check_output_folder(out / "runs", arg);
  if (cmd.repeat) check_output_folder(out / "repeat", arg);
  check_output(out / "runs" / "index.json", target(arg, kIndex));
  check_output(out / "regress.json", target(arg, kResults));
  check_output(out / "regress.md", target(arg, kReport));
  check_output(out / "regress.h5", OutputTarget{arg, "regress file", is_regress_file, {}});
  if (cmd.update) {
    OutputTarget b = target("--baselines", kBaselines);
    b.inputs = {{cmd.registry, "the case registry"}};
    check_output(baselines, b);
  }
}

// The cases the command selects, in the registry's order.
std::vector<const CaseSpec*> selected(const RegressCommand& cmd, const Registry& reg) {
  std::vector<const CaseSpec*> cases;
  for (const CaseSpec& c : reg.cases)
    if (cmd.cases.empty() ? (cmd.tier == experiments::Tier::Full || c.quick)
                          : std::find(cmd.cases.begin(), cmd.cases.end(), c.name) != cmd.cases.end())
      cases.push_back(&c);
  for (const std::string& name : cmd.cases)
    if (std::none_of(reg.cases.begin(), reg.cases.end(), [&](const CaseSpec& c) { return c.name == name; }))
      throw experiments::ExperimentError(fmt::format("{}: no case named '{}'", reg.file.string(), name));
  return cases;
}

// A case's run files: runs/<case>.h5, and repeat/<case>.h5 with --repeat.
std::vector<fs::path> files_of(const RegressCommand& cmd, const fs::path& out, const CaseSpec& c) {
  std::vector<fs::path> files = {out / "runs" / (c.name + ".h5")};
  if (cmd.repeat) files.push_back(out / "repeat" / (c.name + ".h5"));
  return files;
}

// <runs>/<name>: every case's run file with its status.
void write_index(const fs::path& path, const std::vector<const CaseSpec*>& cases) {
  std::ostringstream js;
  js << "{\n  \"runs\": [\n";
  for (size_t k = 0; k < cases.size(); ++k) {
    const fs::path file = path.parent_path() / (cases[k]->name + ".h5");
    std::string status = "missing";
    if (fs::exists(file)) {
      try {
        status = read_run_file(file, false).status();
      } catch (const std::exception&) {
        status = "unreadable";
      }
    }
    js << fmt::format("    {{\"case\": \"{}\", \"file\": \"{}\", \"status\": \"{}\"}}{}\n", cases[k]->name,
                      file.filename().string(), status, k + 1 < cases.size() ? "," : "");
  }
  js << "  ]\n}\n";
  write_text(path, js.str(), "--out", kIndex);
}

// One case a unit, dealt in turn.
int shard_of(size_t k, int shards) { return static_cast<int>(k % static_cast<size_t>(shards)); }
}  // namespace

fs::path regress_out(const RegressCommand& cmd) {
  return !cmd.out.empty() ? cmd.out : fs::path("results") / "regress" / experiments::to_string(cmd.tier);
}

RegressShards regress_shards(const RegressCommand& cmd, int shards) {
  const Registry reg = load_registry(cmd.registry.empty() ? registry_file() : cmd.registry);
  const std::vector<const CaseSpec*> cases = selected(cmd, reg);
  const fs::path out = regress_out(cmd);
  check_output_folder(out, out_argument(cmd));
  check_output_folder(out / "runs", out_argument(cmd));
  RegressShards r;
  for (size_t k = 0; k < cases.size(); ++k) {
    r.shard.push_back(shard_of(k, shards));
    const std::string config = config::load(cases[k]->scenario, cases[k]->set).to_toml();
    bool make = cmd.force;
    for (const fs::path& file : files_of(cmd, out, *cases[k])) make = make || !run_is_current(file, config);
    r.to_make.push_back(make);
  }
  return r;
}

RegressOutcome run_regress(const RegressCommand& cmd, std::ostream& out, std::ostream& log) {
  const fs::path data = config::data_dir();
  const std::string tier = experiments::to_string(cmd.tier);
  const Registry reg = load_registry(cmd.registry.empty() ? registry_file() : cmd.registry);
  const std::vector<const CaseSpec*> cases = selected(cmd, reg);
  if (cmd.update && cmd.baselines.empty() && !config::data_dir_is_checkout())
    throw experiments::ExperimentError(fmt::format(
        "--update: the data folder {} is an installation, not a source checkout: give --baselines FILE",
        data.string()));

  const fs::path baselines_file =
      !cmd.baselines.empty() ? cmd.baselines : data / "regress" / fmt::format("baselines_{}.toml", tier);
  check_outputs(cmd, baselines_file);
  RegressOutcome outcome;
  outcome.out = regress_out(cmd);
  outcome.runs = outcome.out / "runs";
  bool force = cmd.force;
  bool force_repeat = true;  // --repeat: the second run is always made again

  // The merge of shards: every case's runs must be finished; it makes none.
  if (cmd.merge_shards > 0) {
    for (size_t k = 0; k < cases.size(); ++k) {
      const std::string config = config::load(cases[k]->scenario, cases[k]->set).to_toml();
      for (const fs::path& file : files_of(cmd, outcome.out, *cases[k])) {
        const std::string state = run_state(file, config);
        if (state != "current")
          outcome.unfinished.push_back({shard_of(k, cmd.merge_shards),
                                        fmt::format("{} ({})", cases[k]->name, file.parent_path().filename().string()),
                                        file, state});
      }
    }
    write_index(outcome.runs / "index.json", cases);
    log << fmt::format("regress: merge of {} shards: {} cases, {} runs not finished\n", cmd.merge_shards, cases.size(),
                       outcome.unfinished.size());
    if (!outcome.unfinished.empty()) {
      outcome.out.clear();
      return outcome;
    }
    force = false;
    force_repeat = false;  // the shards made them: read, never run
  }

  // The runs in child processes: a shard's, or all of them with --jobs.
  if (cmd.shard_count > 1 || cmd.jobs > 1) {
    std::vector<ChildRun> children;
    for (size_t k = 0; k < cases.size(); ++k) {
      if (shard_of(k, cmd.shard_count) != cmd.shard_index) continue;
      const config::Config cfg = config::load(cases[k]->scenario, cases[k]->set);
      const std::vector<fs::path> files = files_of(cmd, outcome.out, *cases[k]);
      // The second run of --repeat is made again here, but in a shard only when it is not
      // current (a resubmission completes what is missing).
      const bool shard = cmd.shard_count > 1;
      for (size_t f = 0; f < files.size(); ++f)
        if (force || (f == 1 && !shard) || !run_is_current(files[f], cfg.to_toml()))
          children.push_back({cases[k]->scenario, cases[k]->set, files[f]});
    }
    const int jobs = cmd.jobs > 0 ? cmd.jobs : slurm::allocated_cpus();
    log << fmt::format("regress: {} cases{}, {} runs to make, {} at a time -> {}\n", cases.size(),
                       cmd.shard_count > 1 ? fmt::format(" ({}, {})", shard_name(cmd.shard_index, cmd.shard_count),
                                                         shard_numbering(cmd.shard_count))
                                       : "",
                       children.size(), jobs, outcome.runs.string());
    run_children(cmd.executable, children, jobs, [&](size_t c, const std::string& status, const std::string& message) {
      if (status == "failed" || status == "incomplete") {
        ++outcome.failed_runs;
        log << "  " << children[c].file.string() << ": " << status << "\n" << message;
      }
    });
    if (cmd.shard_count > 1) {
      write_index(outcome.runs / fmt::format("index.shard-{}-of-{}.json", cmd.shard_index, cmd.shard_count), cases);
      out << fmt::format("{}: {} runs made, {} failed; then --merge {} compares and reports\n",
                         shard_name(cmd.shard_index, cmd.shard_count), children.size(), outcome.failed_runs,
                         cmd.shard_count);
      outcome.out.clear();
      return outcome;
    }
    write_index(outcome.runs / "index.json", cases);
    force = false;  // everything is now current: the measurement reads it
    force_repeat = false;
  }

  log << fmt::format("regress: {} cases, {} tier, run files in {}\n", cases.size(), tier, outcome.runs.string());
  std::vector<CaseResult> results;
  for (const CaseSpec* c : cases) {
    results.push_back(measure_case(reg, *c, outcome.runs, force, cmd.control));
    const CaseResult& r = results.back();
    log << fmt::format("  {}: {}{}\n", c->name, r.status,
                       r.warnings.empty() ? "" : fmt::format(" with {} warning{}", r.warnings.size(),
                                                             r.warnings.size() == 1 ? "" : "s"));
  }
  write_text(outcome.out / "regress.json", results_json(results), out_argument(cmd), kResults);

  const fs::path& baselines = baselines_file;
  if (cmd.update) {
    write_text(baselines, baseline_toml(results, cmd.tier), "--baselines", kBaselines);
    out << fmt::format("{} cases measured; baselines written to {} (build {})\n", results.size(),
                       baselines.string(), build_info().git_commit);
    outcome.updated = true;
    return outcome;
  }

  const fs::path base_file = !cmd.against.empty() ? cmd.against / "regress.json" : baselines;
  const Baseline base = read_baseline(base_file);
  Report rep = compare(reg, cases, results, base);
  if (cmd.repeat) {
    for (size_t k = 0; k < cases.size(); ++k) {
      const CaseResult again = measure_case(reg, *cases[k], outcome.out / "repeat", force_repeat, cmd.control);
      const bool same = again.hash == results[k].hash;
      if (!same) ++outcome.bit_differences;
      rep.hash_lines.push_back(fmt::format("{}: run twice, {}", cases[k]->name,
                                           same ? "the same bits (" + again.hash + ")"
                                                : "different bits: " + results[k].hash + " then " + again.hash));
    }
  }
  outcome.worse = rep.worse;
  outcome.better = rep.better;
  std::error_code ec;
  fs::path registry_shown = fs::relative(reg.file, data, ec);
  if (ec || registry_shown.empty() || *registry_shown.begin() == "..") registry_shown = reg.file;
  const std::string header = fmt::format(
      "`pbdbench regress` ({} tier): {} cases of `{}` against `{}` (made by {}). Now: {}. Rows are "
      "metrics; a change beyond `allowed` (abs + rel |baseline|) in the metric's bad direction is "
      "**worse**; timings are ratios, never verdicts.",
      tier, cases.size(), registry_shown.generic_string(), base_file.generic_string(),
      base.commit.empty() ? "an unknown build" : base.commit, build_info().git_commit);
  // The cases' warnings (metrics/health.hpp): what a reader would call a failure though no
  // explosion limit was crossed, listed apart from the verdicts.
  std::string warnings;
  for (const CaseResult& r : results)
    for (const std::string& w : r.warnings) warnings += fmt::format("  {}: WARNING {}\n", r.name, w);
  write_text(outcome.out / "regress.md",
             report_markdown(rep, header) +
                 (warnings.empty() ? "" : "\n## Warnings of the runs\n\n```\n" + warnings + "```\n"),
             out_argument(cmd), kReport);
  write_report_h5(outcome.out / "regress.h5", rep);
  out << report_table(rep);
  if (!warnings.empty()) out << "warnings of the runs:\n" << warnings;
  out << bitwise_text(rep, cmd.bitwise);
  out << fmt::format("-> {}\n", (outcome.out / "regress.md").string());
  return outcome;
}

}  // namespace pbdbench::regress
