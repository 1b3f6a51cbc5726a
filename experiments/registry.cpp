#include "experiments/registry.hpp"

#include <sys/wait.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <ostream>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <toml++/toml.h>

#include "experiments/experiment.hpp"
#include "experiments/sha256.hpp"
#include "runfile/output_guard.hpp"
#include "runfile/utc_now.hpp"

namespace pbdbench::experiments {

namespace fs = std::filesystem;

namespace {

std::string toml_quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default: out += c;
    }
  }
  return out + "\"";
}

std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// Runs a command, returns (exit status, stdout). Status -1 when it could not be started.
std::pair<int, std::string> capture(const std::string& command) {
  FILE* pipe = ::popen((command + " 2>/dev/null").c_str(), "r");
  if (pipe == nullptr) return {-1, ""};
  std::string out;
  std::array<char, 4096> buf{};
  while (size_t n = std::fread(buf.data(), 1, buf.size(), pipe)) out.append(buf.data(), n);
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

std::map<std::string, std::string> string_map(const toml::node* node, const fs::path& file, const std::string& key) {
  std::map<std::string, std::string> out;
  if (node == nullptr) return out;
  const toml::table* t = node->as_table();
  if (t == nullptr)
    throw ExperimentError(fmt::format("{}:{}: {}: must be a table of strings", file.string(),
                                      node->source().begin.line, key));
  for (auto&& [k, v] : *t) {
    if (!v.is_string())
      throw ExperimentError(fmt::format("{}:{}: {}.{}: must be a string", file.string(), v.source().begin.line,
                                        key, std::string(k.str())));
    out[std::string(k.str())] = v.as_string()->get();
  }
  return out;
}

}  // namespace

fs::path registry_of(const fs::path& experiments_dir) { return experiments_dir.parent_path() / "registry.toml"; }

std::vector<Registration> read_registry(const fs::path& file) {
  std::vector<Registration> out;
  std::error_code ec;
  if (!fs::exists(file, ec)) return out;
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw ExperimentError(fmt::format("{}:{}: {}", file.string(), e.source().begin.line, e.description()));
  }
  for (auto&& [key, node] : root)
    if (key.str() != "registration")
      throw ExperimentError(fmt::format("{}:{}: {}: unknown key (a registry holds [[registration]] entries)",
                                        file.string(), key.source().begin.line, std::string(key.str())));
  const toml::array* entries = root["registration"].as_array();
  if (entries == nullptr) return out;
  for (auto&& node : *entries) {
    const toml::table* t = node.as_table();
    const int line = static_cast<int>(node.source().begin.line);
    if (t == nullptr) throw ExperimentError(fmt::format("{}:{}: registration: must be a table", file.string(), line));
    Registration r;
    r.line = line;
    auto str = [&](const char* k, bool required) {
      const toml::node* n = t->get(k);
      if (n == nullptr) {
        if (required) throw ExperimentError(fmt::format("{}:{}: registration.{}: missing", file.string(), line, k));
        return std::string();
      }
      if (!n->is_string())
        throw ExperimentError(fmt::format("{}:{}: registration.{}: must be a string", file.string(),
                                          n->source().begin.line, k));
      return n->as_string()->get();
    };
    for (auto&& [k, v] : *t) {
      const std::string name(k.str());
      if (name != "experiment" && name != "sha256" && name != "registered" && name != "note" && name != "earlier")
        throw ExperimentError(fmt::format("{}:{}: registration.{}: unknown key", file.string(),
                                          k.source().begin.line, name));
    }
    r.experiment = str("experiment", true);
    r.sha256 = str("sha256", true);
    r.registered = str("registered", true);
    r.note = str("note", false);
    if (r.sha256.size() != 64)
      throw ExperimentError(fmt::format("{}:{}: registration.sha256: not a SHA-256 (64 hex digits)", file.string(), line));
    if (const toml::node* e = t->get("earlier")) {
      const toml::table* et = e->as_table();
      if (et == nullptr)
        throw ExperimentError(fmt::format("{}:{}: registration.earlier: must be a table", file.string(), line));
      EarlierResult er;
      if (const auto v = (*et)["verdict"].value<std::string>()) er.verdict = *v;
      if (const auto v = (*et)["source"].value<std::string>()) er.source = *v;
      er.parts = string_map(et->get("parts"), file, "registration.earlier.parts");
      er.rules = string_map(et->get("rules"), file, "registration.earlier.rules");
      er.says = string_map(et->get("says"), file, "registration.earlier.says");
      r.earlier = std::move(er);
    }
    out.push_back(std::move(r));
  }
  return out;
}

std::string registration_toml(const Registration& r) {
  std::ostringstream out;
  out << "\n[[registration]]\n"
      << "experiment = " << toml_quote(r.experiment) << "\n"
      << "sha256 = " << toml_quote(r.sha256) << "\n"
      << "registered = " << toml_quote(r.registered) << "\n";
  if (!r.note.empty()) out << "note = " << toml_quote(r.note) << "\n";
  if (r.earlier) {
    const EarlierResult& e = *r.earlier;
    out << "[registration.earlier]\n"
        << "verdict = " << toml_quote(e.verdict) << "\n"
        << "source = " << toml_quote(e.source) << "\n";
    auto table = [&](const char* name, const std::map<std::string, std::string>& m) {
      out << "[registration.earlier." << name << "]\n";
      for (const auto& [k, v] : m) out << toml_quote(k) << " = " << toml_quote(v) << "\n";
    };
    table("parts", e.parts);
    table("rules", e.rules);
    table("says", e.says);
  }
  return out.str();
}

