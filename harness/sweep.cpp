#include "harness/sweep.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <ostream>
#include <sstream>
#include <toml++/toml.h>

#include "config/toml_text.hpp"
#include "harness/runner.hpp"
#include "harness/shards.hpp"
#include "runfile/build_info.hpp"
#include "core/cancel.hpp"
#include "runfile/output_guard.hpp"
#include "runfile/run_file.hpp"
#include "solver_api/options.hpp"

extern char** environ;

namespace pbdbench {

namespace {

using config::ConfigError;
using config::Source;
namespace fs = std::filesystem;

using config::FlatEntry;

Source at(const fs::path& file, const toml::source_region& region) {
  return config::source_of(file, region);
}
std::string value_text(const toml::node& node, const fs::path& file) {
  return config::toml_value_text(node, file);
}
void flatten(const toml::table& table, const std::string& prefix, std::vector<FlatEntry>& out) {
  for (FlatEntry& e : config::flatten_table(table, prefix)) out.push_back(e);
}

std::string sanitize(const std::string& text) {
  std::string out;
  for (char c : text) {
    const bool ok = std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_';
    out += ok ? c : '_';
  }
  return out;
}

std::string stem_for(const std::vector<std::pair<std::string, std::string>>& params) {
  if (params.empty()) return "run";
  std::string stem;
  for (const auto& [path, value] : params) {
    if (!stem.empty()) stem += "__";
    std::string v = value;
    if (v.size() >= 2 && v.front() == '"' && v.back() == '"') v = v.substr(1, v.size() - 2);
    stem += sanitize(path + "-" + v);
  }
  return stem;
}

std::string json_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      default: out += c;
    }
  }
  return out;
}

void write_index(const SweepSpec& spec, const SweepOptions& options,
                 const std::vector<size_t>& indices, const std::vector<SweepRunResult>& results) {
  std::ostringstream js;
  js << "{\n  \"sweep\": \"" << json_escape(spec.name) << "\",\n";
  js << "  \"description\": \"" << json_escape(spec.description) << "\",\n";
  js << "  \"scenario\": \"" << json_escape(spec.scenario) << "\",\n";
  js << "  \"sweep_file\": \"" << json_escape(spec.file.string()) << "\",\n";
  js << "  \"parameters\": [";
  for (size_t k = 0; k < spec.parameters.size(); ++k)
    js << (k ? ", " : "") << "\"" << json_escape(spec.parameters[k]) << "\"";
  js << "],\n  \"runs\": [\n";
  for (size_t k = 0; k < indices.size(); ++k) {
    const SweepRun& run = spec.runs[indices[k]];
    js << "    {\"file\": \"" << json_escape(fs::path(run.stem + ".h5").string()) << "\", \"params\": {";
    for (size_t p = 0; p < run.params.size(); ++p)
      js << (p ? ", " : "") << "\"" << json_escape(run.params[p].first) << "\": " << run.params[p].second;
    js << "}, \"status\": \"" << json_escape(results[k].status) << "\"}" << (k + 1 < indices.size() ? "," : "") << "\n";
  }
  js << "  ]\n}\n";
  const std::string name = options.shard_count > 1
                               ? "index.shard-" + std::to_string(options.shard_index) + "-of-" +
                                     std::to_string(options.shard_count) + ".json"
                               : "index.json";
  // Rewritten only when it changes, so that an up-to-date sweep leaves its index untouched
  // (what is drawn from it need not be drawn again).
  const fs::path target = options.out_dir / name;
  {
    std::ifstream old(target);
    std::stringstream current;
    current << old.rdbuf();
    if (old && current.str() == js.str()) return;
  }
  const fs::path tmp = options.out_dir / (name + ".tmp");
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error("cannot write " + tmp.string());
    f << js.str();
  }
  fs::rename(tmp, target);
}

std::string tail_of(const fs::path& log, size_t lines) {
  std::ifstream f(log);
  std::vector<std::string> all;
  for (std::string line; std::getline(f, line);) all.push_back(line);
  std::string out;
  for (size_t k = all.size() > lines ? all.size() - lines : 0; k < all.size(); ++k) out += "    " + all[k] + "\n";
  return out;
}

std::string status_from_exit(int wstatus) {
  if (WIFEXITED(wstatus)) {
    switch (WEXITSTATUS(wstatus)) {
      case 0: return "complete";
      case 3: return "exploded";
      case 2: return "refused";
      case 4: return "incomplete";
      default: return "failed";
    }
  }
  return "failed";
}

