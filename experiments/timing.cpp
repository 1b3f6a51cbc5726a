#include "experiments/timing.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <ostream>
#include <set>
#include <sstream>

#include <unistd.h>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "catalog/solver_catalog.hpp"
#include "experiments/provenance.hpp"
#include "experiments/sha256.hpp"
#include "harness/runner.hpp"
#include "runfile/utc_now.hpp"
#include "solver_api/options.hpp"

namespace pbdbench::experiments {

namespace fs = std::filesystem;

MedianInterval median_interval(std::vector<double> samples) {
  MedianInterval out;
  const int n = static_cast<int>(samples.size());
  if (n == 0) {
    out.median = out.lo = out.hi = std::numeric_limits<double>::quiet_NaN();
    return out;
  }
  std::sort(samples.begin(), samples.end());
  out.median = n % 2 == 1 ? samples[n / 2] : 0.5 * (samples[n / 2 - 1] + samples[n / 2]);
  // P(B < k) for B ~ Binomial(n, 1/2), k = 1, 2, ...: the largest k with P(B < k) <= 0.025.
  std::vector<double> pmf(static_cast<size_t>(n) + 1);
  double c = 1.0;  // C(n, j)
  for (int j = 0; j <= n; ++j) {
    pmf[static_cast<size_t>(j)] = c * std::pow(0.5, n);
    c = c * (n - j) / (j + 1);
  }
  int k = 1;
  double below = pmf[0];  // P(B < 1) = P(B = 0)
  while (k + 1 <= (n + 1) / 2 && below + pmf[static_cast<size_t>(k)] <= 0.025) {
    below += pmf[static_cast<size_t>(k)];
    ++k;
  }
  // [x_(k), x_(n+1-k)] misses the median with probability 2 P(B < k).
  const double miss = 2.0 * (k == 1 ? pmf[0] : below);
  out.lo = samples[static_cast<size_t>(k - 1)];
  out.hi = samples[static_cast<size_t>(n - k)];
  out.coverage = 1.0 - miss;
  return out;
}

MedianInterval timing_interval(const TimingResult& t, const std::vector<double>& per_repeat) {
  MedianInterval all = median_interval(per_repeat);
  if (t.session.size() != per_repeat.size() || t.sessions.size() < 2) return all;
  for (size_t k = 0; k < t.sessions.size(); ++k) {
    std::vector<double> mine;
    for (size_t r = 0; r < per_repeat.size(); ++r)
      if (t.session[r] == static_cast<int>(k)) mine.push_back(per_repeat[r]);
    if (mine.empty()) continue;
    const MedianInterval one = median_interval(mine);
    all.lo = std::min(all.lo, one.lo);
    all.hi = std::max(all.hi, one.hi);
    all.coverage = std::min(all.coverage, one.coverage);
  }
  return all;
}

fs::path timing_record_path(const fs::path& runs_dir, const std::string& experiment, const std::string& group) {
  return runs_dir / experiment / ("timing-" + group + ".toml");
}

config::Config timing_config(const Experiment& ex, const RunSpec& run, const TimingSpec& timing, Tier tier) {
  std::vector<config::Override> sets = ex.timing_overrides(run, timing, tier);
  config::Config cfg = config::load(ex.scenario_of(run), sets);
  const SolverEntry* solver = find_solver(cfg.get_string("solver.name"));
  const OptionRow* threads = find_solver_option("solver.threads");
  if (solver != nullptr && threads != nullptr && option_applies(*threads, solver->family) &&
      cfg.at("solver.threads").source.file.empty()) {  // the default: not set by the experiment
    sets.push_back({"solver.threads", "1"});
    cfg = config::load(ex.scenario_of(run), sets);
  }
  return cfg;
}

namespace {

std::vector<std::string> config_hashes(const Experiment& ex, const TimingSpec& timing, Tier tier) {
  std::vector<std::string> out;
  for (const std::string& name : timing.runs)
    out.push_back(sha256_hex(timing_config(ex, *ex.find_run(name), timing, tier).to_toml()));
  return out;
}

std::string toml_quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string record_toml(const std::string& experiment, const TimingSpec& timing, Tier tier,
                        const std::vector<std::string>& hashes, const TimingResult& r) {
  std::ostringstream out;
  out << "# Timing samples of one [[timing]] group, written by pbdbench (experiments/timing.hpp):\n"
      << "# the solver time per step (s) of each run in each repeat, after one warm-up repeat.\n"
      << "experiment = " << toml_quote(experiment) << "\n"
      << "group = " << toml_quote(timing.name) << "\n"
      << "tier = " << toml_quote(to_string(tier)) << "\n"
      << "machine = " << toml_quote(r.machine) << "\n"
      << "build = " << toml_quote(r.build) << "\n";
  out << "runs = [";
  for (size_t k = 0; k < timing.runs.size(); ++k) out << (k ? ", " : "") << toml_quote(timing.runs[k]);
  out << "]\n";
  const std::string text = out.str();
  std::ostringstream rest;
  rest << "configs = [";
  for (size_t k = 0; k < hashes.size(); ++k) rest << (k ? ", " : "") << toml_quote(hashes[k]);
  rest << "]  # SHA-256 of each run's resolved configuration\n";
  rest << "status = [";
  for (size_t k = 0; k < r.status.size(); ++k) rest << (k ? ", " : "") << toml_quote(r.status[k]);
  rest << "]\n";
  rest << "sessions = [\n";
  for (size_t k = 0; k < r.sessions.size(); ++k) rest << "  " << toml_quote(r.sessions[k]) << ",\n";
  rest << "]  # one per process that timed the group\n";
  rest << "session = [";
  for (size_t k = 0; k < r.session.size(); ++k) rest << (k ? ", " : "") << r.session[k];
  rest << "]  # per repeat\n";
  rest << "seconds_per_step = [\n";
  for (const std::vector<double>& row : r.seconds_per_step) {
    rest << "  [";
    for (size_t k = 0; k < row.size(); ++k)
      rest << (k ? ", " : "") << (std::isfinite(row[k]) ? fmt::format("{:.16e}", row[k]) : std::string("nan"));
    rest << "],\n";
  }
  rest << "]\n";
  return text + rest.str();
}

bool read_record(const fs::path& path, const std::vector<std::string>& hashes, Tier tier, TimingResult& out) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return false;
  toml::table t;
  try {
    t = toml::parse_file(path.string());
  } catch (const toml::parse_error&) {
    return false;
  }
  if (t["build"].value_or(std::string()) != build_description()) return false;
  if (t["tier"].value_or(std::string()) != to_string(tier)) return false;
  const toml::array* configs = t["configs"].as_array();
  if (configs == nullptr || configs->size() != hashes.size()) return false;
  for (size_t k = 0; k < hashes.size(); ++k)
    if ((*configs)[k].value_or(std::string()) != hashes[k]) return false;
  const toml::array* rows = t["seconds_per_step"].as_array();
  const toml::array* status = t["status"].as_array();
  if (rows == nullptr || status == nullptr || status->size() != hashes.size()) return false;
  out.seconds_per_step.clear();
  for (auto&& row : *rows) {
    const toml::array* a = row.as_array();
    if (a == nullptr || a->size() != hashes.size()) return false;
    std::vector<double> v;
    for (auto&& x : *a) v.push_back(x.value_or(std::numeric_limits<double>::quiet_NaN()));
    out.seconds_per_step.push_back(std::move(v));
  }
  out.status.clear();
  for (auto&& s : *status) out.status.push_back(s.value_or(std::string("?")));
  const toml::array* sessions = t["sessions"].as_array();
  const toml::array* session = t["session"].as_array();
  if (sessions == nullptr || session == nullptr || session->size() != out.seconds_per_step.size()) return false;
  out.sessions.clear();
  out.session.clear();
  std::set<std::string> pids;
  for (auto&& x : *sessions) {
    out.sessions.push_back(x.value_or(std::string("?")));
    pids.insert(out.sessions.back().substr(0, out.sessions.back().find(',')));
  }
  for (auto&& x : *session) {
    const int k = static_cast<int>(x.value_or(int64_t{-1}));
    if (k < 0 || k >= static_cast<int>(out.sessions.size())) return false;
    out.session.push_back(k);
  }
  out.processes = static_cast<int>(pids.size());
  out.machine = t["machine"].value_or(std::string());
  out.build = t["build"].value_or(std::string());
  return true;
}

}  // namespace

