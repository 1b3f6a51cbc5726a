// experiments/registry and experiments/sha256: the content hash, registering experiments,
// revisions after results that keep the earlier verdicts, and the check against git's history.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include <toml++/toml.h>

#include "experiments/experiment.hpp"
#include "experiments/registry.hpp"
#include "experiments/sha256.hpp"

namespace pbdbench::experiments {
namespace {

namespace fs = std::filesystem;

TEST(Sha256, KnownVectors) {
  // FIPS 180-4 examples and the empty string.
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  // 55, 56 and 64 bytes: the padding's edge cases.
  EXPECT_EQ(sha256_hex(std::string(55, 'a')), "9f4390f8d30c2dd92ec9f095b65e2b9ae9b0a925a5258e241c9f1e910f734318");
  EXPECT_EQ(sha256_hex(std::string(56, 'a')), "b35439a4ac6f0948b6d6f9e3c6af0f5f590ce20f1bde7090ef7970686ec6738a");
  EXPECT_EQ(sha256_hex(std::string(64, 'a')), "ffe054fe7ae0cb6dc65c3af9b61d5209f439851db43d0ba5997337df154668eb");
  EXPECT_EQ(sha256_hex(std::string(1000000, 'a')), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("pbdbench_test_registry_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir / "claims" / "experiments");
  return dir;
}

const char* kExperiment = R"toml(id = "S9.5"
section = "9.5"
experiment = "a particle falls"
scenario = "free_fall"
[[run]]
name = "xpbd"
[[measure]]
name = "drop"
run = "xpbd"
value = "initial(potential_energy) - final(potential_energy)"
doc = "drop"
[[part]]
says = "it falls"
quote = "落下"
translation = "falls"
judges = "method"
rule = "drop > 0"
)toml";

// A report's JSON with results for S9.5 (as results_json() writes it).
const char* kReport = R"json({
  "tier": "full", "machine": "m", "build": "pbdbench 0.1.0 (commit old)", "command": "pbdbench claims",
  "claims": [
    {"id": "S9.5", "section": "9.5", "kind": "claim", "paper": "", "verdict": "contradicted",
     "claim": "x", "figure": {}, "runs": [], "measures": [],
     "parts": [{"id": "S9.5.1", "says": "it rises", "rule": "drop < 0", "verdict": "contradicted"}]}
  ]
})json";

int sh(const std::string& command) { return std::system(command.c_str()); }

TEST(Registry, RegisterThenReviseAfterResultsKeepsTheEarlierVerdicts) {
  const fs::path dir = scratch("revise");
  const fs::path file = dir / "claims" / "experiments" / "S9.5.toml";
  std::ofstream(file) << kExperiment;
  const fs::path registry = registry_of(dir / "claims" / "experiments");
  EXPECT_EQ(registry, dir / "claims" / "registry.toml");
  std::ostringstream out;
  const std::vector<Experiment> ex = {load_experiment(file)};
  // No results yet: a first registration, no note needed.
  EXPECT_EQ(register_experiments(ex, registry, dir / "none.json", "", out), 1);
  std::vector<Registration> reg = read_registry(registry);
  ASSERT_EQ(reg.size(), 1u);
  EXPECT_EQ(reg[0].experiment, "S9.5");
  EXPECT_EQ(reg[0].sha256, sha256_file(file));
  EXPECT_FALSE(reg[0].earlier.has_value());
  // Registering the same content again does nothing.
  EXPECT_EQ(register_experiments(ex, registry, dir / "none.json", "", out), 0);

  // Changed after results exist: a revision, which needs a note and keeps the earlier verdicts.
  std::ofstream(dir / "claims.json") << kReport;
  std::ofstream(file, std::ios::app) << "# revised\n";
  const std::vector<Experiment> revised = {load_experiment(file)};
  EXPECT_THROW(register_experiments(revised, registry, dir / "claims.json", "", out), ExperimentError);
  EXPECT_EQ(read_registry(registry).size(), 1u);  // nothing written
  EXPECT_EQ(register_experiments(revised, registry, dir / "claims.json", "the rule read the wrong sign", out), 1);
  reg = read_registry(registry);
  ASSERT_EQ(reg.size(), 2u);
  ASSERT_TRUE(reg[1].earlier.has_value());
  EXPECT_EQ(reg[1].note, "the rule read the wrong sign");
  EXPECT_EQ(reg[1].earlier->verdict, "contradicted");
  EXPECT_EQ(reg[1].earlier->parts.at("S9.5.1"), "contradicted");
  EXPECT_EQ(reg[1].earlier->rules.at("S9.5.1"), "drop < 0");
  EXPECT_EQ(reg[1].earlier->says.at("S9.5.1"), "it rises");
  EXPECT_NE(reg[1].earlier->source.find("commit old"), std::string::npos);

  // The status: registered, with the revision listed; not committed here (no repository).
  const RegistrationStatus st = registration_status(reg, registry, "S9.5", file, "abc");
  EXPECT_EQ(st.state, RegistrationStatus::State::Registered);
  ASSERT_EQ(st.revisions.size(), 1u);
  EXPECT_FALSE(st.before_results.has_value());
  // Changed again without registering: modified.
  std::ofstream(file, std::ios::app) << "# again\n";
  EXPECT_EQ(registration_status(reg, registry, "S9.5", file, "abc").state, RegistrationStatus::State::Modified);
  EXPECT_EQ(registration_status(reg, registry, "S9.6", file, "abc").state,
            RegistrationStatus::State::Unregistered);
}

TEST(Registry, TheRegistrationCommitMustPrecedeTheResultsCommit) {
  if (sh("git --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "git is not installed";
  const fs::path dir = scratch("git");
  const fs::path file = dir / "claims" / "experiments" / "S9.5.toml";
  std::ofstream(file) << kExperiment;
  const std::string git = "git -C '" + dir.string() + "' -c user.email=t@t -c user.name=t ";
  ASSERT_EQ(sh(git + "init -q && " + git + "add -A && " + git + "commit -qm experiment"), 0);
  const fs::path registry = registry_of(dir / "claims" / "experiments");
  std::ostringstream out;
  register_experiments({load_experiment(file)}, registry, dir / "none.json", "", out);
  auto head = [&] {
    std::string h;
    FILE* p = ::popen((git + "rev-parse HEAD").c_str(), "r");
    char buf[64] = {};
    if (p != nullptr && std::fgets(buf, sizeof buf, p) != nullptr) h = buf;
    if (p != nullptr) ::pclose(p);
    while (!h.empty() && (h.back() == '\n' || h.back() == '\r')) h.pop_back();
    return h;
  };
  const std::string before = head();
  std::vector<Registration> reg = read_registry(registry);
  // Not committed yet: cannot be checked.
  RegistrationStatus st = registration_status(reg, registry, "S9.5", file, before);
  EXPECT_FALSE(st.before_results.has_value());
  EXPECT_EQ(st.why_unchecked, "the registration is not committed yet");
  ASSERT_EQ(sh(git + "add -A && " + git + "commit -qm register"), 0);
  const std::string registered = head();
  // Results from a build of the commit before the registration: the results came first.
  st = registration_status(reg, registry, "S9.5", file, before);
  EXPECT_EQ(st.commit, registered);
  ASSERT_TRUE(st.before_results.has_value());
  EXPECT_FALSE(*st.before_results);
  // Results from a build of the registration's commit (dirty or not) or a later one: after it.
  st = registration_status(reg, registry, "S9.5", file, registered + "+dirty");
  ASSERT_TRUE(st.before_results.has_value());
  EXPECT_TRUE(*st.before_results);
}

TEST(Registry, MalformedRegistriesAreRefusedNamingTheLine) {
  const fs::path dir = scratch("bad");
  const fs::path registry = dir / "registry.toml";
  std::ofstream(registry) << "[[registration]]\nexperiment = \"S1\"\nsha256 = \"abc\"\nregistered = \"now\"\n";
  try {
    read_registry(registry);
    FAIL() << "a short hash was accepted";
  } catch (const ExperimentError& e) {
    EXPECT_NE(std::string(e.what()).find("registry.toml:1: registration.sha256"), std::string::npos) << e.what();
  }
  std::ofstream(registry) << "[[registration]]\nexperiment = \"S1\"\nsha = \"abc\"\n";
  EXPECT_THROW(read_registry(registry), ExperimentError);
  EXPECT_TRUE(read_registry(dir / "missing.toml").empty());
}

// Over both registries: every part whose stored quick verdict is counted (supported,
// contradicted, reproduced, not reproduced) names a counterfactual in its experiment file, and no
// part that is an identity by construction is stored as counted.
TEST(Registry, EveryCountedStoredVerdictHasACounterfactual) {
  for (const fs::path& dir : {experiments_dir(), reproductions_dir()}) {
    const fs::path record = dir.parent_path() / "verdicts_quick.toml";
    ASSERT_TRUE(fs::exists(record)) << record;
    const toml::table stored = toml::parse_file(record.string());
    int counted = 0;
    for (const Experiment& ex : load_experiments(dir, false)) {
      for (size_t k = 0; k < ex.parts.size(); ++k) {
        const std::string id = ex.id + "." + std::to_string(k + 1);
        const std::string verdict = stored[id].value_or(std::string());
        const bool is_counted = verdict == "supported" || verdict == "contradicted" || verdict == "reproduced" ||
                                verdict == "not reproduced";
        if (!is_counted) continue;
        ++counted;
        EXPECT_TRUE(ex.parts[k].counterfactual.has_value())
            << record.string() << ": " << id << " is stored as " << verdict << " but " << ex.file.string()
            << " gives it no [part.counterfactual]";
        EXPECT_TRUE(ex.parts[k].identity.empty()) << id << " is an identity by construction, stored as " << verdict;
      }
    }
    std::cout << record.string() << ": " << counted << " counted verdicts\n";
  }
}

}  // namespace
}  // namespace pbdbench::experiments
