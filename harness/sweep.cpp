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
#include <optional>
#include <ostream>
#include <sstream>
#include <fmt/format.h>
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

// The names of this sweep's (or shard's) index and of the journal appended as runs end.
std::string index_name(const SweepOptions& options) {
  return options.shard_count > 1 ? "index.shard-" + std::to_string(options.shard_index) + "-of-" +
                                       std::to_string(options.shard_count) + ".json"
                                 : "index.json";
}
std::string journal_name(const SweepOptions& options) { return index_name(options) + "l"; }  // index.jsonl

std::string run_record(const SweepRun& run, const SweepRunResult& result) {
  std::string js = "{\"file\": \"";
  js += json_escape(fs::path(run.stem + ".h5").string());
  js += "\", \"params\": {";
  for (size_t p = 0; p < run.params.size(); ++p) {
    if (p > 0) js += ", ";
    js += '"';
    js += json_escape(run.params[p].first);
    js += "\": ";
    js += run.params[p].second;
  }
  js += "}, \"status\": \"";
  js += json_escape(result.status);
  js += "\"}";
  return js;
}

std::string index_head(const SweepSpec& spec) {
  std::ostringstream js;
  js << "\"sweep\": \"" << json_escape(spec.name) << "\",\n";
  js << "  \"description\": \"" << json_escape(spec.description) << "\",\n";
  js << "  \"scenario\": \"" << json_escape(spec.scenario) << "\",\n";
  js << "  \"sweep_file\": \"" << json_escape(spec.file.string()) << "\",\n";
  js << "  \"parameters\": [";
  for (size_t k = 0; k < spec.parameters.size(); ++k)
    js << (k ? ", " : "") << "\"" << json_escape(spec.parameters[k]) << "\"";
  js << "]";
  return js.str();
}

// index.json: written once, when the sweep ends (or the merge finds every run), and only when it
// changes, so that an up-to-date sweep leaves its index untouched (what is drawn from it need not
// be drawn again). Its form is what scripts/plot_sweep.py and scripts/runfile.py read.
void write_index(const SweepSpec& spec, const SweepOptions& options,
                 const std::vector<size_t>& indices, const std::vector<SweepRunResult>& results) {
  std::string js = "{\n  " + index_head(spec) + ",\n  \"runs\": [\n";
  for (size_t k = 0; k < indices.size(); ++k)
    js += "    " + run_record(spec.runs[indices[k]], results[k]) + (k + 1 < indices.size() ? ",\n" : "\n");
  js += "  ]\n}\n";
  const std::string name = index_name(options);
  const fs::path target = options.out_dir / name;
  {
    std::ifstream old(target);
    std::stringstream current;
    current << old.rdbuf();
    if (old && current.str() == js) return;
  }
  const fs::path tmp = options.out_dir / (name + ".tmp");
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error("cannot write " + tmp.string());
    f << js;
  }
  fs::rename(tmp, target);
}

// The journal, <index>l (index.jsonl): a line naming the sweep, then a line per run as it ends,
// appended and flushed, so that the sweep's progress is on disk at the cost of the runs that end
// (index.json, rewritten after every run, cost the whole grid each time).
class Journal {
 public:
  Journal(const SweepSpec& spec, const SweepOptions& options) : path_(options.out_dir / journal_name(options)) {
    f_.open(path_, std::ios::trunc);
    if (!f_) throw std::runtime_error("cannot write " + path_.string());
    std::string head = index_head(spec);
    std::replace(head.begin(), head.end(), '\n', ' ');
    f_ << "{" << head << "}\n" << std::flush;
  }
  void add(const SweepRun& run, const SweepRunResult& result) { f_ << run_record(run, result) << "\n" << std::flush; }

 private:
  fs::path path_;
  std::ofstream f_;
};

// The sweep an index or journal belongs to: its "sweep" string, nullopt when the file has none
// (not a sweep's index). Read from the head of the file, where both writers put it.
std::optional<std::string> sweep_of_index(const fs::path& file) {
  std::ifstream f(file, std::ios::binary);
  std::string head(4096, '\0');
  f.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(f.gcount()));
  const std::string key = "\"sweep\": \"";
  const size_t at = head.find(key);
  if (at == std::string::npos) return std::nullopt;
  std::string name;
  for (size_t k = at + key.size(); k < head.size(); ++k) {
    if (head[k] == '"') return name;
    if (head[k] == '\\' && k + 1 < head.size()) ++k;
    name += head[k];
  }
  return std::nullopt;
}

