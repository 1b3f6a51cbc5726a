// Sweep files: expansion into runs, and refusal of bad sweep files with file and line.
#include <unistd.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "core/cancel.hpp"

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

namespace {

fs::path test_dir() { return fs::temp_directory_path() / ("pbdbench_test_sweep_" + std::to_string(::getpid())); }

std::string grid_of(int keys, int values) {
  std::string text = "scenario = \"hanging_chain\"\n[grid]\n";
  for (int k = 0; k < keys; ++k) {
    text += "\"a.k" + std::to_string(k) + "\" = [";
    for (int v = 0; v < values; ++v) text += (v ? ", " : "") + std::to_string(v);
    text += "]\n";
  }
  return text;
}

std::string refusal_of_run(const SweepSpec& spec, const SweepOptions& options) {
  std::ostringstream log;
  try {
    run_sweep(spec, options, log);
  } catch (const config::ConfigError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

// 8^22 runs overflowed size_t to 0 ("0 runs", exit 0); 10^20 ran out of memory after 40 s; 10^6
// took minutes and gigabytes to check. Each is counted first and refused, naming [grid]'s line.
TEST(Sweep, GridsBeyondTheLimitAreCountedAndRefused) {
  struct Case {
    int keys, values;
    std::string says;
  };
  for (const Case& c : {Case{22, 8, "makes 7.379e+19 runs (the values of 22 keys x 1 case)"},
                        Case{20, 10, "makes 1e+20 runs"}, Case{2, 1000, "makes 1e+06 runs (1000 x 1000 values x 1 case)"},
                        Case{2, 317, "makes 1.005e+05 runs (317 x 317 values"}}) {
    const std::string e = error_of(write("big.toml", grid_of(c.keys, c.values)));
    EXPECT_NE(e.find("big.toml:2: "), std::string::npos) << e;
    EXPECT_NE(e.find(c.says), std::string::npos) << e;
    EXPECT_NE(e.find("a sweep makes at most 100000"), std::string::npos) << e;
  }
  // Cases multiply the grid.
  std::string text = grid_of(1, 50000) + "[[case]]\n\"b.x\" = 1\n[[case]]\n\"b.x\" = 2\n[[case]]\n\"b.x\" = 3\n";
  EXPECT_NE(error_of(write("cases.toml", text)).find("makes 1.5e+05 runs (50000 values x 3 cases)"),
            std::string::npos)
      << error_of(write("cases.toml", text));
  // The limit itself is taken.
  const SweepSpec s = load_sweep(write("limit.toml", grid_of(1, static_cast<int>(kMaxSweepRuns))));
  EXPECT_EQ(s.runs.size(), kMaxSweepRuns);
}

TEST(Sweep, TheNameIsOnePlainFolderName) {
  for (const char* name : {"../../../x", "/tmp/x", "a/b", "..", ".hidden", "", "x\\ny"}) {
    const std::string e = error_of(write("named.toml", std::string("scenario = \"hanging_chain\"\nname = \"") + name + "\"\n"));
    EXPECT_NE(e.find("named.toml:2: "), std::string::npos) << name << ": " << e;
    EXPECT_NE(e.find("is not a sweep name"), std::string::npos) << name << ": " << e;
  }
  EXPECT_EQ(load_sweep(write("named.toml", "scenario = \"hanging_chain\"\nname = \"chain-2.b_c\"\n")).name, "chain-2.b_c");
}

// A [grid] key also in a [[case]] made identical runs, with the key twice in index.json.
TEST(Sweep, AKeySweptTwiceIsRefused) {
  std::string e = error_of(write("both.toml", "scenario = \"hanging_chain\"\n[grid]\n\"solver.iterations\" = [1, 2]\n"
                                              "[[case]]\n\"solver.substeps\" = 1\n[[case]]\n\"solver.iterations\" = 3\n"));
  EXPECT_NE(e.find("both.toml:7: 'solver.iterations' is both"), std::string::npos) << e;
  EXPECT_NE(e.find("is both a [grid] key (line 3) and a [[case]] key"), std::string::npos) << e;
  e = error_of(write("twice.toml", "scenario = \"hanging_chain\"\n[grid]\n\"solver.iterations\" = [1, 2]\n"
                                   "[grid.solver]\niterations = [3]\n"));
  EXPECT_NE(e.find("is in [grid] twice"), std::string::npos) << e;
  e = error_of(write("case_twice.toml", "scenario = \"hanging_chain\"\n[[case]]\n\"solver.iterations\" = 1\n"
                                        "solver.iterations = 2\n"));
  EXPECT_NE(e.find("is in this [[case]] twice"), std::string::npos) << e;
}

// --out over another sweep's folder (or a folder of something else) replaced its index.json and
// the logs there: refused, naming the file, before anything is checked or written.
TEST(Sweep, OutOverSomethingElseIsRefused) {
  const SweepSpec spec = load_sweep(write("mine.toml", "name = \"mine\"\nscenario = \"hanging_chain\"\n[set]\n"
                                                       "\"time.duration\" = 0.1\n[grid]\n\"solver.iterations\" = [1, 2]\n"));
  const fs::path out = test_dir() / "foreign_out";
  fs::remove_all(out);
  fs::create_directories(out);
  const std::string foreign = "{\n  \"sweep\": \"theirs\",\n  \"runs\": []\n}\n";
  std::ofstream(out / "index.json") << foreign;
  SweepOptions options;
  options.out_dir = out;
  std::string e = refusal_of_run(spec, options);
  EXPECT_NE(e.find((out / "index.json").string() + ": --out: the index of sweep 'theirs', not of 'mine'"),
            std::string::npos) << e;
  std::ifstream back(out / "index.json");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(back), {}), foreign);
  std::ofstream(out / "index.json") << "{\"experiments\": []}\n";  // not a sweep's
  EXPECT_NE(refusal_of_run(spec, options).find("not the index of a sweep"), std::string::npos);
  // A shard's index and a journal of another sweep count as well.
  fs::remove(out / "index.json");
  std::ofstream(out / "index.jsonl") << "{\"sweep\": \"theirs\"}\n";
  EXPECT_NE(refusal_of_run(spec, options).find("the index of sweep 'theirs'"), std::string::npos);
  fs::remove(out / "index.jsonl");
  // Without an index of this sweep, a log that a run would replace is someone else's.
  std::ofstream(out / "solver.iterations-2.log") << "their notes\n";
  EXPECT_NE(refusal_of_run(spec, options).find("solver.iterations-2.log: --out: a log that no index of sweep 'mine'"),
            std::string::npos) << refusal_of_run(spec, options);
  EXPECT_FALSE(fs::exists(out / "index.jsonl"));
  // --out a file.
  options.out_dir = out / "solver.iterations-2.log";
  EXPECT_NE(refusal_of_run(spec, options).find("not a folder"), std::string::npos);
  fs::remove_all(out);
}

// Ctrl-C while the runs are checked stops the check between two runs: nothing started, nothing
// written, interrupted.
TEST(Sweep, ACancellationStopsTheCheck) {
  const SweepSpec spec = load_sweep(write("cancel.toml", grid_of(0, 0) + "\"solver.iterations\" = [1, 2, 3]\n"));
  SweepOptions options;
  options.out_dir = test_dir() / "cancel_out";
  fs::remove_all(options.out_dir);
  std::ostringstream log;
  request_cancel();
  const SweepResult r = run_sweep(spec, options, log);
  clear_cancel();
  EXPECT_TRUE(r.interrupted);
  EXPECT_FALSE(r.ok());
  EXPECT_NE(log.str().find("interrupted while checking its runs (0 of 3 checked); nothing was started"),
            std::string::npos) << log.str();
  EXPECT_FALSE(fs::exists(options.out_dir));
}
