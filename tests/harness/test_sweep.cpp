// Sweep files: expansion into runs, and refusal of bad sweep files with file and line.
#include <unistd.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "harness/sweep.hpp"

namespace fs = std::filesystem;
using namespace pbdbench;

namespace {

fs::path write(const std::string& name, const std::string& text) {
  const fs::path dir = fs::temp_directory_path() / ("pbdbench_test_sweep_" + std::to_string(::getpid()));  // one folder per test process: sessions sharing /tmp do not collide
  fs::create_directories(dir);
  const fs::path p = dir / name;
  std::ofstream(p) << text;
  return p;
}

std::string error_of(const fs::path& p) {
  try {
    load_sweep(p);
  } catch (const config::ConfigError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Sweep, GridTimesCasesInFileOrder) {
  const fs::path p = write("grid.toml", R"(
name = "g"
scenario = "hanging_chain"
[set]
"time.duration" = 0.5
[grid]
"solver.name" = ["pbd", "xpbd"]
"solver.iterations" = [1, 4, 16]
[[case]]
"solver.substeps" = 1
[[case]]
"solver.substeps" = 2
)");
  const SweepSpec s = load_sweep(p);
  EXPECT_EQ(s.name, "g");
  ASSERT_EQ(s.runs.size(), 12u);
  EXPECT_EQ(s.parameters, (std::vector<std::string>{"solver.name", "solver.iterations", "solver.substeps"}));
  // The first grid axis is outermost, cases innermost.
  EXPECT_EQ(s.runs[0].params[0].second, "\"pbd\"");
  EXPECT_EQ(s.runs[0].params[1].second, "1");
  EXPECT_EQ(s.runs[0].params[2].second, "1");
  EXPECT_EQ(s.runs[1].params[2].second, "2");
  EXPECT_EQ(s.runs[2].params[1].second, "4");
  EXPECT_EQ(s.runs[6].params[0].second, "\"xpbd\"");
  // [set] comes first, then the run's own parameters.
  EXPECT_EQ(s.runs[0].overrides.front().path, "time.duration");
  EXPECT_EQ(s.runs[0].overrides.front().value_text, "0.5");
  EXPECT_EQ(s.runs[0].stem, "solver.name-pbd__solver.iterations-1__solver.substeps-1");
  EXPECT_TRUE(fs::path(s.scenario).is_absolute() || fs::exists(s.scenario));
}

TEST(Sweep, NestedTablesAreDottedPaths) {
  const fs::path p = write("nested.toml", R"(
scenario = "hanging_chain"
[grid.solver]
iterations = [2, 3]
)");
  const SweepSpec s = load_sweep(p);
  ASSERT_EQ(s.runs.size(), 2u);
  EXPECT_EQ(s.parameters, std::vector<std::string>{"solver.iterations"});
  EXPECT_EQ(s.name, "nested");  // the file stem when no name is given
}

TEST(Sweep, FloatsKeepFullPrecision) {
  const fs::path p = write("floats.toml", R"(
scenario = "hanging_chain"
[grid]
"time.dt" = [0.016666666666666666, 1e-3, 2.0]
)");
  const SweepSpec s = load_sweep(p);
  EXPECT_EQ(s.runs[0].params[0].second, "0.016666666666666666");
  EXPECT_EQ(s.runs[1].params[0].second, "0.001");
  EXPECT_EQ(s.runs[2].params[0].second, "2.0");
}

TEST(Sweep, BadSweepFilesAreRefusedWithFileAndLine) {
  std::string e = error_of(write("unknown.toml", "scenario = \"hanging_chain\"\nsweeep = 1\n"));
  EXPECT_NE(e.find("unknown.toml:2"), std::string::npos) << e;
  EXPECT_NE(e.find("sweeep"), std::string::npos) << e;

  e = error_of(write("notarray.toml", "scenario = \"hanging_chain\"\n[grid]\n\"solver.iterations\" = 3\n"));
  EXPECT_NE(e.find("notarray.toml:3"), std::string::npos) << e;
  EXPECT_NE(e.find("solver.iterations"), std::string::npos) << e;

  e = error_of(write("noscenario.toml", "[grid]\n\"solver.iterations\" = [3]\n"));
  EXPECT_NE(e.find("scenario"), std::string::npos) << e;

  e = error_of(write("missing.toml", "scenario = \"no_such_scenario\"\n"));
  EXPECT_NE(e.find("no_such_scenario"), std::string::npos) << e;

  e = error_of(write("dup.toml", "scenario = \"hanging_chain\"\n[grid]\n\"solver.iterations\" = [3, 3]\n"));
  EXPECT_NE(e.find("same parameters"), std::string::npos) << e;

  e = error_of(write("syntax.toml", "scenario = \"hanging_chain\"\n[grid\n"));
  EXPECT_NE(e.find("syntax.toml:2"), std::string::npos) << e;

  e = error_of(fs::temp_directory_path() / "pbdbench_test_sweep" / "does_not_exist.toml");
  EXPECT_NE(e.find("does_not_exist.toml"), std::string::npos) << e;
}