bool timing_is_current(const Experiment& ex, const TimingSpec& timing, Tier tier, const fs::path& runs_dir) {
  TimingResult scratch;
  return read_record(timing_record_path(runs_dir, ex.id, timing.name), config_hashes(ex, timing, tier), tier,
                     scratch) &&
         static_cast<int>(scratch.sessions.size()) >= kTimingSessions &&
         static_cast<int>(scratch.seconds_per_step.size()) == timing.repeats * static_cast<int>(scratch.sessions.size());
}

void time_session(const Experiment& ex, const TimingSpec& timing, Tier tier, const fs::path& runs_dir,
                  std::ostream* log) {
  TimingResult r;
  r.group = timing.name;
  r.runs = timing.runs;
  r.record = timing_record_path(runs_dir, ex.id, timing.name);
  const std::vector<std::string> hashes = config_hashes(ex, timing, tier);
  if (!read_record(r.record, hashes, tier, r)) {  // none, or of another build or configuration
    r.seconds_per_step.clear();
    r.session.clear();
    r.sessions.clear();
    r.status.assign(timing.runs.size(), "complete");
  }
  const auto t0 = std::chrono::steady_clock::now();
  const size_t n = timing.runs.size();
  std::vector<config::Config> configs;
  for (const std::string& name : timing.runs) configs.push_back(timing_config(ex, *ex.find_run(name), timing, tier));
  const fs::path dir = runs_dir / ex.id / "timing" / timing.name;
  const int index = static_cast<int>(r.sessions.size());
  r.sessions.push_back(fmt::format("pid {}, started {}", static_cast<long>(::getpid()), utc_now()));
  // The steps are timed with their logging inline (harness/step_logger.hpp): no logger thread
  // reads memory beside the step being timed, and every timing is made the same way.
  RunControl control;
  control.logging = StepLogging::Inline;
  for (int repeat = 0; repeat <= timing.repeats; ++repeat) {  // repeat 0: the warm-up
    std::vector<double> row(n, std::numeric_limits<double>::quiet_NaN());
    for (size_t j = 0; j < n; ++j) {
      const size_t k = (j + static_cast<size_t>(repeat)) % n;  // rotated order
      const RunOutcome outcome = run_config(configs[k], dir / (timing.runs[k] + ".h5"), control);
      if (outcome.status != RunStatus::Complete && r.status[k] == "complete") r.status[k] = to_string(outcome.status);
      if (outcome.steps_completed > 0) row[k] = outcome.solver_time / static_cast<double>(outcome.steps_completed);
    }
    if (repeat > 0) {
      r.seconds_per_step.push_back(std::move(row));
      r.session.push_back(index);
    }
  }
  r.machine = machine_description();
  r.build = build_description();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  fs::create_directories(r.record.parent_path());
  {
    std::ofstream out(r.record);
    out << record_toml(ex.id, timing, tier, hashes, r);
    if (!out) throw std::runtime_error("cannot write " + r.record.string());
  }
  if (log != nullptr)
    *log << fmt::format("  {} timing {} (session {} of {}): {} runs x {} repeats, interleaved, {:.2f} s\n", ex.id,
                        timing.name, index + 1, kTimingSessions, n, timing.repeats, wall);
}