// --out must be this sweep's folder or a new one: an index.json (or this shard's index, or a
// journal) of another sweep, or of something else, is not replaced.
void check_out_dir(const SweepSpec& spec, const SweepOptions& options) {
  if (!fs::exists(options.out_dir)) return;
  if (!fs::is_directory(options.out_dir))
    throw ConfigError({options.out_dir.string(), 0}, "--out", "--out: not a folder: a sweep writes its runs into a folder");
  std::vector<std::string> names = {"index.json", "index.jsonl", index_name(options), journal_name(options)};
  for (const std::string& name : names) {
    const fs::path file = options.out_dir / name;
    if (!fs::exists(file)) continue;
    const std::optional<std::string> owner = sweep_of_index(file);
    if (owner && *owner == spec.name) continue;
    throw ConfigError({file.string(), 0}, "--out",
                      (owner ? "--out: the index of sweep '" + *owner + "'"
                             : std::string("--out: not the index of a sweep")) +
                          ", not of '" + spec.name + "' (" + spec.file.string() +
                          "): it is not replaced; give --out a folder of its own");
  }
}

// Whether the folder holds an index or journal of this sweep (checked above: any there is ours).
bool out_dir_is_ours(const SweepOptions& options) {
  for (const std::string& name : {std::string("index.json"), std::string("index.jsonl"), index_name(options),
                                  journal_name(options)})
    if (fs::exists(options.out_dir / name)) return true;
  return false;
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

// A sweep's name is the folder of its runs under results/sweeps/: one plain name, so that it
// cannot name a folder elsewhere ("../x", "/tmp/x", "a/b").
void check_sweep_name(const std::string& name, const Source& src) {
  const bool plain = !name.empty() && name.size() <= 200 && name.front() != '.' &&
                     std::all_of(name.begin(), name.end(), [](char c) {
                       return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_';
                     });
  if (!plain)
    throw ConfigError(src, "name",
                      "name: '" + name + "' is not a sweep name: the name is the folder results/sweeps/<name>/, so it "
                      "takes letters, digits, '.', '-' and '_' (1 to 200, not starting with '.')");
}

// The grid points (the product of the grid's value counts): refused, with the count, when the
// runs (points times cases) would pass kMaxSweepRuns. Counted in long double, which cannot
// overflow here (at most 2^64 values a key), and checked before any product in size_t.
size_t grid_points(const std::vector<std::pair<std::string, std::vector<std::string>>>& axes, size_t cases,
                   const Source& grid_source) {
  long double runs = static_cast<long double>(std::max<size_t>(cases, 1));
  std::string factors;
  for (const auto& axis : axes) {
    runs *= static_cast<long double>(axis.second.size());
    factors += (factors.empty() ? "" : " x ") + std::to_string(axis.second.size());
  }
  if (runs > static_cast<long double>(kMaxSweepRuns)) {
    if (axes.size() > 8) factors = "the values of " + std::to_string(axes.size()) + " keys";
    else factors = axes.empty() ? "no grid" : factors + " values";
    throw ConfigError(grid_source, "grid",
                      fmt::format("[grid]: the sweep makes {:.4g} runs ({} x {} case{}); a sweep makes at "
                                  "most {}: split it into several sweep files",
                                  static_cast<double>(runs), factors, std::max<size_t>(cases, 1),
                                  cases > 1 ? "s" : "", kMaxSweepRuns));
  }
  size_t points = 1;
  for (const auto& axis : axes) points *= axis.second.size();
  return points;
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
  Source grid_source{path.string(), 0};
  for (auto&& [key, node] : root) {
    const std::string k(key.str());
    const Source src = at(path, key.source());
    if (k == "grid") grid_source = src;
    if (k == "name" || k == "description" || k == "scenario") {
      auto s = node.as_string();
      if (!s) throw ConfigError(src, k, "'" + k + "' must be a string");
      if (k == "name") {
        spec.name = s->get();
        check_sweep_name(spec.name, src);
      }
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
  if (spec.name == "." || spec.name == "..") check_sweep_name(spec.name, {path.string(), 0});
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
  // A key swept twice would make runs that differ in name only, or not at all: the same key
  // twice in [grid] or in one [[case]] (once quoted, "solver.iterations", once as a nested table),
  // or in both (the case's value would replace every grid value).
  std::map<std::string, int> grid_lines;
  for (const FlatEntry& e : grid_entries)
    if (!grid_lines.emplace(e.path, e.line).second)
      throw ConfigError({path.string(), e.line}, e.path,
                        "'" + e.path + "' is in [grid] twice (also line " + std::to_string(grid_lines[e.path]) + ")");
  std::vector<std::vector<std::pair<std::string, std::string>>> case_params;
  for (const auto& c : cases) {
    case_params.emplace_back();
    std::map<std::string, int> case_lines;
    for (const FlatEntry& e : c) {
      if (auto g = grid_lines.find(e.path); g != grid_lines.end())
        throw ConfigError({path.string(), e.line}, e.path,
                          "'" + e.path + "' is both a [grid] key (line " + std::to_string(g->second) +
                              ") and a [[case]] key: every run would take the case's value, and the grid's "
                              "runs would be the same run; sweep it in one of the two");
      if (!case_lines.emplace(e.path, e.line).second)
        throw ConfigError({path.string(), e.line}, e.path,
                          "'" + e.path + "' is in this [[case]] twice (also line " +
                              std::to_string(case_lines[e.path]) + ")");
      case_params.back().emplace_back(e.path, value_text(*e.node, path));
      if (std::find(spec.parameters.begin(), spec.parameters.end(), e.path) == spec.parameters.end())
        spec.parameters.push_back(e.path);
    }
  }
  if (case_params.empty()) case_params.emplace_back();

  // The number of runs, counted without overflow before anything is expanded.
  const size_t points = grid_points(axes, case_params.size(), grid_source);
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
  check_out_dir(spec, options);
  std::vector<size_t> indices;
  for (size_t k = 0; k < spec.runs.size(); ++k)
    if (static_cast<int>(k % static_cast<size_t>(options.shard_count)) == options.shard_index) indices.push_back(k);
  auto overrides_of = [&](size_t k) {
    std::vector<config::Override> o = spec.runs[indices[k]].overrides;
    o.insert(o.end(), options.extra.begin(), options.extra.end());
    return o;
  };

  // Check every run first: nothing starts when one is refused. A run whose file is current (this
  // configuration, this build, finished) was built before and is only compared; the others are
  // built (config::build_scene) to be sure they will not be refused. No configuration is kept
  // (a merge keeps those of the runs not current, to say what their files hold). A cancellation
  // (Ctrl-C) is honoured between two runs.
  SweepResult result;
  result.runs.resize(indices.size());
  std::vector<size_t> pending;
  std::vector<std::string> pending_configs;
  for (size_t k = 0; k < indices.size(); ++k) {
    if (cancel_requested()) {
      log << "sweep " << spec.name << ": interrupted while checking its runs (" << k << " of " << indices.size()
          << " checked); nothing was started\n";
      for (SweepRunResult& r : result.runs) r.status = "pending";
      result.interrupted = true;
      return result;
    }
    const SweepRun& run = spec.runs[indices[k]];
    SweepRunResult& r = result.runs[k];
    r.file = options.out_dir / (run.stem + ".h5");
    try {
      const config::Config cfg = config::load(spec.scenario, overrides_of(k));
      check_solver_names(cfg);
      std::string text = cfg.to_toml();
      if (!options.force && run_is_current(r.file, text)) {
        r.skipped = true;
        r.status = read_run_file(r.file, false).status();
        continue;
      }
      (void)config::build_scene(cfg);
      r.status = "pending";
      pending.push_back(k);
      if (options.merge_shards > 0) pending_configs.push_back(std::move(text));  // for run_state()
    } catch (const ConfigError& e) {
      throw ConfigError({spec.file.string(), 0}, e.key(), "run '" + run.stem + "' is refused: " + e.what());
    }
  }
  // A run's log (<stem>.log) is replaced when it runs: in a folder that holds no index of this
  // sweep, a log without its run file is someone else's.
  if (!out_dir_is_ours(options))
    for (size_t k : pending) {
      const fs::path log_file = fs::path(result.runs[k].file).replace_extension(".log");
      if (fs::exists(log_file) && !fs::exists(result.runs[k].file))
        throw ConfigError({log_file.string(), 0}, "--out",
                          "--out: a log that no index of sweep '" + spec.name +
                              "' accounts for: it is not replaced; give --out a folder of its own");
    }

  if (options.merge_shards > 0) {
    // The merge makes no run: what is not current is unfinished, named with its shard.
    for (size_t p = 0; p < pending.size(); ++p) {  // (with --force every run is pending: the current ones are fine)
      const size_t k = pending[p];
      SweepRunResult& r = result.runs[k];
      r.status = run_state(r.file, pending_configs[p]);
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
    if (result.unfinished.empty()) {
      check_output_folder(options.out_dir, "--out");  // the one output guard (runfile/output_guard.hpp)
      fs::create_directories(options.out_dir);
      write_index(spec, options, indices, result.runs);
    }
    return result;
  }
  check_output_folder(options.out_dir, "--out");  // the one output guard (runfile/output_guard.hpp)
  fs::create_directories(options.out_dir);
  const size_t skipped = indices.size() - pending.size();
  log << "sweep " << spec.name << ": " << indices.size() << " runs";
  if (options.shard_count > 1)
    log << " (" << shard_name(options.shard_index, options.shard_count) << ", " << shard_numbering(options.shard_count)
        << ")";
  log << ", " << skipped << " already complete, " << pending.size() << " to run, " << options.jobs
      << " at a time -> " << options.out_dir.string() << "\n";

  std::vector<ChildRun> children;
  for (size_t k : pending) children.push_back({spec.scenario, overrides_of(k), result.runs[k].file});
  size_t done = 0;
  // Begun anew when something is to run: an up-to-date sweep leaves it, as index.json, untouched.
  std::optional<Journal> journal;
  if (!pending.empty()) journal.emplace(spec, options);
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
                 journal->add(spec.runs[indices[k]], r);
               });
  if (result.interrupted)
    log << "sweep " << spec.name << ": interrupted; " << std::count_if(result.runs.begin(), result.runs.end(), [](const SweepRunResult& r) { return r.status == "pending"; })
        << " runs not started (run the sweep again to resume)\n";
  write_index(spec, options, indices, result.runs);
  return result;
}

}  // namespace pbdbench
