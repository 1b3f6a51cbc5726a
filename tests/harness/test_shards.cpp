// harness/shards: the deal of units to shards, Slurm array lists, and what a run file says
// against its planned configuration.
#include <unistd.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "config/config.hpp"
#include "harness/runner.hpp"
#include "harness/shards.hpp"

namespace fs = std::filesystem;
using namespace pbdbench;

TEST(Shards, EqualUnitsDealInTurn) {
  const std::vector<int> s = deal_units(std::vector<size_t>(7, 1), 3);
  EXPECT_EQ(s, (std::vector<int>{0, 1, 2, 0, 1, 2, 0}));
}

TEST(Shards, LargestUnitFirstToTheLeastLoaded) {
  // Units of 5, 1, 1, 1, 1, 3 runs over 2 shards: 5 -> 0, 3 -> 1, then the ones to the lighter.
  const std::vector<int> s = deal_units({5, 1, 1, 1, 1, 3}, 2);
  EXPECT_EQ(s, (std::vector<int>{0, 1, 1, 0, 1, 1}));
  std::vector<size_t> load(2, 0);
  const std::vector<size_t> sizes = {5, 1, 1, 1, 1, 3};
  for (size_t u = 0; u < sizes.size(); ++u) load[static_cast<size_t>(s[u])] += sizes[u];
  EXPECT_EQ(load, (std::vector<size_t>{6, 6}));
  // More shards than units: the rest are empty; one shard: everything in it.
  EXPECT_EQ(deal_units({2, 1}, 4), (std::vector<int>{0, 1}));
  EXPECT_EQ(deal_units({2, 1, 4}, 1), (std::vector<int>{0, 0, 0}));
  EXPECT_THROW(deal_units({1}, 0), std::invalid_argument);
}

TEST(Shards, ArrayLists) {
  EXPECT_EQ(array_list({0, 1, 2, 5, 7, 8}), "0-2,5,7-8");
  EXPECT_EQ(array_list({3}), "3");
  EXPECT_EQ(array_list({}), "");
}

TEST(Shards, RunStateAgainstThePlannedConfiguration) {
  const fs::path dir = fs::temp_directory_path() / ("pbdbench_test_shards_" + std::to_string(::getpid()));  // one folder per test process: sessions sharing /tmp do not collide
  fs::remove_all(dir);
  fs::create_directories(dir);
  const config::Config cfg = config::load("free_fall", {{"time.duration", "0.05"}});
  const config::Config other = config::load("free_fall", {{"time.duration", "0.1"}});
  const fs::path file = dir / "run.h5";
  EXPECT_EQ(run_state(file, cfg.to_toml()), "missing");
  ASSERT_EQ(run_config(cfg, file).status, RunStatus::Complete);
  EXPECT_EQ(run_state(file, cfg.to_toml()), "current");
  EXPECT_EQ(run_state(file, other.to_toml()), "stale");
  std::ofstream(dir / "junk.h5") << "not hdf5";
  EXPECT_EQ(run_state(dir / "junk.h5", cfg.to_toml()), "unreadable");

  const std::vector<UnfinishedRun> runs = {{2, "S9/a", file, "missing"}, {0, "S9/b", file, "incomplete"},
                                           {2, "S9/c", dir / "junk.h5", "failed"}};
  EXPECT_EQ(shards_of(runs), (std::vector<int>{0, 2}));
  const std::string text = unfinished_report(runs, 3, "NEXT\n");
  EXPECT_NE(text.find("3 runs of 2 shards (of 3, counted from 0: 0/3 to 2/3) are not finished"), std::string::npos)
      << text;
  EXPECT_NE(text.find("shard 0/3: 1 run\n    S9/b: incomplete"), std::string::npos) << text;
  EXPECT_NE(text.find("shard 2/3: 2 runs\n    S9/a: missing"), std::string::npos) << text;
  EXPECT_EQ(text.substr(text.size() - 5), "NEXT\n");
  // A long list is cut at ten runs a shard.
  const std::vector<UnfinishedRun> many(12, UnfinishedRun{0, "S9/x", file, "missing"});
  EXPECT_NE(unfinished_report(many, 1, "").find("    ... and 2 more (index.json"), std::string::npos);
}
