#include "app/claims_command.hpp"

#include <algorithm>
#include <fstream>
#include <iterator>
#include <map>
#include <ostream>
#include <sstream>

#include <fmt/format.h>

#include "experiments/evaluate.hpp"
#include "experiments/report.hpp"
#include "harness/shards.hpp"
#include "harness/slurm.hpp"
#include "harness/sweep.hpp"
#include "runfile/run_file.hpp"

namespace pbdbench::experiments {

namespace fs = std::filesystem;

namespace {
// Writes `text` unless the file already holds it (so that a rerun that reused every run file
// leaves the report's time stamps alone and the figures are not redrawn).
void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  {
    std::ifstream in(path, std::ios::binary);
    if (in) {
      const std::string old((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (old == text) return;
    }
  }
  std::ofstream f(path, std::ios::binary);
  f << text;
  if (!f) throw std::runtime_error("cannot write " + path.string());
}
}  // namespace

namespace {

const char* command_name(ExperimentKind kind) { return kind == ExperimentKind::Claim ? "claims" : "paper"; }

// <runs>/<name>: every planned run file with its status (missing when not made yet).
void write_index(const fs::path& path, const std::vector<PlannedRun>& plan) {
  std::ostringstream js;
  js << "{\n  \"runs\": [\n";
  for (size_t k = 0; k < plan.size(); ++k) {
    const PlannedRun& p = plan[k];
    std::string status = "missing";
    if (fs::exists(p.file)) {
      try {
        status = read_run_file(p.file, false).status();
      } catch (const std::exception&) {
        status = "unreadable";
      }
    }
    js << fmt::format("    {{\"experiment\": \"{}\", \"run\": \"{}\", \"trial\": {}, \"file\": \"{}\", "
                      "\"status\": \"{}\"}}{}\n",
                      p.experiment, p.run, p.trial, fs::relative(p.file, path.parent_path()).generic_string(),
                      status, k + 1 < plan.size() ? "," : "");
  }
  js << "  ]\n}\n";
  write_text(path, js.str());
}

// The experiments the command names (all of them by default), in the index's order.
std::vector<Experiment> chosen_experiments(const ClaimsCommand& cmd, fs::path& dir) {
  const bool claims = cmd.kind == ExperimentKind::Claim;
  dir = !cmd.experiments.empty() ? cmd.experiments : claims ? experiments_dir() : reproductions_dir();
  std::vector<Experiment> all = load_experiments(dir);
  if (cmd.ids.empty()) return all;
  std::vector<Experiment> chosen;
  for (const std::string& id : cmd.ids) {
    auto it = std::find_if(all.begin(), all.end(), [&](const Experiment& e) { return e.id == id; });
    if (it == all.end()) {
      std::vector<std::string> ids;
      for (const Experiment& e : all) ids.push_back(e.id);
      throw ExperimentError(fmt::format("no {} '{}' in {}; there are: {}", claims ? "claim" : "experiment", id,
                                        dir.string(), fmt::join(ids, ", ")));
    }
    chosen.push_back(*it);
  }
  return chosen;
}

// Every run of the chosen experiments, with its shard of `shards`: the units are the plan's
// groups (the runs a timing part compares stay together), dealt by harness/shards.hpp.
std::vector<PlannedRun> plan_all(const std::vector<Experiment>& chosen, const EvaluateOptions& options) {
  std::vector<PlannedRun> plan;
  for (const Experiment& e : chosen)
    for (PlannedRun& p : plan_runs(e, options)) plan.push_back(std::move(p));
  return plan;
}

std::vector<int> shards_of_plan(const std::vector<PlannedRun>& plan, int shards) {
  std::map<std::pair<std::string, int>, size_t> unit_of;
  std::vector<size_t> sizes, unit(plan.size());
  for (size_t k = 0; k < plan.size(); ++k) {
    auto [it, added] = unit_of.try_emplace({plan[k].experiment, plan[k].group}, sizes.size());
    if (added) sizes.push_back(0);
    ++sizes[it->second];
    unit[k] = it->second;
  }
  const std::vector<int> dealt = deal_units(sizes, shards);
  std::vector<int> out(plan.size());
  for (size_t k = 0; k < plan.size(); ++k) out[k] = dealt[unit[k]];
  return out;
}

EvaluateOptions evaluate_options(const ClaimsCommand& cmd, std::ostream* log) {
  EvaluateOptions options;
  options.tier = cmd.tier;
  options.runs_dir = runs_folder(cmd);
  options.force = cmd.force;
  options.log = log;
  return options;
}

}  // namespace

fs::path runs_folder(const ClaimsCommand& cmd) {
  return !cmd.runs.empty() ? cmd.runs : fs::path("results") / command_name(cmd.kind) / to_string(cmd.tier) / "runs";
}

ShardPlan shard_plan(const ClaimsCommand& cmd, int shards) {
  fs::path dir;
  const std::vector<PlannedRun> plan = plan_all(chosen_experiments(cmd, dir), evaluate_options(cmd, nullptr));
  ShardPlan out;
  out.shard = shards_of_plan(plan, shards);
  for (const PlannedRun& p : plan) out.to_make.push_back(cmd.force || !p.current);
  return out;
}

ClaimsOutcome run_claims(const ClaimsCommand& cmd, std::ostream& out, std::ostream& log) {
  const bool claims = cmd.kind == ExperimentKind::Claim;
  fs::path dir;
  const std::vector<Experiment> chosen = chosen_experiments(cmd, dir);

  const std::string tier = to_string(cmd.tier);
  ClaimsOutcome outcome;
  const fs::path whole_report = claims ? fs::path("paper") / "claims" : fs::path("paper");
  outcome.out = !cmd.out.empty() ? cmd.out
                : (cmd.ids.empty() && cmd.tier == Tier::Full) ? whole_report
                                                                : fs::path("results") / command_name(cmd.kind) / tier;
  EvaluateOptions options = evaluate_options(cmd, &log);
  outcome.runs = options.runs_dir;

  // The merge of shards: every run must be finished; it makes none.
  if (cmd.merge_shards > 0) {
    const std::vector<PlannedRun> plan = plan_all(chosen, options);
    const std::vector<int> shard = shards_of_plan(plan, cmd.merge_shards);
    for (size_t k = 0; k < plan.size(); ++k) {
      const std::string state = run_state(plan[k].file, plan[k].config_toml);
      if (state != "current")
        outcome.unfinished.push_back({shard[k], fmt::format("{}/{}", plan[k].experiment, plan[k].file.stem().string()),
                                      plan[k].file, state});
    }
    write_index(options.runs_dir / "index.json", plan);
    log << fmt::format("{}: merge of {} shards: {} runs, {} not finished\n", command_name(cmd.kind),
                       cmd.merge_shards, plan.size(), outcome.unfinished.size());
    if (!outcome.unfinished.empty()) {
      outcome.out.clear();
      return outcome;
    }
    options.force = false;  // everything is current: the evaluation only reads
  }

  // The runs in child processes: a shard's, or all of them with --jobs.
  if (cmd.shard_count > 1 || cmd.jobs > 1) {
    const std::vector<PlannedRun> plan = plan_all(chosen, options);
    const std::vector<int> shard = shards_of_plan(plan, cmd.shard_count);
    std::vector<ChildRun> children;
    for (size_t k = 0; k < plan.size(); ++k) {
      if (shard[k] != cmd.shard_index) continue;
      if (plan[k].current && !cmd.force) continue;
      children.push_back({plan[k].scenario, plan[k].overrides, plan[k].file});
    }
    const int jobs = cmd.jobs > 0 ? cmd.jobs : slurm::allocated_cpus();
    log << fmt::format("{}: {} runs{}, {} to run, {} at a time -> {}\n", command_name(cmd.kind), plan.size(),
                       cmd.shard_count > 1 ? fmt::format(" (shard {} of {})", cmd.shard_index, cmd.shard_count) : "",
                       children.size(), jobs, options.runs_dir.string());
    run_children(cmd.executable, children, jobs,
                 [&](size_t c, const std::string& status, const std::string& message) {
                   if (status == "failed" || status == "incomplete") {
                     ++outcome.failed_runs;
                     log << "  " << children[c].file.string() << ": " << status << "\n" << message;
                   }
                 });
    if (cmd.shard_count > 1) {
      write_index(options.runs_dir / fmt::format("index.shard-{}-of-{}.json", cmd.shard_index, cmd.shard_count), plan);
      out << fmt::format("shard {} of {}: {} runs made, {} failed; then --merge {} writes the report\n",
                         cmd.shard_index, cmd.shard_count, children.size(), outcome.failed_runs, cmd.shard_count);
      outcome.out.clear();
      return outcome;
    }
    write_index(options.runs_dir / "index.json", plan);
    options.force = false;  // everything is now current: the evaluation reads it
  }

  log << fmt::format("{}: {} experiment{}, {} tier, run files in {}\n", command_name(cmd.kind), chosen.size(),
                     chosen.size() == 1 ? "" : "s", tier, options.runs_dir.string());
  out << fmt::format("id      verdict{}parts ({} {}, {} {}, - not testable), time\n",
                     claims ? "       " : "           ", claims ? "S" : "R", claims ? "supported" : "reproduced",
                     claims ? "C" : "N", claims ? "contradicted" : "not reproduced");
  std::vector<ClaimResult> results;
  for (const Experiment& e : chosen) {
    results.push_back(evaluate_claim(e, options));
    const ClaimResult& r = results.back();
    std::string parts;
    for (const PartResult& p : r.parts)
      parts += p.verdict == Verdict::Supported ? (claims ? 'S' : 'R') : p.verdict == Verdict::Contradicted ? (claims ? 'C' : 'N') : '-';
    out << fmt::format("{:<7} {:<{}} [{}] {:6.1f} s\n", r.id, verdict_word(r.verdict, r.kind), claims ? 13 : 17, parts,
                       r.wall_time);
    out.flush();
  }

  ReportContext ctx;
  ctx.tier = cmd.tier;
  ctx.machine = machine_description();
  ctx.build = build_description();
  ctx.command = cmd.command_line;
  ctx.figures_dir = "figures";
  ctx.jobs = std::max(cmd.jobs, 1);
  write_text(outcome.out / "README.md", report_markdown(results, ctx));
  write_text(outcome.out / (claims ? "claims.json" : "reproductions.json"), results_json(results, ctx, outcome.out));
  if (!cmd.record.empty()) write_text(cmd.record, verdicts_toml(results, cmd.tier));
  if (!cmd.expect.empty()) outcome.differences = verdict_differences(results, cmd.expect);

  int counts[3] = {0, 0, 0};
  for (const ClaimResult& r : results) ++counts[static_cast<int>(r.verdict)];
  out << fmt::format("{} {}: {} {}, {} {}, {} not testable -> {}\n", results.size(),
                     claims ? "claims" : "experiments", counts[0], claims ? "supported" : "reproduced", counts[1],
                     claims ? "contradicted" : "not reproduced", counts[2], (outcome.out / "README.md").string());
  return outcome;
}

}  // namespace pbdbench::experiments