TimingResult time_group(const Experiment& ex, const TimingSpec& timing, Tier tier, const fs::path& runs_dir,
                        bool force, std::ostream* log, const SessionLauncher& launch) {
  TimingResult r;
  r.group = timing.name;
  r.runs = timing.runs;
  r.record = timing_record_path(runs_dir, ex.id, timing.name);
  const std::vector<std::string> hashes = config_hashes(ex, timing, tier);
  std::error_code ec;
  if (force) fs::remove(r.record, ec);
  const auto t0 = std::chrono::steady_clock::now();
  int made = 0;
  for (;;) {
    TimingResult now;
    const bool have = read_record(r.record, hashes, tier, now);
    const int sessions = have ? static_cast<int>(now.sessions.size()) : 0;
    if (have && static_cast<int>(now.seconds_per_step.size()) != timing.repeats * sessions) {
      fs::remove(r.record, ec);  // a record of another repeat count: timed again
      continue;
    }
    if (sessions >= kTimingSessions || made >= kTimingSessions) break;
    if (launch) {
      if (!launch(runs_dir)) throw std::runtime_error(fmt::format("{}: timing group {}: the process timing session {} failed",
                                                                  ex.id, timing.name, sessions + 1));
    } else {
      time_session(ex, timing, tier, runs_dir, log);
    }
    ++made;
  }
  if (!read_record(r.record, hashes, tier, r))
    throw std::runtime_error(fmt::format("{}: not a record of this build's sessions of these configurations ({}) "
                                         "after timing them",
                                         r.record.string(), fmt::join(hashes, ", ")));
  r.group = timing.name;
  r.runs = timing.runs;
  r.reused = made == 0;
  r.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (log != nullptr && r.reused)
    *log << fmt::format("  {} timing {}: {} sessions x {} repeats (reused)\n", ex.id, timing.name, r.sessions.size(),
                        timing.repeats);
  return r;
}

}  // namespace pbdbench::experiments
