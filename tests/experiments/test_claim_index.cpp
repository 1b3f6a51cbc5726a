// experiments/claim_index: the index of a source's claims, and its coverage by experiments.
#include <unistd.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "experiments/claim_index.hpp"
#include "experiments/experiment.hpp"

namespace pbdbench::experiments {
namespace {

namespace fs = std::filesystem;

const char* kIndex = R"toml([source]
title = "t"
kind = "an article"
language = "Chinese"
author = "not given"
origin = "unknown"
sha256 = "0000"
[[claim]]
id = "S9.5"
section = "9.5"
claim = "things fall"
original = "落下"
translation = "falls"
[[claim]]
id = "S9.6"
section = "9.6"
claim = "fluids"
original = "流体"
translation = "fluids"
untestable = "no fluids here"
)toml";

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

TEST(ClaimIndex, ReadsTheSourceAndTheClaimsAndChecksCoverage) {
  const fs::path dir = fs::temp_directory_path() / ("pbdbench_test_claim_index_" + std::to_string(::getpid()));  // one folder per test process: sessions sharing /tmp do not collide
  fs::remove_all(dir);
  fs::create_directories(dir / "experiments");
  std::ofstream(dir / "index.toml") << kIndex;
  std::ofstream(dir / "experiments" / "S9.5.toml") << kExperiment;
  const ClaimIndex index = read_claim_index(claim_index_of(dir / "experiments"));
  EXPECT_EQ(index.source.language, "Chinese");
  ASSERT_EQ(index.claims.size(), 2u);
  EXPECT_EQ(index.find("S9.6")->untestable, "no fluids here");
  const std::vector<Experiment> ex = load_experiments(dir / "experiments");
  EXPECT_NO_THROW(check_coverage(index, ex));
  // A claim without an experiment or a reason, and an experiment without a claim, are refused.
  EXPECT_THROW(check_coverage(index, {}), ExperimentError);
  std::string missing_reason = kIndex;
  missing_reason.replace(missing_reason.find("untestable = \"no fluids here\"\n"), 30, "");
  std::ofstream(dir / "index.toml") << missing_reason;
  try {
    check_coverage(read_claim_index(dir / "index.toml"), ex);
    FAIL() << "S9.6 has neither";
  } catch (const ExperimentError& e) {
    EXPECT_NE(std::string(e.what()).find("'S9.6' has neither an experiment"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "index.toml") << std::string(kIndex) + "[[claim]]\nid = \"S9.5\"\nsection = \"9\"\nclaim = \"c\"\n"
                                       "original = \"o\"\ntranslation = \"t\"\n";
  EXPECT_THROW(read_claim_index(dir / "index.toml"), ExperimentError);  // indexed twice
  std::ofstream(dir / "index.toml") << std::string(kIndex) + "bogus = 1\n";
  try {
    read_claim_index(dir / "index.toml");
    FAIL();
  } catch (const ExperimentError& e) {
    EXPECT_NE(std::string(e.what()).find("bogus: unknown key"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pbdbench::experiments
