// pbdbench: the command-line front end. It depends on every module; nothing depends on it.
//
// Exit codes (stable, for scripts):
//   0  success (run complete; sweep: every run complete or exploded)
//   1  failure (a run failed, a file could not be written or read)
//   2  bad input (usage, scenario or sweep file, --set override)
//   3  run exploded (run only: the file records where)
//   4  run interrupted (SIGINT/SIGTERM: the file is marked incomplete)
//   5  claims --expect: a verdict differs from the record
//   6  regress: a metric is worse than its baseline beyond tolerance, or a repeated run differs
// compare: 0 done, 1 a file could not be read or written or the plot failed, 2 bad input (runs
// of different scenes, a bad --until).
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <new>
#include <system_error>

#include <fmt/format.h>

#include "app/claims_command.hpp"
#include "app/regress_command.hpp"
#include "app/slurm_command.hpp"
#include "catalog/solver_catalog.hpp"
#include "config/config.hpp"
#include "config/data_dir.hpp"
#include "core/cancel.hpp"
#include "core/stage.hpp"
#include "experiments/timing.hpp"
#include "harness/compare.hpp"
#include "harness/converge.hpp"
#include "harness/runner.hpp"
#include "harness/slurm.hpp"
#include "harness/summary.hpp"
#include "harness/sweep.hpp"
#include "runfile/build_info.hpp"
#include "runfile/output_guard.hpp"
#include "runfile/run_file.hpp"
#include "runfile/series.hpp"
#include "runfile/xdmf.hpp"
#include "solver_api/solver.hpp"

namespace fs = std::filesystem;
using namespace pbdbench;

namespace {

constexpr int kExitOk = 0, kExitFailure = 1, kExitBadInput = 2, kExitExploded = 3, kExitInterrupted = 4,
              kExitVerdictChanged = 5, kExitRegression = 6;

std::atomic<bool> g_stop{false};

// The first SIGINT or SIGTERM asks the run to stop (inside its step: core/cancel.hpp) and
// records it as interrupted; a second one ends the process at once.
void on_signal(int sig) {
  if (g_stop.exchange(true)) {
    signal(sig, SIG_DFL);
    raise(sig);
  }
  request_cancel();
}

void install_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

std::vector<config::Override> parse_overrides(const std::vector<std::string>& sets) {
  std::vector<config::Override> out;
  for (const std::string& s : sets) out.push_back(config::parse_override(s));
  return out;
}

// 64-bit FNV-1a, for short stable file names.
std::string short_hash(const std::string& text) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return fmt::format("{:08x}", static_cast<std::uint32_t>(h ^ (h >> 32)));
}

// A progress line on a terminal, redrawn at most ten times a second.
class Progress {
 public:
  explicit Progress(bool enabled) : enabled_(enabled && isatty(STDERR_FILENO)) {}
  void operator()(long done, long total) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (done < total && now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    const int width = 30;
    const int filled = total > 0 ? static_cast<int>(width * done / total) : width;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    std::fprintf(stderr, "\r  [%s%s] %3ld%%  step %ld/%ld  %.1f s", std::string(filled, '#').c_str(),
                 std::string(width - filled, ' ').c_str(), total > 0 ? 100 * done / total : 100, done,
                 total, elapsed);
    if (done >= total) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }
  void end() {
    if (enabled_) std::fprintf(stderr, "\n");
  }

 private:
  bool enabled_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point last_{};
};

fs::path self_executable() { return config::executable_path(); }

// A script of the data folder's scripts/ (config/data_dir.hpp).
fs::path script_path(const char* name) { return config::data_dir() / "scripts" / name; }

// The run file's own scene: its stored configuration, loaded as the scenario file it came from
// (relative mesh paths resolve from there).
Model model_of_run(const fs::path& run_file) {
  const RunFileData d = read_run_file(run_file, false);
  auto cfg_text = d.attributes.find("config");
  if (cfg_text == d.attributes.end()) throw std::runtime_error(run_file.string() + ": no stored configuration");
  auto scenario_file = d.attributes.find("scenario_file");
  const fs::path file = scenario_file != d.attributes.end() ? fs::path(scenario_file->second) : run_file;
  return config::build_scene(config::load_text(cfg_text->second, file)).model;
}

void print_export(const XdmfSummary& x) {
  std::cout << fmt::format("ParaView: {} ({} frames; {} tets, {} triangles, {} edges{}; fields in {})\n",
                           x.xdmf.string(), x.frames, x.tets, x.triangles, x.edges,
                           x.collider_points > 0 ? ", colliders" : "", x.data.filename().string());
}

