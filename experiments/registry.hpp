// Pre-registration you can check. Registering an experiment records, before any result exists,
// the SHA-256 of its file and the time, in the registry beside the experiments folder
// (claims/registry.toml, reproductions/registry.toml); the commit that adds the entry is found in
// git. Committed first and run after, the report can then show for each experiment that its rules,
// thresholds and setup were fixed before its results: the registration's commit is an ancestor of
// the commit of the build that computed them.
//
//   [[registration]]
//   experiment = "S4.3"
//   sha256 = "3f1c..."                 # of the experiment file's bytes
//   registered = "2026-11-24T15:02:11Z"
//   note = "..."                       # why it was (re)registered
//   [registration.earlier]             # a revision after results: what the results were
//   verdict = "contradicted"           # of the experiment, under the version revised
//   source = "paper/claims/claims.json (tier full, commit 781aa0e)"
//   parts = { "S4.3.1" = "contradicted", ... }   # each part's verdict then
//   rules = { "S4.3.1" = "...", ... }            # and its rule then
//
// A file changed after its results is registered again as a revision: the note is required and
// the earlier verdicts are kept, so the report shows the rule as revised with what it said before.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace pbdbench::experiments {

struct EarlierResult {
  std::string verdict;                        // of the experiment
  std::string source;                         // where the results were read
  std::map<std::string, std::string> parts;   // part id -> verdict
  std::map<std::string, std::string> rules;   // part id -> rule text ("" when untestable)
  std::map<std::string, std::string> says;    // part id -> what the part said
};

struct Registration {
  std::string experiment;
  std::string sha256;
  std::string registered;  // UTC, ISO 8601
  std::string note;
  std::optional<EarlierResult> earlier;
  int line = 0;
};

// Reads a registry; a missing file is an empty registry. Throws ExperimentError naming the file
// and line for a malformed one.
std::vector<Registration> read_registry(const std::filesystem::path& registry);

// The TOML of one entry (appended to the registry by `pbdbench register`).
std::string registration_toml(const Registration& registration);

// The registry of a folder of experiments: <folder>/../registry.toml.
std::filesystem::path registry_of(const std::filesystem::path& experiments_dir);

// What the report says of an experiment's registration.
struct RegistrationStatus {
  enum class State {
    Unregistered,  // no entry
    Modified,      // the file's hash is not the latest entry's: changed since it was registered
    Registered,    // the latest entry holds the file's hash
  };
  State state = State::Unregistered;
  std::string sha256;            // of the file now
  const Registration* latest = nullptr;
  std::string commit;            // the commit that added the latest entry ("" when not committed,
                                 // or when git or the repository is not available)
  std::string commit_date;       // its committer date
  std::string results_commit;    // the commit of the build whose results are reported (no +dirty)
  std::optional<bool> before_results;  // the registration commit is an ancestor of (or is) the
                                       // results' commit; nullopt when it cannot be checked
  std::string why_unchecked;           // when before_results is nullopt
  std::vector<const Registration*> revisions;  // entries that revised a version with results
  std::vector<const Registration*> entries;    // every entry of the experiment, oldest first
};

RegistrationStatus registration_status(const std::vector<Registration>& registry,
                                       const std::filesystem::path& registry_file,
                                       const std::string& experiment_id,
                                       const std::filesystem::path& experiment_file,
                                       const std::string& results_commit);

struct Experiment;

// The results a report's JSON (results_json() of experiments/report.hpp) holds for one experiment:
// its verdict and each part's verdict, rule and words; nullopt when the file or the experiment is
// not there. Throws ExperimentError when the file is not a report's JSON.
std::optional<EarlierResult> earlier_results(const std::filesystem::path& json, const std::string& id);

// Registers each experiment whose file's SHA-256 is not the latest registration of its id:
// appends an entry to `registry_file` (creating it). When `results` (a report's JSON) already
// holds results for the experiment, the entry is a revision after results: `note` is required
// (ExperimentError otherwise, before anything is written) and the earlier results are kept in it.
// Prints a line per experiment; returns how many were registered.
int register_experiments(const std::vector<Experiment>& experiments, const std::filesystem::path& registry_file,
                         const std::filesystem::path& results, const std::string& note, std::ostream& out);

}  // namespace pbdbench::experiments
