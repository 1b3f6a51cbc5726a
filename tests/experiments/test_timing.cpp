// experiments/timing: the distribution-free interval of the median; the configuration a run is
// timed in.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "experiments/timing.hpp"

namespace pbdbench::experiments {
namespace {

TEST(Timing, MedianIntervalFromOrderStatistics) {
  // n = 9: [x_(2), x_(8)], coverage 1 - 2 (1 + 9) / 512.
  const MedianInterval nine = median_interval({9, 1, 8, 2, 7, 3, 6, 4, 5});
  EXPECT_EQ(nine.median, 5);
  EXPECT_EQ(nine.lo, 2);
  EXPECT_EQ(nine.hi, 8);
  EXPECT_NEAR(nine.coverage, 1.0 - 20.0 / 512.0, 1e-12);
  // n = 7: P(B = 0) = 1/128 <= 0.025 but P(B <= 1) = 8/128 is not: [x_(1), x_(7)].
  const MedianInterval seven = median_interval({3, 1, 2, 7, 5, 4, 6});
  EXPECT_EQ(seven.median, 4);
  EXPECT_EQ(seven.lo, 1);
  EXPECT_EQ(seven.hi, 7);
  EXPECT_NEAR(seven.coverage, 1.0 - 2.0 / 128.0, 1e-12);
  EXPECT_GE(seven.coverage, 0.95);
  // n = 20: k = 6 (P(B <= 5) = 0.0207), [x_(6), x_(15)].
  std::vector<double> twenty;
  for (int i = 20; i >= 1; --i) twenty.push_back(i);
  const MedianInterval t = median_interval(twenty);
  EXPECT_EQ(t.median, 10.5);
  EXPECT_EQ(t.lo, 6);
  EXPECT_EQ(t.hi, 15);
  EXPECT_GE(t.coverage, 0.95);
  EXPECT_LT(t.coverage, 0.97);
  // Too few samples for 95 %: the whole range, with its lower coverage said.
  const MedianInterval five = median_interval({1, 2, 3, 4, 5});
  EXPECT_EQ(five.lo, 1);
  EXPECT_EQ(five.hi, 5);
  EXPECT_NEAR(five.coverage, 1.0 - 2.0 / 32.0, 1e-12);
  EXPECT_TRUE(std::isnan(median_interval({}).median));
}

// pbd and xpbd are timed on one thread unless the experiment sets solver.threads; a solver that
// does not read the option is left without it.
TEST(Timing, PbdAndXpbdAreTimedOnOneThreadUnlessTheExperimentSaysOtherwise) {
  namespace fs = std::filesystem;
  const fs::path root(PBDBENCH_SOURCE_DIR);
  Experiment cloth = load_experiment(root / "reproductions" / "experiments" / "xpbd2016_cloth.toml");
  ASSERT_FALSE(cloth.timings.empty());
  const TimingSpec& cost = cloth.timings.front();
  for (const std::string& name : {std::string("pbd_20"), std::string("xpbd_20")}) {
    const config::Config cfg = timing_config(cloth, *cloth.find_run(name), cost, Tier::Full);
    EXPECT_EQ(cfg.get_int("solver.threads"), 1) << name;
    // The other runs of the experiment keep the default.
    EXPECT_EQ(config::load(cloth.scenario_of(*cloth.find_run(name)), cloth.overrides(*cloth.find_run(name), Tier::Full, 0))
                  .get_int("solver.threads"),
              0)
        << name;
  }
  cloth.set.push_back({"solver.threads", "2"});
  EXPECT_EQ(timing_config(cloth, *cloth.find_run("xpbd_20"), cost, Tier::Full).get_int("solver.threads"), 2);

  const Experiment bowl = load_experiment(root / "claims" / "experiments" / "S5.4.toml");
  ASSERT_FALSE(bowl.timings.empty());
  const config::Config cg = timing_config(bowl, *bowl.find_run("bowl_global_cg"), bowl.timings.front(), Tier::Full);
  EXPECT_EQ(cg.get_string("solver.name"), "global-cg");
  EXPECT_TRUE(cg.at("solver.threads").source.file.empty());  // the default, not set for it
  const config::Config seq = timing_config(bowl, *bowl.find_run("bowl_sequential"), bowl.timings.front(), Tier::Full);
  EXPECT_EQ(seq.get_int("solver.threads"), 1);
}

}  // namespace
}  // namespace pbdbench::experiments