int cmd_export(const std::vector<std::string>& files, const std::string& out) {
  if (files.empty()) throw CompareInputError("export: name at least one run file");
  if (!out.empty() && files.size() > 1) throw CompareInputError("export: --out takes one run file, not " + std::to_string(files.size()));
  for (const std::string& f : files) {
    const fs::path run_file(f);
    if (!is_run_file(run_file)) throw CompareInputError(f + ": not a pbdbench run file");
    set_stage("exporting a run file to ParaView");
    print_export(write_xdmf(run_file, model_of_run(run_file), out.empty() ? default_xdmf_path(run_file) : fs::path(out),
                            out.empty() ? "the export" : "--out"));
  }
  return kExitOk;
}

int cmd_run(const std::string& scenario, const std::string& solver, const std::vector<std::string>& sets,
            const std::string& out_arg, bool quiet, bool force, bool xdmf) {
  std::vector<config::Override> overrides = parse_overrides(sets);
  if (!solver.empty()) overrides.insert(overrides.begin(), {"solver.name", solver});
  const config::Config cfg = config::load(scenario, overrides);
  const std::string solver_name = cfg.get_string("solver.name");
  const fs::path out = out_arg.empty() ? fs::path("results") / "runs" / cfg.scenario_name /
                                             (solver_name + "-" + short_hash(cfg.to_toml()) + ".h5")
                                       : fs::path(out_arg);
  install_signal_handlers();
  Progress progress(!quiet);
  RunControl control;
  control.progress = [&](long done, long total) { progress(done, total); };
  control.stop = &g_stop;
  control.force = force;
  control.exported = xdmf;
  control.notice = [](const std::string& text) { std::cerr << "pbdbench: " << text << "\n"; };
  const RunOutcome r = run_config(cfg, out, control);
  std::string status = to_string(r.status);
  if (!r.warnings.empty())
    status += fmt::format(" with {} warning{}", r.warnings.size(), r.warnings.size() == 1 ? "" : "s");
  std::cout << fmt::format("{} [{}]: {} after {}/{} steps in {:.2f} s ({:.2f} s in the solver) -> {}\n",
                           cfg.scenario_name, solver_name, status, r.steps_completed, r.steps_planned,
                           r.wall_time, r.solver_time, out.string());
  if (!r.reason.empty()) std::cout << "  " << r.reason << "\n";
  for (const std::string& w : r.warnings) std::cout << "  WARNING " << w << "\n";
  if (!quiet) std::cout << summary_table({{cfg.scenario_name + " " + solver_name, out}});
  if (xdmf && r.steps_completed > 0) {
    try {
      set_stage("exporting the run to ParaView");
      print_export(write_xdmf(out, config::build_scene(cfg).model, default_xdmf_path(out)));
    } catch (const std::bad_alloc&) {
      std::cerr << "pbdbench: no ParaView file: out of memory (std::bad_alloc) while exporting the run "
                   "(the run file is complete; `pbdbench export` writes it later)\n";
    } catch (const std::exception& e) {
      std::cerr << "pbdbench: no ParaView file: " << e.what() << "\n";
    }
  }
  switch (r.status) {
    case RunStatus::Complete: return kExitOk;
    case RunStatus::Exploded: return kExitExploded;
    case RunStatus::Incomplete: return kExitInterrupted;
    case RunStatus::Failed: return kExitFailure;
  }
  return kExitFailure;
}

int cmd_sweep(const std::string& file, const std::string& out_arg, int jobs, bool force,
              const app::ArrayOptions& array, const std::vector<std::string>& sets, bool quiet, int argc, char** argv) {
  const SweepSpec spec = load_sweep(file);
  SweepOptions opt;
  opt.out_dir = out_arg.empty() ? fs::path("results") / "sweeps" / spec.name : fs::path(out_arg);
  opt.jobs = jobs > 0 ? jobs : slurm::allocated_cpus();
  opt.force = force;
  opt.extra = parse_overrides(sets);
  opt.executable = self_executable();
  opt.progress = !quiet;
  app::parse_array_options(array, opt.shard_index, opt.shard_count);
  opt.merge_shards = array.merge;
  if (array.slurm > 0) {
    // One run a unit, dealt in turn (as run_sweep shards).
    std::vector<int> shard;
    std::vector<bool> to_make;
    for (size_t i = 0; i < spec.runs.size(); ++i) {
      std::vector<config::Override> o = spec.runs[i].overrides;
      o.insert(o.end(), opt.extra.begin(), opt.extra.end());
      const fs::path run_file = opt.out_dir / (spec.runs[i].stem + ".h5");
      shard.push_back(static_cast<int>(i % static_cast<size_t>(array.slurm)));
      to_make.push_back(force || !run_is_current(run_file, config::load(spec.scenario, o).to_toml()));
    }
    return app::submit_to_slurm("sweep", array, opt.out_dir, shard, to_make, argc, argv, std::cout);
  }
  install_signal_handlers();
  const SweepResult result = run_sweep(spec, opt, std::cout);
  if (result.interrupted) return kExitInterrupted;
  if (!result.unfinished.empty()) {
    app::report_unfinished("sweep", result.unfinished, opt.merge_shards, opt.out_dir, std::cerr);
    return kExitFailure;
  }
  std::vector<SummaryEntry> entries;
  size_t k = 0;
  for (size_t i = 0; i < spec.runs.size(); ++i) {
    if (static_cast<int>(i % static_cast<size_t>(opt.shard_count)) != opt.shard_index) continue;
    std::string label;
    for (const auto& [path, value] : spec.runs[i].params) label += (label.empty() ? "" : " ") + path + "=" + value;
    entries.push_back({label.empty() ? spec.runs[i].stem : label, result.runs[k++].file});
  }
  std::cout << "\n" << spec.name << (spec.description.empty() ? "" : ": " + spec.description) << "\n";
  std::cout << summary_table(entries);
  return result.ok() ? kExitOk : kExitFailure;
}

