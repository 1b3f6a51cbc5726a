#include "app/slurm_command.hpp"

#include <algorithm>
#include <cstdlib>
#include <ostream>

#include <fmt/format.h>

#include "config/config.hpp"
#include "config/data_dir.hpp"
#include "harness/slurm.hpp"

namespace pbdbench::app {

namespace fs = std::filesystem;

// Shards of one job array: a bound that names itself in the message (a positive-number check
// printed its upper bound as a 309-digit number).
constexpr int kMostShards = 100000;

void add_array_options(CLI::App* command, ArrayOptions& o) {
  command->add_option("--shard", o.shard,
                      "Make only the runs of shard I of N, one task of a job array. Shards are counted from 0, as "
                      "Slurm's array task ids: I/N with 0 <= I < N (0/4, 1/4, 2/4 and 3/4 for four shards)");
  command->add_option("--merge", o.merge,
                      "After N shards: check that every run is finished (exit 1 naming the shards that are not) "
                      "and write the report; makes no run")
      ->check(CLI::Range(1, kMostShards));
  command->add_option("--slurm", o.slurm,
                      "Submit the runs as a Slurm job array of N tasks and the merge after it (scripts and logs "
                      "in <run files>/slurm/; docs/cluster.md)")
      ->check(CLI::Range(1, kMostShards));
  command->add_option("--slurm-opt", o.slurm_options,
                      "sbatch options for both jobs, e.g. --slurm-opt='--time=02:00:00 --partition=short' (repeatable)");
  command->add_option("--slurm-template", o.slurm_template,
                      "A file of #SBATCH lines and environment setup (module load ...) for both jobs");
  command->add_flag("--no-submit", o.no_submit, "With --slurm: write the scripts and print how to submit them");
}

void parse_array_options(const ArrayOptions& o, int& index, int& count) {
  const int modes = (o.shard.empty() ? 0 : 1) + (o.merge > 0 ? 1 : 0) + (o.slurm > 0 ? 1 : 0);
  if (modes > 1) throw config::ConfigError({"--shard/--merge/--slurm", 0}, "", "give one of --shard, --merge and --slurm");
  if ((!o.slurm_options.empty() || !o.slurm_template.empty() || o.no_submit) && o.slurm == 0)
    throw config::ConfigError({"--slurm-opt/--slurm-template/--no-submit", 0}, "", "these go with --slurm N");
  if (o.shard.empty()) return;
  const auto slash = o.shard.find('/');
  try {
    if (slash == std::string::npos) throw std::invalid_argument("no slash");
    size_t used = 0;
    index = std::stoi(o.shard.substr(0, slash), &used);
    if (used != slash) throw std::invalid_argument("not a number");
    count = std::stoi(o.shard.substr(slash + 1), &used);
    if (used != o.shard.size() - slash - 1) throw std::invalid_argument("not a number");
  } catch (const std::exception&) {
    throw config::ConfigError({"--shard " + o.shard, 0}, "",
                              "expected I/N, two integers: shard I of N, counted from 0 (0/N to N-1/N)");
  }
  if (count < 1)
    throw config::ConfigError({"--shard " + o.shard, 0}, "", "N, the number of shards, must be at least 1");
  if (index < 0 || index >= count)
    throw config::ConfigError({"--shard " + o.shard, 0}, "",
                              fmt::format("shards are {} (I/N with 0 <= I < N)", shard_numbering(count)));
}

int submit_to_slurm(const std::string& command, const ArrayOptions& o, const fs::path& run_files,
                    const std::vector<int>& shard, const std::vector<bool>& to_make, int argc, char** argv,
                    std::ostream& out, const std::string& what) {
  std::vector<int> shards_with_work;
  std::size_t runs_left = 0;
  for (std::size_t k = 0; k < shard.size(); ++k)
    if (to_make[k]) {
      ++runs_left;
      shards_with_work.push_back(shard[k]);
    }
  std::sort(shards_with_work.begin(), shards_with_work.end());
  shards_with_work.erase(std::unique(shards_with_work.begin(), shards_with_work.end()), shards_with_work.end());
  const std::size_t runs = shard.size();
  // The folder is checked first, named by what set it, before anything is planned into it.
  slurm::check_script_value(run_files.string(), command == "sweep"     ? "the sweep's folder (--out, else the sweep file's name)"
                                                : command == "regress" ? "the regression's folder (--out)"
                                                                       : "the run files' folder (--runs, --out)");
  slurm::check_script_value(fs::current_path().string(), "the working folder (where the jobs run)");
  const slurm::SiteSettings site = slurm::site_settings(o.slurm_options, o.slurm_template);
  slurm::Jobs jobs;
  jobs.command = command;
  jobs.dir = fs::absolute(run_files / "slurm").lexically_normal();
  jobs.workdir = fs::current_path();
  jobs.executable = config::executable_path();
  jobs.shards = o.slurm;
  std::vector<std::string> typed(argv + 1, argv + argc);
  jobs.args = slurm::strip_slurm_options(typed);
  // What decides where the data is: carried explicitly, in case the site does not export the
  // submitting environment (SBATCH_EXPORT=NONE).
  for (const char* name : {"PBDBENCH_DATA_DIR", "PBDBENCH_SCENARIOS", "PBDBENCH_CLAIMS"})
    if (const char* v = std::getenv(name); v != nullptr && *v != '\0')
      jobs.environment.emplace_back(name, fs::absolute(v).lexically_normal().string());
  // submit.sh completes what is missing: without --force (which would redo every run again).
  std::vector<std::string> again = {jobs.executable.string()};
  for (const std::string& a : typed)
    if (a != "--no-submit" && a != "--force") again.push_back(a);
  const slurm::ScriptFiles files = slurm::write_scripts(jobs, site, again);

  out << fmt::format("{}: {} of {} {} to make, in {} of {} shards; scripts and logs in {}\n", command, runs_left, runs,
                     what, shards_with_work.size(), o.slurm, jobs.dir.string());
  const std::string by_hand =
      shards_with_work.empty()
          ? fmt::format("sbatch {}", slurm::shell_quote(files.merge.string()))
          : fmt::format("jid=$(sbatch --parsable --array={} {}) && sbatch --dependency=afterany:$jid {}",
                        array_list(shards_with_work), slurm::shell_quote(files.array.string()),
                        slurm::shell_quote(files.merge.string()));
  if (o.no_submit) {
    out << "not submitted (--no-submit); submit with:\n  " << by_hand << "\n";
    return 0;
  }
  const slurm::Submitted s = slurm::submit(files, shards_with_work);
  if (!s.array_job.empty())
    out << fmt::format("submitted job array {} (shards {}), and the merge, job {}, after it\n", s.array_job,
                       array_list(shards_with_work), s.merge_job);
  else
    out << fmt::format("every run is finished: submitted only the merge, job {}\n", s.merge_job);
  out << fmt::format("  watch: squeue -j {}{}\n", s.array_job.empty() ? "" : s.array_job + ",", s.merge_job);
  out << fmt::format("  logs:  {}/{}-{}_<shard>.log, {}/{}-merge-{}.log\n", jobs.dir.string(), command,
                     s.array_job.empty() ? "<job>" : s.array_job, jobs.dir.string(), command, s.merge_job);
  out << fmt::format("  if the merge fails it names the shards to redo: bash {} resubmits only those\n",
                     slurm::shell_quote(files.submit.string()));
  return 0;
}

void report_unfinished(const std::string& command, const std::vector<UnfinishedRun>& runs, int shards,
                       const fs::path& run_files, std::ostream& err) {
  const std::vector<int> bad = shards_of(runs);
  const fs::path dir = fs::absolute(run_files / "slurm").lexically_normal();
  std::string next;
  std::error_code ec;
  if (fs::exists(dir / "submit.sh", ec)) {
    next = fmt::format(
        "Task logs: {}/{}-<job>_<shard>.log. Resubmit the shards that are not finished (only those), and a new "
        "merge after them:\n  bash {}\nor by hand:\n  jid=$(sbatch --parsable --array={} {}) && sbatch "
        "--dependency=afterany:$jid {}\n",
        dir.string(), command, slurm::shell_quote((dir / "submit.sh").string()), array_list(bad),
        slurm::shell_quote((dir / (command + ".array.sbatch")).string()),
        slurm::shell_quote((dir / (command + ".merge.sbatch")).string()));
  } else {
    next = fmt::format("Make them: the same command with --shard I/{} for each shard above (or without --merge, "
                       "here), then --merge {} again.\n",
                       shards, shards);
  }
  err << "pbdbench: " << unfinished_report(runs, shards, next);
}

}  // namespace pbdbench::app