// A child runs `argv` with stdout and stderr to `log_path`, and dies with the thread that
// started it (PR_SET_PDEATHSIG: SIGTERM, so that it still records itself as interrupted): a
// killed sweep leaves no run going on without it. Only async-signal-safe calls after fork().
pid_t spawn_child(const std::vector<char*>& argv, char* const* envp, const std::string& log_path) {
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(std::string("cannot start a run: fork failed: ") + std::strerror(errno));
  if (pid == 0) {
    if (::prctl(PR_SET_PDEATHSIG, SIGTERM) != 0 || ::getppid() != parent) _exit(127);
    // The parent's handlers and mask are not the child's business: it installs its own.
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    ::sigaction(SIGINT, &dfl, nullptr);
    ::sigaction(SIGTERM, &dfl, nullptr);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0 || ::dup2(fd, STDOUT_FILENO) < 0 || ::dup2(fd, STDERR_FILENO) < 0) _exit(127);
    ::execve(argv[0], argv.data(), envp);
    _exit(127);
  }
  return pid;
}

}  // namespace

bool run_children(const fs::path& executable, const std::vector<ChildRun>& runs, int jobs,
                  const std::function<void(size_t, const std::string&, const std::string&)>& on_done) {
  std::map<pid_t, size_t> running;
  size_t next = 0, done = 0;
  // The children's environment: this one, with each child's share of the cores,
  // max(1, cores / jobs), so that `jobs` runs at once do not each start a thread per core:
  // PBDBENCH_CORES (read by available_cores(): what solver.threads = 0 gives pbd and xpbd), and,
  // unless this environment sets it, OMP_THREAD_LIMIT, the only bound on the OpenMP threads of
  // Debian's CHOLMOD (built with a fixed num_threads(4)), read when a process starts.
  std::vector<std::string> env_text;
  const std::string share_prefix = std::string(kCoresVariable) + "=";
  const std::string share = std::to_string(std::max(1, available_cores() / std::max(jobs, 1)));
  for (char** e = environ; *e != nullptr; ++e)
    if (std::string(*e).rfind(share_prefix, 0) != 0) env_text.emplace_back(*e);
  env_text.push_back(share_prefix + share);
  if (std::getenv("OMP_THREAD_LIMIT") == nullptr) env_text.push_back("OMP_THREAD_LIMIT=" + share);
  std::vector<char*> envp;
  for (std::string& e : env_text) envp.push_back(e.data());
  envp.push_back(nullptr);
  bool stopping = false;
  auto launch = [&](size_t k) {
    const ChildRun& r = runs[k];
    // A run whose writer is alive (a process left by an earlier sweep, another sweep) is not
    // started a second time.
    if (const auto holder = output_holder(r.file)) {
      ++done;
      on_done(k, "busy", "    " + r.file.string() + " is being written by " + *holder + "\n");
      return;
    }
    std::vector<std::string> args = {executable.string(), "run", r.scenario};
    for (const auto& o : r.overrides) {
      args.push_back("--set");
      args.push_back(o.path + "=" + o.value_text);
    }
    args.push_back("--out");
    args.push_back(r.file.string());
    args.push_back("--quiet");
    args.push_back("--no-xdmf");  // `pbdbench export` makes one when wanted
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    fs::create_directories(r.file.parent_path());
    const std::string log_path = fs::path(r.file).replace_extension(".log").string();
    running[spawn_child(argv, envp.data(), log_path)] = k;
  };
  while (done < runs.size()) {
    if (!stopping && cancel_requested()) {
      // Interrupted: launch nothing more, and ask the running children to stop (each records
      // its run as interrupted).
      stopping = true;
      for (const auto& [pid, k] : running) ::kill(pid, SIGTERM);
    }
    while (!stopping && running.size() < static_cast<size_t>(std::max(jobs, 1)) && next < runs.size())
      launch(next++);
    if (running.empty()) break;  // stopping, or the last runs were busy
    // Polled, so that a signal that comes between the check above and the wait is seen within
    // 20 ms (a blocking wait would sleep until a child ends).
    int wstatus = 0;
    const pid_t pid = waitpid(-1, &wstatus, WNOHANG);
    if (pid == 0 || (pid < 0 && errno == EINTR)) {
      ::usleep(20000);
      continue;
    }
    if (pid < 0) throw std::runtime_error(std::string("waitpid failed: ") + std::strerror(errno));
    auto it = running.find(pid);
    if (it == running.end()) continue;
    const size_t k = it->second;
    running.erase(it);
    ++done;
    const std::string status = status_from_exit(wstatus);
    std::string message;
    const fs::path log_path = fs::path(runs[k].file).replace_extension(".log");
    if (status != "complete" && status != "exploded") message = tail_of(log_path, 8);
    on_done(k, status, message);
  }
  return !stopping;
}

bool SweepResult::ok() const {
  return unfinished.empty() && std::none_of(runs.begin(), runs.end(), [](const SweepRunResult& r) {
           return r.status == "failed" || r.status == "refused" || r.status == "incomplete" || r.status == "busy" ||
                  r.status == "pending";
         });
}

