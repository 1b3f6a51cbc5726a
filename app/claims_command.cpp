#include "app/claims_command.hpp"

#include <algorithm>
#include <fstream>
#include <iterator>
#include <map>
#include <ostream>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "experiments/claim_index.hpp"
#include "experiments/evaluate.hpp"
#include "experiments/registry.hpp"
#include "experiments/report.hpp"
#include "experiments/sha256.hpp"
#include "experiments/timing.hpp"
#include "harness/shards.hpp"
#include "harness/slurm.hpp"
#include "harness/sweep.hpp"
#include "runfile/build_info.hpp"
#include "runfile/output_guard.hpp"
#include "runfile/run_file.hpp"

namespace pbdbench::experiments {

namespace fs = std::filesystem;

namespace {
// Writes `text` unless the file already holds it (so that a rerun that reused every run file
// leaves the report's time stamps alone and the figures are not redrawn).
void write_text(const fs::path& path, const std::string& text) {
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  {
    std::ifstream in(path, std::ios::binary);
    if (in) {
      const std::string old((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (old == text) return;
    }
  }
  write_text_output(path, text);  // whole or not at all, never through a planted link
}

// Every file the command writes, checked before any run is made (runfile/output_guard.hpp): only
// pbdbench's own earlier report, index and verdict record are replaced, each known by its text.
void check_outputs(const ClaimsCommand& cmd, const fs::path& report, const fs::path& runs, bool claims) {
  auto text = [](const std::string& marker) {
    return [marker](const fs::path& p) { return has_marker(p, marker, 1 << 16); };
  };
  const std::string arg = cmd.out.empty() ? "the report folder" : "--out";
  check_output_folder(report, arg);
  check_output(report / "README.md", OutputTarget{arg, "report (README.md)", text("Do not edit: run the command again."), {}});
  check_output(report / (claims ? "claims.json" : "reproductions.json"),
               OutputTarget{arg, "results file", text("{\n  \"tier\": "), {}});
  check_output_folder(runs, "--runs");
  check_output(runs / "index.json", OutputTarget{"--runs", "index of run files", text("{\n  \"runs\": [\n"), {}});
  if (!cmd.record.empty())
    check_output(cmd.record, OutputTarget{"--record", "verdict record",
                                          text("# The verdict of every part of every experiment, "),
                                          {{cmd.expect, "the --expect record"}}});
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

}  // namespace

namespace {

fs::path folder_of(ExperimentKind kind, const fs::path& given) {
  return !given.empty() ? given : kind == ExperimentKind::Claim ? experiments_dir() : reproductions_dir();
}

// Relative to the working folder, like every default output folder.
fs::path whole_report_dir(ExperimentKind kind) {
  return kind == ExperimentKind::Claim ? fs::path("paper") / "claims" : fs::path("paper");
}

// The experiments named (all when none), in the index's order; throws for an unknown id.
std::vector<Experiment> choose(const std::vector<Experiment>& all, const std::vector<std::string>& ids, bool claims,
                               const fs::path& dir) {
  std::vector<Experiment> chosen;
  for (const std::string& id : ids) {
    auto it = std::find_if(all.begin(), all.end(), [&](const Experiment& e) { return e.id == id; });
    if (it == all.end()) {
      std::vector<std::string> known;
      for (const Experiment& e : all) known.push_back(e.id);
      throw ExperimentError(fmt::format("no {} '{}' in {}; there are: {}", claims ? "claim" : "experiment", id,
                                        dir.string(), fmt::join(known, ", ")));
    }
    chosen.push_back(*it);
  }
  return ids.empty() ? all : chosen;
}

// The experiments of the folder (claims: checked against the index), then those the command names.
std::vector<Experiment> load_chosen(const ClaimsCommand& cmd, fs::path& dir, std::optional<ClaimIndex>& index) {
  const bool claims = cmd.kind == ExperimentKind::Claim;
  dir = folder_of(cmd.kind, cmd.experiments);
  std::vector<Experiment> all = load_experiments(dir);
  if (claims) {  // the index and the experiments cover each other
    index = read_claim_index(claim_index_of(dir));
    check_coverage(*index, all);
  }
  return choose(all, cmd.ids, claims, dir);
}

EvaluateOptions evaluate_options(const ClaimsCommand& cmd, std::ostream* log) {
  EvaluateOptions options;
  options.tier = cmd.tier;
  options.runs_dir = runs_folder(cmd);
  options.force = cmd.force;
  options.log = log;
  options.executable = cmd.executable;
  return options;
}

// Each timing group's sessions at separate times: round r times the r-th session of every group
// before any group's next one (experiments/timing.hpp), each in a process of its own.
void time_in_rounds(const std::vector<Experiment>& chosen, const EvaluateOptions& options) {
  if (options.executable.empty()) return;
  std::error_code ec;
  if (options.force)
    for (const Experiment& e : chosen)
      for (const TimingSpec& t : e.timings) fs::remove(timing_record_path(options.runs_dir, e.id, t.name), ec);
  for (int round = 1; round <= kTimingSessions; ++round)
    for (const Experiment& e : chosen)
      for (const TimingSpec& t : e.timings) {
        if (timing_is_current(e, t, options.tier, options.runs_dir)) continue;
        if (!session_launcher(options.executable, e, t, options.tier)(options.runs_dir))
          throw std::runtime_error(fmt::format("{}: timing group {}: the process timing session {} failed", e.id,
                                               t.name, round));
      }
}

// A timing part whose rule came out the other way in the previous report of the same tier (the
// report being replaced) is inconclusive: the verdict flips between regenerations.
void mark_timing_flips(std::vector<ClaimResult>& results, const fs::path& previous, Tier tier) {
  std::error_code ec;
  if (!fs::exists(previous, ec)) return;
  nlohmann::json old;
  try {
    std::ifstream in(previous);
    old = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception&) {
    return;  // not a report's JSON: nothing to compare
  }
  if (old.value("tier", std::string()) != to_string(tier)) return;
  std::map<std::string, std::pair<bool, std::string>> held;  // part id -> (rule held, verdict)
  for (const nlohmann::json& c : old.value("claims", nlohmann::json::array()))
    for (const nlohmann::json& p : c.value("parts", nlohmann::json::array())) {
      if (!p.value("timing", false)) continue;
      const std::string verdict = p.value("measured", p.value("verdict", std::string()));
      Verdict v;
      if (!parse_verdict(verdict, v) || (v != Verdict::Supported && v != Verdict::Contradicted)) continue;
      held[p.value("id", std::string())] = {v == Verdict::Supported, verdict};
    }
  for (ClaimResult& c : results) {
    for (size_t k = 0; k < c.parts.size(); ++k) {
      PartResult& p = c.parts[k];
      if (!p.timing || (p.measured != Verdict::Supported && p.measured != Verdict::Contradicted)) continue;
      const auto it = held.find(part_id(c, k));
      if (it == held.end() || it->second.first == (p.measured == Verdict::Supported)) continue;
      p.verdict = Verdict::Inconclusive;
      p.reason = fmt::format("the rule came out the other way in the previous report ({}, {}): a timing verdict that "
                             "flips between regenerations is inconclusive",
                             it->second.second, old.value("build", std::string("?")));
    }
    c.verdict = combine_verdicts(c.parts);
  }
}

// The units of the shards (harness/shards.hpp): every planned run alone, and every [[timing]]
// group whole (its runs are timed together in one task: their costs are compared), weighed by
// the runs it makes (runs x (repeats + the warm-up)).
struct Units {
  std::vector<PlannedRun> plan;
  std::vector<std::pair<const Experiment*, const TimingSpec*>> timings;
  std::vector<int> run_shard, timing_shard;
};
Units units_of(const std::vector<Experiment>& chosen, const EvaluateOptions& options, int shards) {
  Units u;
  for (const Experiment& e : chosen) {
    for (PlannedRun& p : plan_runs(e, options)) u.plan.push_back(std::move(p));
    for (const TimingSpec& t : e.timings) u.timings.emplace_back(&e, &t);
  }
  std::vector<size_t> sizes(u.plan.size(), 1);
  for (const auto& [e, t] : u.timings) sizes.push_back(t->runs.size() * static_cast<size_t>(t->repeats + 1));
  const std::vector<int> dealt = deal_units(sizes, shards);
  u.run_shard.assign(dealt.begin(), dealt.begin() + static_cast<long>(u.plan.size()));
  u.timing_shard.assign(dealt.begin() + static_cast<long>(u.plan.size()), dealt.end());
  return u;
}

}  // namespace

fs::path runs_folder(const ClaimsCommand& cmd) {
  return !cmd.runs.empty() ? cmd.runs : fs::path("results") / command_name(cmd.kind) / to_string(cmd.tier) / "runs";
}

ShardPlan shard_plan(const ClaimsCommand& cmd, int shards) {
  fs::path dir;
  std::optional<ClaimIndex> index;
  const std::vector<Experiment> chosen = load_chosen(cmd, dir, index);
  const EvaluateOptions options = evaluate_options(cmd, nullptr);
  const Units u = units_of(chosen, options, shards);
  ShardPlan out;
  for (size_t k = 0; k < u.plan.size(); ++k) {
    out.shard.push_back(u.run_shard[k]);
    out.to_make.push_back(cmd.force || !u.plan[k].current);
  }
  for (size_t k = 0; k < u.timings.size(); ++k) {
    out.shard.push_back(u.timing_shard[k]);
    out.to_make.push_back(cmd.force ||
                          !timing_is_current(*u.timings[k].first, *u.timings[k].second, cmd.tier, options.runs_dir));
  }
  return out;
}

ClaimsOutcome run_claims(const ClaimsCommand& cmd, std::ostream& out, std::ostream& log) {
  const bool claims = cmd.kind == ExperimentKind::Claim;
  fs::path dir;
  std::optional<ClaimIndex> index;
  const std::vector<Experiment> chosen = load_chosen(cmd, dir, index);

  const std::string tier = to_string(cmd.tier);
  ClaimsOutcome outcome;
  const fs::path whole_report = whole_report_dir(cmd.kind);
  outcome.out = !cmd.out.empty() ? cmd.out
                : (cmd.ids.empty() && cmd.tier == Tier::Full) ? whole_report
                                                                : fs::path("results") / command_name(cmd.kind) / tier;
  EvaluateOptions options = evaluate_options(cmd, &log);
  outcome.runs = options.runs_dir;
  check_outputs(cmd, outcome.out, outcome.runs, claims);

  // The merge of shards: every run and every timing group must be finished; it makes none.
  if (cmd.merge_shards > 0) {
    const Units u = units_of(chosen, options, cmd.merge_shards);
    for (size_t k = 0; k < u.plan.size(); ++k) {
      const PlannedRun& p = u.plan[k];
      const std::string state = run_state(p.file, p.config_toml);
      if (state != "current")
        outcome.unfinished.push_back({u.run_shard[k], fmt::format("{}/{}", p.experiment, p.file.stem().string()), p.file,
                                      state});
    }
    for (size_t k = 0; k < u.timings.size(); ++k) {
      const auto& [e, t] = u.timings[k];
      if (timing_is_current(*e, *t, cmd.tier, options.runs_dir)) continue;
      const fs::path record = timing_record_path(options.runs_dir, e->id, t->name);
      outcome.unfinished.push_back({u.timing_shard[k], fmt::format("{}/timing group {}", e->id, t->name), record,
                                    fs::exists(record) ? "stale" : "missing"});
    }
    write_index(options.runs_dir / "index.json", u.plan);
    log << fmt::format("{}: merge of {} shards: {} runs and {} timing groups, {} not finished\n",
                       command_name(cmd.kind), cmd.merge_shards, u.plan.size(), u.timings.size(),
                       outcome.unfinished.size());
    if (!outcome.unfinished.empty()) {
      outcome.out.clear();
      return outcome;
    }
    options.force = false;  // everything is current: the evaluation only reads
  }

  // The runs in child processes: a shard's, or all of them with --jobs.
  if (cmd.shard_count > 1 || cmd.jobs > 1) {
    const Units u = units_of(chosen, options, cmd.shard_count);
    std::vector<ChildRun> children;
    for (size_t k = 0; k < u.plan.size(); ++k) {
      if (u.run_shard[k] != cmd.shard_index) continue;
      if (u.plan[k].current && !cmd.force) continue;
      children.push_back({u.plan[k].scenario, u.plan[k].overrides, u.plan[k].file});
    }
    const int jobs = cmd.jobs > 0 ? cmd.jobs : slurm::allocated_cpus();
    log << fmt::format("{}: {} runs{}, {} to run, {} at a time -> {}\n", command_name(cmd.kind), u.plan.size(),
                       cmd.shard_count > 1 ? fmt::format(" ({}, {})", shard_name(cmd.shard_index, cmd.shard_count),
                                                         shard_numbering(cmd.shard_count))
                                       : "",
                       children.size(), jobs, options.runs_dir.string());
    run_children(cmd.executable, children, jobs,
                 [&](size_t c, const std::string& status, const std::string& message) {
                   if (status == "failed" || status == "incomplete") {
                     ++outcome.failed_runs;
                     log << "  " << children[c].file.string() << ": " << status << "\n" << message;
                   }
                 });
    if (cmd.shard_count > 1) {
      // This shard's timing groups, each timed whole in this process once the runs are done (or
      // read from a current record).
      int timed = 0;
      for (size_t k = 0; k < u.timings.size(); ++k)
        if (u.timing_shard[k] == cmd.shard_index) {
          (void)time_group(*u.timings[k].first, *u.timings[k].second, cmd.tier, options.runs_dir, cmd.force, &log,
                           session_launcher(cmd.executable, *u.timings[k].first, *u.timings[k].second, cmd.tier));
          ++timed;
        }
      write_index(options.runs_dir / fmt::format("index.shard-{}-of-{}.json", cmd.shard_index, cmd.shard_count), u.plan);
      out << fmt::format("{}: {} runs made, {} failed, {} timing groups; then --merge {} writes the report\n",
                         shard_name(cmd.shard_index, cmd.shard_count), children.size(), outcome.failed_runs, timed,
                         cmd.shard_count);
      outcome.out.clear();
      return outcome;
    }
    write_index(options.runs_dir / "index.json", u.plan);
    options.force = false;  // everything is now current: the evaluation reads it
  }

  log << fmt::format("{}: {} experiment{}, {} tier, run files in {}\n", command_name(cmd.kind), chosen.size(),
                     chosen.size() == 1 ? "" : "s", tier, options.runs_dir.string());
  out << fmt::format("id      verdict{}parts ({} {}, {} {}, I inconclusive, - not testable{}; "
                     "lower case: beyond the article's regime), time\n",
                     claims ? "       " : "           ", claims ? "S" : "R", claims ? "supported" : "reproduced",
                     claims ? "C" : "N", claims ? "contradicted" : "not reproduced",
                     claims ? ", = identity, ? not shown able to fail" : ", U setup unknown, = identity, ? not shown able to fail");
  time_in_rounds(chosen, options);
  options.timings_made = !options.executable.empty();  // read, even when forced: just timed
  std::vector<ClaimResult> results;
  for (const Experiment& e : chosen) {
    results.push_back(evaluate_claim(e, options));
    const ClaimResult& r = results.back();
    std::string parts;
    for (const PartResult& p : r.parts) {
      char ch = '-';
      switch (p.verdict) {
        case Verdict::Supported: ch = claims ? 'S' : 'R'; break;
        case Verdict::Contradicted: ch = claims ? 'C' : 'N'; break;
        case Verdict::Inconclusive: ch = 'I'; break;
        case Verdict::SetupUnknown: ch = 'U'; break;
        case Verdict::Identity: ch = '='; break;
        case Verdict::NotShown: ch = '?'; break;
        default: break;
      }
      parts += p.beyond ? static_cast<char>(std::tolower(ch)) : ch;
    }
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
  if (index) ctx.index = &*index;
  const std::vector<Registration> registry = read_registry(registry_of(dir));
  for (const ClaimResult& r : results)
    ctx.registration.emplace(r.id, registration_status(registry, registry_of(dir), r.id, r.file,
                                                       build_info().git_commit));
  mark_timing_flips(results, outcome.out / (claims ? "claims.json" : "reproductions.json"), cmd.tier);
  write_text(outcome.out / "README.md", report_markdown(results, ctx));
  write_text(outcome.out / (claims ? "claims.json" : "reproductions.json"), results_json(results, ctx, outcome.out));
  if (!cmd.record.empty()) write_text(cmd.record, verdicts_toml(results, cmd.tier));
  if (!cmd.expect.empty()) outcome.differences = verdict_differences(results, cmd.expect);

  out << part_counts_line(results) << "\n" << experiment_counts_line(results) << "\n-> "
      << (outcome.out / "README.md").string() << "\n";
  return outcome;
}

int run_register(const RegisterCommand& cmd, std::ostream& out) {
  const bool claims = cmd.kind == ExperimentKind::Claim;
  const fs::path dir = folder_of(cmd.kind, cmd.experiments);
  const std::vector<Experiment> all = load_experiments(dir);
  if (claims) check_coverage(read_claim_index(claim_index_of(dir)), all);
  const fs::path results = !cmd.results.empty() ? cmd.results
                                                : whole_report_dir(cmd.kind) / (claims ? "claims.json" : "reproductions.json");
  return register_experiments(choose(all, cmd.ids, claims, dir), registry_of(dir), results, cmd.note, out);
}

}  // namespace pbdbench::experiments
