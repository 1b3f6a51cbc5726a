// experiments/experiment: the catalog of experiments loads, and bad files are refused naming the file,
// the line and the key.
#include <unistd.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "experiments/claim_index.hpp"
#include "experiments/experiment.hpp"

namespace pbdbench::experiments {
namespace {

namespace fs = std::filesystem;

// Claim ids in the order of the article's sections.
const std::vector<std::string> kClaimIds = {
    "S1",   "S2.1a", "S2.1b", "S2.2", "S2.3a", "S2.3b", "S3.1", "S3.1a", "S3.1b", "S3.1c", "S3.2",
    "S3.3", "S3.4",  "S4.1",  "S4.2", "S4.3",  "S4.4",  "S4.5", "S5.1",  "S5.2",  "S5.3",  "S5.4"};

fs::path write(const std::string& id, const std::string& text) {
  const fs::path dir = fs::temp_directory_path() / ("pbdbench_test_experiment_" + std::to_string(::getpid()));  // one folder per test process: sessions sharing /tmp do not collide
  fs::create_directories(dir);
  const fs::path p = dir / (id + ".toml");
  std::ofstream(p) << text;
  return p;
}

const char* kGood = R"toml(id = "S9.9"
section = "9.9"
claim = "a particle falls"
experiment = "a particle falls for 0.1 s"
scenario = "free_fall"
[set]
"time.duration" = 0.1
[quick]
trials = 2
set = { "time.duration" = 0.05 }
[[run]]
name = "pbd"
set = { "solver.name" = "pbd" }
trials = 3
trial_key = "solver.shuffle_seed"
[[measure]]
name = "drop"
run = "pbd"
value = "initial(potential_energy) - final(potential_energy)"
units = "J"
doc = "energy lost"
[[measure]]
name = "twice"
value = "2 * drop"
doc = "twice that"
[[part]]
says = "it falls"
quote = "它会落下"
translation = "it falls"
judges = "method"
rule = "drop > 0"
[[part]]
says = "it flies"
quote = "它会飞"
translation = "it flies"
judges = "method"
regime = "beyond"
untestable = "no wings"
)toml";

std::string error_of(const std::string& text) {
  try {
    load_experiment(write("S9.9", text));
  } catch (const ExperimentError& e) {
    return e.what();
  }
  return "no error";
}

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(Experiment, EveryClaimOfTheIndexHasAnExperimentThatLoadsOrAReason) {
  const fs::path dir = fs::path(PBDBENCH_SOURCE_DIR) / "claims" / "experiments";
  const std::vector<Experiment> all = load_experiments(dir);
  const ClaimIndex index = read_claim_index(claim_index_of(dir));
  EXPECT_NO_THROW(check_coverage(index, all));
  std::vector<std::string> ids;
  for (const Experiment& e : all) ids.push_back(e.id);
  EXPECT_TRUE(std::is_sorted(ids.begin(), ids.end(), claim_id_less));
  for (const std::string& id : kClaimIds) EXPECT_NE(index.find(id), nullptr) << id;
  for (const Experiment& e : all) {
    EXPECT_FALSE(e.parts.empty()) << e.id;
    for (const PartSpec& p : e.parts) {
      EXPECT_FALSE(p.quote.empty()) << e.id << ": " << p.says;
      EXPECT_FALSE(p.translation.empty()) << e.id << ": " << p.says;
      // The quote is the article's, verbatim: found in the index's original text of the claim
      // or of another claim of the same section.
    }
  }
  for (const IndexedClaim& c : index.claims) {
    EXPECT_FALSE(c.original.empty()) << c.id;
    EXPECT_FALSE(c.translation.empty()) << c.id;
  }
}

TEST(Experiment, EveryReproductionLoadsAndSaysWhatItReproduces) {
  const std::vector<Experiment> all = load_experiments(fs::path(PBDBENCH_SOURCE_DIR) / "reproductions" / "experiments");
  EXPECT_GE(all.size(), 6u);
  for (const Experiment& e : all) {
    EXPECT_EQ(e.kind, ExperimentKind::Reproduction) << e.id;
    EXPECT_FALSE(e.paper.empty()) << e.id;
    EXPECT_FALSE(e.setup.empty()) << e.id;
    for (const SetupSpec& s : e.setup) {
      if (s.from == SetupFrom::Paper) EXPECT_FALSE(s.source.empty()) << e.id << ": " << s.what;
      else EXPECT_FALSE(s.why.empty()) << e.id << ": " << s.what;
    }
    for (const PartSpec& p : e.parts) {
      EXPECT_FALSE(p.published.empty()) << e.id << ": " << p.says;
      EXPECT_FALSE(p.source.empty()) << e.id << ": " << p.says;
      if (p.rule) {
        EXPECT_FALSE(p.ours.empty()) << e.id << ": " << p.says;
      }
    }
  }
}

TEST(Experiment, ReadsEveryPart) {
  const Experiment e = load_experiment(write("S9.9", kGood));
  EXPECT_EQ(e.id, "S9.9");
  ASSERT_EQ(e.runs.size(), 1u);
  EXPECT_EQ(e.trials(e.runs[0], Tier::Full), 3);
  EXPECT_EQ(e.trials(e.runs[0], Tier::Quick), 2);
  const auto o = e.overrides(e.runs[0], Tier::Quick, 1);
  ASSERT_EQ(o.size(), 4u);  // [set], the run's set, [quick] set, the trial key
  EXPECT_EQ(o[0].path, "time.duration");
  EXPECT_EQ(o[1].value_text, "\"pbd\"");
  EXPECT_EQ(o[2].value_text, "0.05");
  EXPECT_EQ(o[3].path, "solver.shuffle_seed");
  EXPECT_EQ(o[3].value_text, "2");  // trial_base 1 + trial 1
  ASSERT_EQ(e.measures.size(), 2u);
  EXPECT_TRUE(e.measures[1].run.empty());
  ASSERT_EQ(e.parts.size(), 2u);
  EXPECT_TRUE(e.parts[0].rule.has_value());
  EXPECT_EQ(e.parts[0].quote, "它会落下");
  EXPECT_EQ(e.parts[0].judges, Judges::Method);
  EXPECT_FALSE(e.parts[0].beyond);
  EXPECT_TRUE(e.parts[1].beyond);
  EXPECT_EQ(e.parts[1].untestable, "no wings");
  EXPECT_EQ(e.measures_read(e.parts[0]), std::vector<std::string>{"drop"});
  EXPECT_EQ(e.runs_read(e.measures[1]), std::vector<std::string>{"pbd"});
}

TEST(Experiment, TimingGroupsAndTheirMeasures) {
  const std::string text = replace(kGood, "[[measure]]\nname = \"twice\"", R"toml([[timing]]
name = "cost"
runs = ["pbd"]
repeats = 7
set = { "time.duration" = 0.02 }
[[measure]]
name = "per_step"
timing = "cost"
value = "pbd * 1000"
units = "ms"
doc = "solver time per step"
[[measure]]
name = "twice")toml");
  const Experiment e = load_experiment(write("S9.9", text));
  ASSERT_EQ(e.timings.size(), 1u);
  EXPECT_EQ(e.timings[0].repeats, 7);
  const MeasureSpec* m = e.find_measure("per_step");
  ASSERT_NE(m, nullptr);
  EXPECT_TRUE(e.reads_timing(*m));
  EXPECT_FALSE(e.reads_timing(*e.find_measure("drop")));
  EXPECT_FALSE(e.timing_only(e.runs[0]));  // "drop" reads the run too
  const auto o = e.timing_overrides(e.runs[0], e.timings[0], Tier::Full);
  EXPECT_EQ(o.back().path, "time.duration");
  EXPECT_EQ(o.back().value_text, "0.02");
}

TEST(Experiment, BadFilesAreRefusedNamingFileLineAndKey) {
  struct Case {
    std::string from, to, expected;
  };
  const std::vector<Case> cases = {
      {"claim = ", "claimz = ", "S9.9.toml:3: claimz: unknown key"},
      {"name = \"pbd\"\nset", "name = \"pbd\"\nsett", "run.sett: unknown key (did you mean 'run.set'?)"},
      {"rule = \"drop > 0\"", "rule = \"dorp > 0\"", "part.rule: no measure named 'dorp'"},
      {"value = \"2 * drop\"", "value = \"2 * twice\"", "'twice' is not a measure defined above"},
      {"final(potential_energy)", "final(potential_enrgy)", "no series named 'potential_enrgy'"},
      {"value = \"initial", "value = \"exploded + initial", ""},  // a run scalar is fine
      {"value = \"initial", "value = \"bogus + initial", "'bogus' is not a run scalar"},
      {"rule = \"drop > 0\"", "rule = \"drop >\"", "part.rule: in 'drop >' at column 7"},
      {"\"solver.name\" = \"pbd\"", "\"solver.name\" = \"pdb\"", "run 'pbd' (full tier)"},
      {"trials = 3\ntrial_key = \"solver.shuffle_seed\"", "trials = 3", "has trials but no trial_key"},
      {"untestable = \"no wings\"", "rule = \"drop > 0\"\nuntestable = \"no wings\"", "either a rule or an untestable reason"},
      {"id = \"S9.9\"", "id = \"S9.8\"", "does not match the file name"},
      {"quote = \"它会落下\"\n", "", "part.quote: missing"},
      {"judges = \"method\"\nrule", "judges = \"code\"\nrule", "part.judges: 'code' is not one of listing, method"},
      {"regime = \"beyond\"", "regime = \"far\"", "part.regime: 'far' is not one of article, beyond"},
      {"rule = \"drop > 0\"", "rule = \"drop > 0\"\nrequires = \"drop < 1\"", "part.requires_why: missing"},
      {"rule = \"drop > 0\"", "rule = \"drop > 0\"\npublished = \"1 m\"", "part.published: unknown key"},
      {"value = \"initial(potential_energy) - final(potential_energy)\"", "value = \"mean(wall_step)\"",
       "a wall-clock series"},
      {"value = \"initial(potential_energy) - final(potential_energy)\"", "value = \"wall_time\"",
       "'wall_time' is a wall-clock time"},
      {"[[measure]]\nname = \"twice\"", "[[timing]]\nname = \"t\"\nruns = [\"pbd\"]\nrepeats = 3\n[[measure]]\nname = \"twice\"",
       "timing.repeats: 3 is below the minimum 7"},
      {"[[measure]]\nname = \"twice\"", "[[timing]]\nname = \"t\"\nruns = [\"pdb\"]\n[[measure]]\nname = \"twice\"",
       "timing.runs: no run named 'pdb'"},
      {"[[measure]]\nname = \"twice\"",
       "[[timing]]\nname = \"t\"\nruns = [\"pbd\"]\n[[measure]]\nname = \"c\"\ntiming = \"t\"\nvalue = \"xpbd\"\ndoc = \"d\"\n[[measure]]\nname = \"twice\"",
       "'xpbd' is neither a run of timing group 't'"},
      // One fault, one verdict: a part judging the method may not read the listing unrepaired.
      {"set = { \"solver.name\" = \"pbd\" }", "set = { \"solver.name\" = \"pbd-seed\", \"solver.seed.fixes\" = [\"D1\", \"D3\"] }",
       "judges the method but reads run 'pbd', the listing without the fixes D4, D5, D6, D7, D8, D9"},
      {"set = { \"solver.name\" = \"pbd\" }", "set = { \"solver.name\" = \"pbd-seed\", \"solver.seed.fixes\" = [\"D1\", \"D3\", \"D4\", \"D5\", \"D6\", \"D7\", \"D8\", \"D9\"] }",
       ""},
  };
  for (const Case& c : cases) {
    const std::string err = error_of(replace(kGood, c.from, c.to));
    if (c.expected.empty()) {
      EXPECT_EQ(err, "no error") << c.to;
    } else {
      EXPECT_NE(err.find(c.expected), std::string::npos) << "expected '" << c.expected << "' in: " << err;
      EXPECT_NE(err.find("S9.9.toml:"), std::string::npos) << err;
    }
  }
}

// What crashed or ran without end is refused, naming the file, the line, the key and (for a rule)
// the column.
TEST(Experiment, RulesBeyondTheLimitsAndEndlessCountsAreRefused) {
  const std::string deep = std::string(10000, '(') + "drop" + std::string(10000, ')') + " > 0";
  std::string e = error_of(replace(kGood, "rule = \"drop > 0\"", "rule = \"" + deep + "\""));
  EXPECT_NE(e.find("S9.9.toml:31: part.rule: in '...((((("), std::string::npos) << e.substr(0, 300);
  EXPECT_NE(e.find("at column 10001: the expression is 20008 characters long"), std::string::npos) << e.substr(0, 300);
  std::string chain = "drop > 0";
  for (int k = 0; k < 300; ++k) chain += " and drop > 0";
  e = error_of(replace(kGood, "rule = \"drop > 0\"", "rule = \"" + chain + "\""));
  EXPECT_NE(e.find("S9.9.toml:31: part.rule:"), std::string::npos) << e.substr(0, 300);
  EXPECT_NE(e.find("nested more than 200 levels deep"), std::string::npos) << e.substr(0, 300);
  e = error_of(replace(kGood, "value = \"2 * drop\"", "value = \"0x2 * drop\""));
  EXPECT_NE(e.find("S9.9.toml:24: measure.value: in '0x2 * drop' at column 1: '0x2' is not a number"),
            std::string::npos) << e;
  e = error_of(replace(kGood, "trials = 3\n", "trials = 1000000000\n"));
  EXPECT_NE(e.find("S9.9.toml:14: run.trials: 1000000000 is above the maximum 1000"), std::string::npos) << e;
  e = error_of(replace(kGood, "[quick]\ntrials = 2", "[quick]\ntrials = 1001"));
  EXPECT_NE(e.find("S9.9.toml:9: quick.trials: 1001 is above the maximum 1000"), std::string::npos) << e;
  e = error_of(replace(kGood, "trials = 3\n", "trials = 1e9\n"));
  EXPECT_NE(e.find("S9.9.toml:14: run.trials: must be an integer"), std::string::npos) << e;
  e = error_of(replace(kGood, "[[measure]]\nname = \"twice\"",
                       "[[timing]]\nname = \"t\"\nruns = [\"pbd\"]\nrepeats = 1000000000\n[[measure]]\nname = \"twice\""));
  EXPECT_NE(e.find("timing.repeats: 1000000000 is above the maximum 1000"), std::string::npos) << e;
}

TEST(Experiment, ClaimIdsSortAsTheIndex) {
  EXPECT_TRUE(claim_id_less("S1", "S2.1a"));
  EXPECT_TRUE(claim_id_less("S3.1", "S3.1a"));
  EXPECT_TRUE(claim_id_less("S3.1c", "S3.2"));
  EXPECT_TRUE(claim_id_less("S4.5", "S5.1"));
  EXPECT_FALSE(claim_id_less("S5.4", "S5.4"));
  std::vector<std::string> ids = kClaimIds;
  std::reverse(ids.begin(), ids.end());
  std::sort(ids.begin(), ids.end(), claim_id_less);
  EXPECT_EQ(ids, kClaimIds);
}

}  // namespace
}  // namespace pbdbench::experiments