// `list --solver-keys`: which solver options each solver reads, as JSON, for the plots
// (scripts/runfile.py solver_reads: a legend names only the keys a run's solver reads).
// {"keys": [every solver option], "reads": {"xpbd": ["solver.iterations", ...], ...}}
int cmd_list_solver_keys() {
  const auto quoted = [](const std::string& s) { return "\"" + s + "\""; };
  std::string keys, reads;
  for (const OptionRow& r : solver_option_rows()) keys += (keys.empty() ? "" : ", ") + quoted(r.key);
  for (const auto& s : solver_catalog()) {
    std::string mine;
    for (const OptionRow& r : solver_option_rows())
      if (option_applies(r, s.family)) mine += (mine.empty() ? "" : ", ") + quoted(r.key);
    reads += fmt::format("{}\n  {}: [{}]", reads.empty() ? "" : ",", quoted(s.name), mine);
  }
  std::cout << "{\"keys\": [" << keys << "],\n\"reads\": {" << reads << "\n}}\n";
  return kExitOk;
}

int cmd_list() {
  std::cout << "Scenarios (" << config::scenarios_dir().string() << "):\n";
  const auto scenarios = config::list_scenarios();
  size_t w = 0, wk = 0;
  for (const auto& s : scenarios) {
    w = std::max(w, s.name.size());
    wk = std::max(wk, s.kind.size());
  }
  for (const auto& s : scenarios)
    std::cout << fmt::format("  {:<{}}  {:<{}}  {}\n", s.name, w, s.kind, wk, s.description);
  std::cout << "\nSolvers:\n";
  for (const auto& s : solver_catalog()) std::cout << fmt::format("  {:<10}  {}\n", s.name, s.doc);
  std::cout << "\nScene kinds (scene.kind):\n";
  for (const auto& k : config::scene_kinds()) std::cout << fmt::format("  {:<10}  {}\n", k.name, k.doc);
  return kExitOk;
}

// A scenario (file or catalog name) is described with its resolved values and their sources; a
// scene kind (or any name with --kind) with its keys. Scenario names win: "spring" is both.
int cmd_describe(const std::string& what, const std::vector<std::string>& sets, bool kind, bool all) {
  bool is_kind = false;
  for (const auto& k : config::scene_kinds()) is_kind = is_kind || k.name == what;
  bool is_scenario = !kind;
  if (is_scenario) {
    try {
      config::resolve_scenario(what);
    } catch (const config::ConfigError&) {
      is_scenario = false;
    }
  }
  if (!is_scenario && (is_kind || kind)) {
    std::cout << config::describe_keys(what);
    return kExitOk;
  }
  const config::Config cfg = config::load(what, parse_overrides(sets));
  // The catalogue, above config/, says which options the solver reads.
  const SolverEntry* solver = find_solver(cfg.get_string("solver.name"));
  std::cout << config::describe_config(cfg, all, 100,
                                       solver ? std::optional(solver->family) : std::nullopt);
  return kExitOk;
}

int cmd_summary(const std::vector<std::string>& files, const std::string& index_dir, bool csv) {
  std::vector<SummaryEntry> entries;
  for (const std::string& f : files) entries.push_back({fs::path(f).stem().string(), f});
  if (!index_dir.empty()) {
    // Files of a sweep directory, in the order of its index.
    const fs::path dir = fs::is_directory(index_dir) ? fs::path(index_dir) : fs::path(index_dir).parent_path();
    std::vector<fs::path> h5;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.path().extension() == ".h5") h5.push_back(e.path());
    std::sort(h5.begin(), h5.end());
    for (const auto& p : h5) entries.push_back({p.stem().string(), p});
  }
  // The ParaView data files that `run` writes beside its run files (RUN.viz.h5) are passed
  // over, silently: `summary results/mine/*.h5` reads the run files of a folder, and a line per
  // export skipped by design would read like a failure.
  std::erase_if(entries, [](const SummaryEntry& e) { return is_xdmf_data(e.file); });
  if (entries.empty()) throw config::ConfigError({"summary", 0}, "", "no run files given");
  for (const SummaryEntry& e : entries) {
    std::error_code ec;
    if (!fs::exists(e.file, ec))
      throw config::ConfigError({"summary", 0}, "", e.file.string() + ": no such file");
    if (!is_run_file(e.file))
      throw config::ConfigError({"summary", 0}, "", e.file.string() + ": not a pbdbench run file");
  }
  std::cout << (csv ? summary_csv(entries) : summary_table(entries));
  return kExitOk;
}