RegistrationStatus registration_status(const std::vector<Registration>& registry, const fs::path& registry_file,
                                       const std::string& id, const fs::path& experiment_file,
                                       const std::string& results_commit) {
  RegistrationStatus st;
  st.sha256 = sha256_file(experiment_file);
  for (const Registration& r : registry) {
    if (r.experiment != id) continue;
    st.latest = &r;
    if (r.earlier) st.revisions.push_back(&r);
    st.entries.push_back(&r);
  }
  if (st.latest == nullptr) {
    st.state = RegistrationStatus::State::Unregistered;
    return st;
  }
  st.state = st.latest->sha256 == st.sha256 ? RegistrationStatus::State::Registered
                                           : RegistrationStatus::State::Modified;
  st.results_commit = results_commit;
  std::string commit = results_commit;
  if (const size_t plus = commit.find('+'); plus != std::string::npos) commit.resize(plus);

  // The commit that added the latest entry: the oldest commit that changed the number of times
  // its hash occurs in the registry.
  const fs::path dir = registry_file.parent_path();
  const auto [rc, log] = capture(fmt::format("git -C {} log --format='%H %cI' -S{} -- {}", shell_quote(dir.string()),
                                             shell_quote(st.latest->sha256),
                                             shell_quote(registry_file.filename().string())));
  if (rc != 0) {
    st.why_unchecked = "git or the repository is not available";
    return st;
  }
  std::istringstream lines(log);
  for (std::string line; std::getline(lines, line);) {
    if (line.empty()) continue;
    const size_t space = line.find(' ');
    st.commit = line.substr(0, space);
    st.commit_date = space == std::string::npos ? "" : line.substr(space + 1);
  }
  if (st.commit.empty()) {
    st.why_unchecked = "the registration is not committed yet";
    return st;
  }
  if (commit.empty() || commit == "unknown") {
    st.why_unchecked = "the build does not know its commit";
    return st;
  }
  const auto [arc, unused] = capture(fmt::format("git -C {} merge-base --is-ancestor {} {}", shell_quote(dir.string()),
                                                 st.commit, shell_quote(commit)));
  if (arc == 0) st.before_results = true;
  else if (arc == 1) st.before_results = false;
  else st.why_unchecked = "the build's commit is not in this repository";
  return st;
}

// The results a committed report holds for one experiment: verdict, and each part's verdict, rule
// and words. Empty when the report or the experiment is not there.
std::optional<EarlierResult> earlier_results(const fs::path& json, const std::string& id) {
  std::error_code ec;
  if (!fs::exists(json, ec)) return std::nullopt;
  nlohmann::json report;
  try {
    std::ifstream in(json);
    report = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw ExperimentError(fmt::format("{}: not a report's JSON: {}", json.string(), e.what()));
  }
  for (const nlohmann::json& c : report.value("claims", nlohmann::json::array())) {
    if (c.value("id", "") != id) continue;
    EarlierResult e;
    e.verdict = c.value("verdict", "");
    e.source = fmt::format("{} ({} tier, {})", json.filename().string(), report.value("tier", "?"),
                           report.value("build", "?"));
    for (const nlohmann::json& p : c.value("parts", nlohmann::json::array())) {
      const std::string pid = p.value("id", "");
      e.parts[pid] = p.value("verdict", "");
      e.rules[pid] = p.value("rule", "");
      e.says[pid] = p.value("says", "");
    }
    return e;
  }
  return std::nullopt;
}


int register_experiments(const std::vector<Experiment>& chosen, const fs::path& registry_file,
                         const fs::path& results, const std::string& note, std::ostream& out) {
  const std::vector<Registration> registry = read_registry(registry_file);
  std::string appended;
  int registered = 0;
  for (const Experiment& e : chosen) {
    Registration r;
    r.experiment = e.id;
    r.sha256 = sha256_file(e.file);
    const Registration* latest = nullptr;
    for (const Registration& g : registry)
      if (g.experiment == e.id) latest = &g;
    if (latest != nullptr && latest->sha256 == r.sha256) {
      out << fmt::format("{}: already registered {} (sha256 {})\n", e.id, latest->registered, r.sha256.substr(0, 12));
      continue;
    }
    r.registered = utc_now();
    r.note = note;
    r.earlier = earlier_results(results, e.id);
    if (r.earlier && note.empty())
      throw ExperimentError(fmt::format("{}: {} already has results in {}: registering it now is a revision after "
                                        "results; say why with --note",
                                        e.file.string(), e.id, results.string()));
    appended += registration_toml(r);
    ++registered;
    out << fmt::format("{}: registered (sha256 {}){}\n", e.id, r.sha256.substr(0, 12),
                       r.earlier ? fmt::format(", a revision after results (earlier verdict: {})", r.earlier->verdict)
                                 : std::string());
  }
  if (!appended.empty()) {
    // Appended to pbdbench's own registry only (runfile/output_guard.hpp).
    check_output(registry_file, OutputTarget{"the registry", "registry",
                                             [](const fs::path& p) { return has_marker(p, "# Registrations of experiment files"); },
                                             {}});
    std::error_code ec;
    const bool fresh = !fs::exists(registry_file, ec);
    std::ofstream f(registry_file, std::ios::app);
    if (fresh)
      f << "# Registrations of experiment files (experiments/registry.hpp): each entry records a file's\n"
        << "# SHA-256 before its results. Written by `pbdbench register`; commit it before running the\n"
        << "# experiments. Never edit an entry: register a revision instead.\n";
    f << appended;
    if (!f) throw std::runtime_error("cannot write " + registry_file.string());
    out << fmt::format("{} registered in {}: commit it before running the experiments\n", registered,
                       registry_file.string());
  }
  return registered;
}


}  // namespace pbdbench::experiments