SweepSpec load_sweep(const fs::path& path) {
  if (!fs::exists(path)) throw ConfigError({path.string(), 0}, "", "sweep file not found");
  toml::table root;
  try {
    root = toml::parse_file(path.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(at(path, e.source()), "", std::string(e.description()));
  }
  SweepSpec spec;
  spec.file = path;
  spec.name = path.stem().string();
  std::vector<FlatEntry> set_entries, grid_entries;
  std::vector<std::vector<FlatEntry>> cases;
  for (auto&& [key, node] : root) {
    const std::string k(key.str());
    const Source src = at(path, key.source());
    if (k == "name" || k == "description" || k == "scenario") {
      auto s = node.as_string();
      if (!s) throw ConfigError(src, k, "'" + k + "' must be a string");
      if (k == "name") spec.name = s->get();
      if (k == "description") spec.description = s->get();
      if (k == "scenario") spec.scenario = s->get();
    } else if (k == "set" || k == "grid") {
      auto t = node.as_table();
      if (!t) throw ConfigError(src, k, "'" + k + "' must be a table");
      flatten(*t, "", k == "set" ? set_entries : grid_entries);
    } else if (k == "case") {
      auto a = node.as_array();
      if (!a || !a->is_array_of_tables()) throw ConfigError(src, k, "'case' must be an array of tables ([[case]])");
      for (auto&& c : *a) {
        cases.emplace_back();
        flatten(*c.as_table(), "", cases.back());
      }
    } else {
      throw ConfigError(src, k, "unknown key '" + k + "' in a sweep file (expected name, description, scenario, set, grid, case)");
    }
  }
  if (spec.scenario.empty()) throw ConfigError({path.string(), 0}, "scenario", "a sweep file needs 'scenario'");
  const fs::path relative = path.parent_path() / spec.scenario;
  spec.scenario = fs::exists(relative) && fs::is_regular_file(relative)
                      ? relative.string()
                      : config::resolve_scenario(spec.scenario).string();

  std::vector<config::Override> base;
  for (const FlatEntry& e : set_entries) base.push_back({e.path, value_text(*e.node, path)});

  // Grid axes: each a path and its values.
  std::vector<std::pair<std::string, std::vector<std::string>>> axes;
  for (const FlatEntry& e : grid_entries) {
    auto a = e.node->as_array();
    if (!a || a->empty())
      throw ConfigError({path.string(), e.line}, e.path, "grid '" + e.path + "' must be a non-empty array of values");
    std::vector<std::string> values;
    for (auto&& v : *a) values.push_back(value_text(v, path));
    axes.emplace_back(e.path, values);
    spec.parameters.push_back(e.path);
  }
  std::vector<std::vector<std::pair<std::string, std::string>>> case_params;
  for (const auto& c : cases) {
    case_params.emplace_back();
    for (const FlatEntry& e : c) {
      case_params.back().emplace_back(e.path, value_text(*e.node, path));
      if (std::find(spec.parameters.begin(), spec.parameters.end(), e.path) == spec.parameters.end())
        spec.parameters.push_back(e.path);
    }
  }
  if (case_params.empty()) case_params.emplace_back();

  // Every combination: grid points (the first axis outermost), each with every case.
  size_t points = 1;
  for (const auto& axis : axes) points *= axis.second.size();
  for (size_t point = 0; point < points; ++point) {
    std::vector<size_t> digit(axes.size());
    size_t rest = point;
    for (size_t a = axes.size(); a-- > 0;) {
      digit[a] = rest % axes[a].second.size();
      rest /= axes[a].second.size();
    }
    for (const auto& cp : case_params) {
      SweepRun run;
      run.overrides = base;
      for (size_t a = 0; a < axes.size(); ++a) run.params.emplace_back(axes[a].first, axes[a].second[digit[a]]);
      for (const auto& p : cp) run.params.push_back(p);
      for (const auto& [p, v] : run.params) run.overrides.push_back({p, v});
      run.stem = stem_for(run.params);
      spec.runs.push_back(std::move(run));
    }
  }
  std::map<std::string, int> seen;
  for (const SweepRun& r : spec.runs)
    if (++seen[r.stem] > 1)
      throw ConfigError({path.string(), 0}, "", "two runs of this sweep have the same parameters (" + r.stem + "); remove the duplicate values");
  return spec;
}

bool run_is_current(const fs::path& file, const std::string& config_toml) {
  if (!fs::exists(file)) return false;
  try {
    const RunFileData data = read_run_file(file, false);
    const std::string status = data.status();
    if (status != "complete" && status != "exploded") return false;
    auto cfg = data.attributes.find("config");
    auto commit = data.attributes.find("git_commit");
    return cfg != data.attributes.end() && cfg->second == config_toml &&
           commit != data.attributes.end() && commit->second == build_info().git_commit;
  } catch (const std::exception&) {
    return false;
  }
}

SweepResult run_sweep(const SweepSpec& spec, const SweepOptions& options, std::ostream& log) {
  if (options.shard_count < 1 || options.shard_index < 0 || options.shard_index >= options.shard_count)
    throw std::invalid_argument("run_sweep: shards are counted from 0: the shard index must be in [0, count)");
  std::vector<size_t> indices;
  for (size_t k = 0; k < spec.runs.size(); ++k)
    if (static_cast<int>(k % static_cast<size_t>(options.shard_count)) == options.shard_index) indices.push_back(k);

  // Validate every run first: nothing starts when one is refused.
  std::vector<std::vector<config::Override>> overrides(indices.size());
  std::vector<std::string> configs(indices.size());
  for (size_t k = 0; k < indices.size(); ++k) {
    const SweepRun& run = spec.runs[indices[k]];
    overrides[k] = run.overrides;
    overrides[k].insert(overrides[k].end(), options.extra.begin(), options.extra.end());
    try {
      const config::Config cfg = config::load(spec.scenario, overrides[k]);
      check_solver_names(cfg);
      (void)config::build_scene(cfg);
      configs[k] = cfg.to_toml();
    } catch (const ConfigError& e) {
      throw ConfigError({spec.file.string(), 0}, e.key(), "run '" + run.stem + "' is refused: " + e.what());
    }
  }

  check_output_folder(options.out_dir, "--out");  // the one output guard (runfile/output_guard.hpp)
  fs::create_directories(options.out_dir);
  SweepResult result;
  result.runs.resize(indices.size());
  std::vector<size_t> pending;
  for (size_t k = 0; k < indices.size(); ++k) {
    SweepRunResult& r = result.runs[k];
    r.file = options.out_dir / (spec.runs[indices[k]].stem + ".h5");
    if (!options.force && run_is_current(r.file, configs[k])) {
      r.skipped = true;
      r.status = read_run_file(r.file, false).status();
    } else {
      r.status = "pending";
      pending.push_back(k);
    }
  }
  if (options.merge_shards > 0) {
    // The merge makes no run: what is not current is unfinished, named with its shard.
    for (size_t k : pending) {  // (with --force every run is pending: the current ones are fine)
      SweepRunResult& r = result.runs[k];
      r.status = run_state(r.file, configs[k]);
      if (r.status == "current") {
        r.skipped = true;
        r.status = read_run_file(r.file, false).status();
        continue;
      }
      result.unfinished.push_back({static_cast<int>(indices[k] % static_cast<size_t>(options.merge_shards)),
                                   spec.runs[indices[k]].stem, r.file, r.status});
    }
    log << "sweep " << spec.name << ": merge of " << options.merge_shards << " shards: " << indices.size()
        << " runs, " << result.unfinished.size() << " not finished -> " << options.out_dir.string() << "\n";
    if (result.unfinished.empty()) write_index(spec, options, indices, result.runs);
    return result;
  }
  const size_t skipped = indices.size() - pending.size();
  log << "sweep " << spec.name << ": " << indices.size() << " runs";
  if (options.shard_count > 1)
    log << " (" << shard_name(options.shard_index, options.shard_count) << ", " << shard_numbering(options.shard_count)
        << ")";
  log << ", " << skipped << " already complete, " << pending.size() << " to run, " << options.jobs
      << " at a time -> " << options.out_dir.string() << "\n";

  std::vector<ChildRun> children;
  for (size_t k : pending) children.push_back({spec.scenario, overrides[k], result.runs[k].file});
  size_t done = 0;
  result.interrupted = !run_children(options.executable, children, options.jobs,
               [&](size_t c, const std::string& status, const std::string& message) {
                 const size_t k = pending[c];
                 ++done;
                 SweepRunResult& r = result.runs[k];
                 r.status = status;
                 r.message = message;
                 if (options.progress || r.status == "failed" || r.status == "busy" || r.status == "refused")
                   log << "  [" << done << "/" << pending.size() << "] " << spec.runs[indices[k]].stem
                       << ": " << r.status << "\n"
                       << r.message;
                 write_index(spec, options, indices, result.runs);
               });
  if (result.interrupted)
    log << "sweep " << spec.name << ": interrupted; " << std::count_if(result.runs.begin(), result.runs.end(), [](const SweepRunResult& r) { return r.status == "pending"; })
        << " runs not started (run the sweep again to resume)\n";
  write_index(spec, options, indices, result.runs);
  return result;
}

}  // namespace pbdbench