// Runs /usr/bin/python3 SCRIPT ARGS... and returns its exit status (-1 when it could not start).
int run_python(const fs::path& script, const std::vector<std::string>& args) {
  std::vector<std::string> argv_s = {"/usr/bin/python3", script.string()};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv_c;
  for (std::string& a : argv_s) argv_c.push_back(a.data());
  argv_c.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, argv_c[0], nullptr, nullptr, argv_c.data(), environ) != 0) return -1;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return -1;
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The compare file goes to --out; with --plot alone, to a temporary file removed after plotting.
int cmd_compare(const std::string& run_file, const std::string& reference_file,
                const std::string& out_arg, const std::string& plot, double until) {
  const std::vector<OutputInput> inputs = {{run_file, "the run file compared"},
                                           {reference_file, "the reference run file"}};
  if (!out_arg.empty()) check_output(out_arg, OutputTarget{"--out", "compare file", is_compare_file, inputs});
  // The plot: an earlier figure of matplotlib's (its PNG, PDF and SVG writers name it), nothing else.
  if (!plot.empty()) {
    std::vector<OutputInput> not_plot = inputs;
    not_plot.push_back({out_arg, "the compare file (--out)"});
    check_output(plot, OutputTarget{"--plot", "plot (a matplotlib figure)",
                                    [](const fs::path& p) { return has_marker(p, "atplotlib", 1 << 20); }, not_plot});
  }
  const CompareRun run = read_compare_run(run_file);
  const CompareRun reference = read_compare_run(reference_file);
  CompareOptions options;
  options.until = until;
  const CompareResult result = compare_runs(run, reference, options);
  for (const std::string& w : result.warnings) std::cerr << "pbdbench: warning: " << w << "\n";
  std::cout << compare_summary(result);
  fs::path out = out_arg;
  const bool temporary = out.empty() && !plot.empty();
  if (temporary)
    out = fs::temp_directory_path() / fmt::format("pbdbench-compare-{}.h5", static_cast<long>(getpid()));
  if (!out.empty()) {
    write_compare_file(out, result);
    if (!temporary) std::cout << "-> " << out.string() << "\n";
  }
  if (plot.empty()) return kExitOk;
  const fs::path script = script_path("plot_compare.py");
  std::cout.flush();  // before the script's own output
  const int rc = run_python(script, {out.string(), "-o", plot});
  if (temporary) {
    std::error_code ec;
    fs::remove(out, ec);
  }
  if (rc != 0) {
    std::cerr << "pbdbench: " << script.string() << " failed (exit " << rc << "): no plot\n";
    return kExitFailure;
  }
  return kExitOk;  // the script said where it wrote the plot
}

// One step solved every way from the same state: the convergence file and its table.
int cmd_converge(const std::string& scenario, const std::vector<std::string>& sets, int warmup_steps,
                 int max_sweeps, const std::vector<std::string>& methods, const std::string& out,
                 bool quiet) {
  check_output(out, OutputTarget{"--out", "convergence file", is_converge_file, {{scenario, "the scenario file"}}});
  const config::Config cfg = config::load(scenario, parse_overrides(sets));
  ConvergeOptions options;
  options.warmup_steps = warmup_steps;
  options.max_sweeps = max_sweeps;
  options.methods = methods;
  options.progress = !quiet;
  const ConvergeResult result = run_converge(cfg, options);
  write_converge_file(out, result);
  std::cout << converge_table(result, options.target) << "-> " << out << "\n";
  return kExitOk;
}

// The claims' experiments, the report, its figures and the verdict records.
int cmd_claims(experiments::ClaimsCommand command, bool plots, int argc, char** argv) {
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (i == 0) a = fs::path(a).filename().string();
    command.command_line += (i ? " " : "") + a;
  }
  const experiments::ClaimsOutcome outcome = experiments::run_claims(command, std::cout, std::cerr);
  if (!outcome.unfinished.empty()) {  // a merge that found runs not finished
    app::report_unfinished(command.kind == experiments::ExperimentKind::Claim ? "claims" : "paper",
                           outcome.unfinished, command.merge_shards, outcome.runs, std::cerr);
    return kExitFailure;
  }
  if (outcome.out.empty()) return outcome.failed_runs > 0 ? kExitFailure : kExitOk;  // a shard
  if (plots) {
    const fs::path script = script_path("plot_claims.py");  // both reports
    const int rc = run_python(script, {outcome.out.string()});
    if (rc != 0) {
      std::cerr << "pbdbench: the figures were not drawn (" << script << " exited " << rc << ")\n";
      return kExitFailure;
    }
  }
  if (!outcome.differences.empty()) {
    std::cerr << "pbdbench: " << outcome.differences.size() << " verdict(s) differ from " << command.expect
              << ":\n";
    for (const std::string& d : outcome.differences) std::cerr << "  " << d << "\n";
    return kExitVerdictChanged;
  }
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"pbdbench: runs position-based dynamics solvers and references on the same scenes, "
               "and measures how far each is from the truth and what it costs."};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(build_info().version) + " (" + build_info().git_commit + ")");

  std::string scenario, solver, out, file, index_dir;
  std::vector<std::string> sets, files;
  bool quiet = false, force = false, csv = false, markdown = false;
  int jobs = 0;

  auto* run = app.add_subcommand("run", "Run one scenario with one solver and write its run file");
  run->add_option("scenario", scenario, "A scenario file, or a name from scenarios/")->required();
  run->add_option("--solver", solver, "Solver name (same as --set solver.name=NAME)");
  run->add_option("--set", sets, "Override a key by its dotted path: --set time.dt=0.005 (repeatable)");
  run->add_option("--out", out, "Run file to write (default results/runs/<scenario>/<solver>-<hash>.h5)");
  run->add_flag("--quiet", quiet, "Print only the one-line result");
  run->add_flag("--force", force,
                "Run even when the planned run does not fit this machine (memory, disk, more than a day)");

  bool no_xdmf = false;
  run->add_flag("--no-xdmf", no_xdmf, "Do not write the ParaView description (RUN.xdmf and RUN.viz.h5) beside the run file");
  auto* export_sub = app.add_subcommand(
      "export", "Write a run file's ParaView description: RUN.xdmf over its frames, with RUN.viz.h5 beside it");
  export_sub->add_option("files", files, "Run files")->required();
  export_sub->add_option("--out", out, "The XDMF file to write (one run file only; default RUN.xdmf)");

  auto* sweep = app.add_subcommand("sweep", "Run a sweep file's grid in parallel, skipping runs already complete");
  sweep->add_option("file", file, "Sweep file (TOML)")->required();
  sweep->add_option("--out", out, "Directory for the run files (default results/sweeps/<name>)");
  sweep->add_option("--jobs,-j", jobs, "Runs at once (default 0: the cores this process may use: its CPU affinity, $SLURM_CPUS_PER_TASK)")
      ->check(CLI::Range(0, 4096));
  sweep->add_flag("--force", force, "Rerun runs that are already complete");
  sweep->add_option("--set", sets, "Override a key in every run (repeatable)");
  app::ArrayOptions sweep_array;
  app::add_array_options(sweep, sweep_array);
  sweep->add_flag("--quiet", quiet, "Print only the summary");

  bool list_solver_keys = false;
  app.add_subcommand("list", "List the scenarios, solvers and scene kinds")
      ->add_flag("--solver-keys", list_solver_keys, "Print which solver options each solver reads (JSON)");

  auto* describe = app.add_subcommand("describe", "Describe a scenario's keys (types, defaults, units, docs) or a scene kind's");
  describe->add_option("what", scenario, "A scenario (file or name) or a scene kind")->required();
  describe->add_option("--solver", solver, "Describe for this solver (same as --set solver.name=NAME)");
  describe->add_option("--set", sets, "Overrides to apply before describing (repeatable)");
  bool kind = false;
  describe->add_flag("--kind", kind, "Describe the scene kind of this name, not a scenario");
  bool describe_all = false;
  describe->add_flag("--all", describe_all, "Show the keys of every solver, not only the chosen one's");

  auto* summary = app.add_subcommand("summary", "Print a table of what run files measured");
  summary->add_option("files", files, "Run files");
  summary->add_option("--dir", index_dir, "Every run file of a sweep directory");
  summary->add_flag("--csv", csv, "Comma-separated values");

  std::string reference, plot;
  double until = std::numeric_limits<double>::infinity();
  auto* compare = app.add_subcommand(
      "compare", "The gap between two runs of the same scene over time: positions, series, observables");
  compare->add_option("run", file, "The run file to measure")->required();
  compare->add_option("reference", reference, "The run file to measure it against")->required();
  compare->add_option("--out", out, "Compare file (HDF5) to write");
  compare->add_option("--plot", plot, "Plot to draw with scripts/plot_compare.py (PNG)");
  compare->add_option("--until", until, "Compare only up to this time, s (default: the shorter run's end)");

  auto* series = app.add_subcommand("series", "Print the logged series (name, shape, units, doc)");
  series->add_flag("--markdown", markdown, "As the Markdown table of results/README.md");

  int warmup_steps = 0, max_sweeps = 1000;
  auto* converge = app.add_subcommand(
      "converge", "Solve one step of a scene with xpbd (three orders, 1 to N sweeps) and the global "
                  "solvers, and write how each converges");
  converge->add_option("scenario", scenario, "A scenario file, or a name from scenarios/")->required();
  converge->add_option("--set", sets, "Override a key by its dotted path (repeatable)");
  converge->add_option("--warmup-steps", warmup_steps,
                       "Steps of the scene's own solver before the measured step (default 0)")
      ->check(CLI::Range(0, 100000000));
  converge->add_option("--max-sweeps", max_sweeps, "The largest xpbd sweep count (default 1000)")
      ->check(CLI::Range(1, 1000000));
  std::vector<std::string> methods;
  converge->add_option("--methods", methods,
                       "Measure only these methods (comma-separated keys; default all: "
                       "xpbd-sequential, xpbd-colored, xpbd-jacobi, global-cholmod, global-cg, "
                       "global-cg-matrix-free, global-ceres)")
      ->delimiter(',');
  converge->add_option("--out", out, "Convergence file (HDF5) to write")->required();
  converge->add_flag("--quiet", quiet, "No progress lines on stderr");

  // claims and paper: the same engine on two folders of experiments (claims/experiments,
  // reproductions/), with the same options.
  experiments::ClaimsCommand claims_cmd;
  std::string tier = "full";
  bool no_plots = false;
  app::ArrayOptions experiment_array;
  auto add_experiment_options = [&](CLI::App* sub, const std::string& default_out, const std::string& what) {
    sub->add_option("ids", claims_cmd.ids, "Ids (default: every " + what + ")");
    sub->add_option("--tier", tier, "quick (seconds, the test suite) or full (the report)")
        ->check(CLI::IsMember({"quick", "full"}));
    sub->add_option("--out", claims_cmd.out,
                    "Report folder (default " + default_out + " for every " + what +
                        " in the full tier, else results/<command>/<tier>)");
    sub->add_option("--runs", claims_cmd.runs, "Run files folder (default results/<command>/<tier>/runs)");
    sub->add_option("--experiments", claims_cmd.experiments, "Folder of experiment files");
    sub->add_flag("--force", claims_cmd.force, "Run again even when current run files exist");
    sub->add_option("--jobs,-j", claims_cmd.jobs,
                    "Runs at once, in child processes (default: in this process; a shard: the cores it may use)")
        ->check(CLI::Range(1, 4096));
    app::add_array_options(sub, experiment_array);
    sub->add_option("--record", claims_cmd.record, "Write every part's verdict to this file");
    sub->add_option("--expect", claims_cmd.expect, "Compare the verdicts with this record; exit 5 when one differs");
    sub->add_flag("--no-plots", no_plots, "Do not draw the figures");
  };
  auto* claims_sub = app.add_subcommand(
      "claims", "Run the seed article's claims as experiments and write the report with verdicts");
  add_experiment_options(claims_sub, "paper/claims", "claim");
  auto* paper_sub = app.add_subcommand(
      "paper", "Run the paper reproductions and write paper/: each published number beside ours");
  add_experiment_options(paper_sub, "paper", "reproduction");

  experiments::RegisterCommand register_cmd;
  std::string register_what;
  auto* register_sub = app.add_subcommand(
      "register", "Register experiment files (their SHA-256, before any result) in claims/ or reproductions/registry.toml");
  register_sub->add_option("what", register_what, "claims or paper")->required()->check(CLI::IsMember({"claims", "paper"}));
  register_sub->add_option("ids", register_cmd.ids, "Ids (default: every experiment not registered as it is)");
  register_sub->add_option("--note", register_cmd.note,
                           "Why (required when the experiment already has results: a revision after results)");
  register_sub->add_option("--experiments", register_cmd.experiments, "Folder of experiment files");
  register_sub->add_option("--results", register_cmd.results,
                           "The report's JSON whose results an earlier version had (default paper/claims/claims.json "
                           "or paper/reproductions.json)");

  // time-session: one session of a timing group, in a process of its own, started by claims and
  // paper (experiments/timing.hpp: a timing verdict needs the spread between processes).
  std::string session_file, session_group, session_tier = "full", session_runs;
  int session_part = 0;
  auto* session_sub = app.add_subcommand(
      "time-session", "Time one session of an experiment's timing group in this process (claims and paper start it)");
  session_sub->group("");  // not in the help: not meant to be typed
  session_sub->add_option("file", session_file, "Experiment file")->required();
  session_sub->add_option("group", session_group, "Timing group")->required();
  session_sub->add_option("--tier", session_tier, "quick or full")->check(CLI::IsMember({"quick", "full"}));
  session_sub->add_option("--runs", session_runs, "Run files folder of the group's record")->required();
  session_sub->add_option("--part", session_part, "Time the variant of this part's counterfactual (from 1)")
      ->check(CLI::PositiveNumber);

  regress::RegressCommand regress_cmd;
  std::string regress_tier = "quick";
  bool regress_no_plot = false;
  auto* regress_sub = app.add_subcommand(
      "regress", "Run the regression cases and compare their metrics with the stored baselines");
  regress_sub->add_option("cases", regress_cmd.cases, "Case names (default: the tier's)");
  regress_sub->add_option("--tier", regress_tier, "quick (the test suite) or full (every case)")
      ->check(CLI::IsMember({"quick", "full"}));
  regress_sub->add_flag("--update", regress_cmd.update, "Rewrite the tier's baselines from this build");
  regress_sub->add_option("--against", regress_cmd.against,
                          "Compare with another run's output folder (its regress.json) instead of the baselines");
  regress_sub->add_flag("--repeat", regress_cmd.repeat, "Run every case twice and compare the bits (determinism)");
  regress_sub->add_flag("--bitwise", regress_cmd.bitwise,
                        "Print every case's hash against the stored one (default: only differences)");
  regress_sub->add_option("--out", regress_cmd.out, "Output folder (default results/regress/<tier>)");
  regress_sub->add_option("--baselines", regress_cmd.baselines, "Baselines file (default regress/baselines_<tier>.toml)");
  regress_sub->add_option("--registry", regress_cmd.registry,
                          "Registry of metrics and cases (default regress/cases.toml; docs/regress.md has its form)")
      ->check(CLI::ExistingFile);
  regress_sub->add_flag("--force", regress_cmd.force, "Run again even when current run files exist");
  regress_sub->add_flag("--no-plot", regress_no_plot, "Do not draw regress.png");
  regress_sub->add_option("--jobs,-j", regress_cmd.jobs,
                          "Runs at once, in child processes (default: in this process; a shard: the cores it may use)")
      ->check(CLI::Range(1, 4096));
  app::ArrayOptions regress_array;
  app::add_array_options(regress_sub, regress_array);

  // A mistyped subcommand is named, with the closest one (CLI11 would only say that one is
  // required).
  if (argc > 1 && argv[1][0] != '-') {
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands({})) names.push_back(sub->get_name());
    if (std::find(names.begin(), names.end(), argv[1]) == names.end()) {
      const std::string close = config::suggest_name(argv[1], names);
      std::cerr << "pbdbench: unknown command '" << argv[1] << "'"
                << (close.empty() ? "" : " (did you mean '" + close + "'?)") << "; the commands are "
                << fmt::format("{}", fmt::join(names, ", ")) << " (pbdbench --help)\n";
      return kExitBadInput;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? kExitOk : kExitBadInput;
  }

  try {
    if (*run) return cmd_run(scenario, solver, sets, out, quiet, force, !no_xdmf);
    if (*export_sub) return cmd_export(files, out);
    if (*sweep) return cmd_sweep(file, out, jobs, force, sweep_array, sets, quiet, argc, argv);
    if (app.got_subcommand("list")) return list_solver_keys ? cmd_list_solver_keys() : cmd_list();
    if (*describe) {
      if (!solver.empty()) sets.insert(sets.begin(), "solver.name=" + solver);
      return cmd_describe(scenario, sets, kind, describe_all);
    }
    if (*summary) return cmd_summary(files, index_dir, csv);
    if (*compare) return cmd_compare(file, reference, out, plot, until);
    if (*converge) return cmd_converge(scenario, sets, warmup_steps, max_sweeps, methods, out, quiet);
    if (*regress_sub) {
      regress_cmd.tier = regress_tier == "full" ? experiments::Tier::Full : experiments::Tier::Quick;
      regress_cmd.executable = self_executable();
      app::parse_array_options(regress_array, regress_cmd.shard_index, regress_cmd.shard_count);
      regress_cmd.merge_shards = regress_array.merge;
      if (regress_array.slurm > 0) {
        const regress::RegressShards plan = regress::regress_shards(regress_cmd, regress_array.slurm);
        return app::submit_to_slurm("regress", regress_array, regress::regress_out(regress_cmd) / "runs", plan.shard,
                                    plan.to_make, argc, argv, std::cout);
      }
      const regress::RegressOutcome r = regress::run_regress(regress_cmd, std::cout, std::cerr);
      if (!r.unfinished.empty()) {
        app::report_unfinished("regress", r.unfinished, regress_cmd.merge_shards, r.runs, std::cerr);
        return kExitFailure;
      }
      if (r.out.empty()) return r.failed_runs > 0 ? kExitFailure : kExitOk;  // a shard
      if (r.updated) return kExitOk;
      if (!regress_no_plot) {
        const fs::path script = script_path("plot_regress.py");
        if (run_python(script, {(r.out / "regress.h5").string(), (r.out / "regress.png").string()}) != 0)
          std::cerr << "pbdbench: the plot was not drawn (" << script << ")\n";
      }
      return r.worse > 0 || r.bit_differences > 0 ? kExitRegression : kExitOk;
    }
    if (*session_sub) {
      experiments::Experiment ex = experiments::load_experiment(session_file, false);
      if (session_part > 0) {
        if (session_part > static_cast<int>(ex.parts.size()) || !ex.parts[session_part - 1].counterfactual)
          throw experiments::ExperimentError(
              fmt::format("{}: --part {}: no such part with a counterfactual", session_file, session_part));
        ex = ex.with_variant(ex.parts[session_part - 1].counterfactual->runs);
      }
      const experiments::TimingSpec* timing = ex.find_timing(session_group);
      if (timing == nullptr)
        throw experiments::ExperimentError(fmt::format("{}: no timing group named '{}'", session_file, session_group));
      experiments::time_session(ex, *timing,
                                session_tier == "quick" ? experiments::Tier::Quick : experiments::Tier::Full,
                                session_runs, &std::cerr);
      return kExitOk;
    }
    if (*register_sub) {
      register_cmd.kind = register_what == "claims" ? experiments::ExperimentKind::Claim
                                                    : experiments::ExperimentKind::Reproduction;
      experiments::run_register(register_cmd, std::cout);
      return kExitOk;
    }
    if (*claims_sub || *paper_sub) {
      claims_cmd.kind = *claims_sub ? experiments::ExperimentKind::Claim : experiments::ExperimentKind::Reproduction;
      claims_cmd.tier = tier == "quick" ? experiments::Tier::Quick : experiments::Tier::Full;
      claims_cmd.executable = self_executable();
      app::parse_array_options(experiment_array, claims_cmd.shard_index, claims_cmd.shard_count);
      claims_cmd.merge_shards = experiment_array.merge;
      if (experiment_array.slurm > 0) {
        const experiments::ShardPlan plan = experiments::shard_plan(claims_cmd, experiment_array.slurm);
        return app::submit_to_slurm(*claims_sub ? "claims" : "paper", experiment_array,
                                    experiments::runs_folder(claims_cmd), plan.shard, plan.to_make, argc, argv,
                                    std::cout, "runs and timing groups");
      }
      return cmd_claims(claims_cmd, !no_plots, argc, argv);
    }
    if (*series) {
      if (markdown) {
        std::cout << series_markdown();
      } else {
        std::cout << "Each series is a dataset of the run file: /series/<name>, one row per step (row 0 the\n"
                     "initial state), shape (rows,) or (rows, 3); frames are in /frames (time, positions,\n"
                     "velocities), the model in /model (results/README.md has the whole layout).\n\n";
        std::cout << fmt::format("{:<22} {:<3} {:<10} {}\n", "name", "dim", "units", "doc");
        for (const SeriesSpec& s : series_table())
          std::cout << fmt::format("{:<22} {:<3} {:<10} {}\n", s.name, s.width == 1 ? "1" : "3", s.units, s.doc);
        for (const GroupSeriesSpec& g : group_series_table())
          std::cout << fmt::format("{:<22} {:<3} {:<10} {}\n", std::string(g.prefix) + "<group>", "1", g.units, g.doc);
      }
      return kExitOk;
    }
  } catch (const config::ConfigError& e) {
    std::cerr << "pbdbench: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const experiments::ExperimentError& e) {
    std::cerr << "pbdbench: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const CompareInputError& e) {
    std::cerr << "pbdbench: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const OutputRefused& e) {
    std::cerr << "pbdbench: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::bad_alloc&) {
    // Nothing here may allocate much: the message is written piece by piece.
    const auto& used = app.get_subcommands();
    std::cerr << "pbdbench " << (used.empty() ? std::string("") : used.front()->get_name())
              << ": out of memory (std::bad_alloc) while " << current_stage()
              << " (more than this machine or its limit gives the process)\n";
    return kExitFailure;
  } catch (const std::system_error& e) {
    // A thread or a mapping refused for want of memory ("Resource temporarily unavailable")
    // says nothing of where: the stage names it (a file's error names its file).
    if (dynamic_cast<const fs::filesystem_error*>(&e) != nullptr) {
      std::cerr << "pbdbench: " << e.what() << "\n";
      return kExitFailure;
    }
    const auto& used = app.get_subcommands();
    std::cerr << "pbdbench " << (used.empty() ? std::string("") : used.front()->get_name()) << ": " << e.what()
              << " while " << current_stage() << "\n";
    return kExitFailure;
  } catch (const std::exception& e) {
    std::cerr << "pbdbench: " << e.what() << "\n";
    return kExitFailure;
  }
  return kExitBadInput;
}
