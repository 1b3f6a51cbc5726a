// experiments/evaluate and experiments/report: a small experiment run end to end, its verdicts, the reuse of
// current run files, the records and the report.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "experiments/evaluate.hpp"
#include "experiments/report.hpp"

namespace pbdbench::experiments {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("pbdbench_test_evaluate_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A particle in free fall for 0.5 s (closed form: it falls g t^2 / 2 = 1.226 m), three trials.
const char* kFall = R"toml(id = "S9.1"
section = "9.1"
claim = "things fall"
experiment = "a particle falls for 0.5 s"
scenario = "free_fall"
[set]
"time.duration" = 0.5
"scene.velocity" = [0.0, 0.0, 0.0]
[[run]]
name = "xpbd"
trials = 3
trial_key = "solver.shuffle_seed"
[[measure]]
name = "fall"
run = "xpbd"
units = "m"
value = "(initial(potential_energy) - final(potential_energy)) / 9.81"
doc = "distance fallen"
[[measure]]
name = "exploded_any"
run = "xpbd"
value = "exploded"
over_trials = "max"
doc = "1 when a trial exploded"
[[measure]]
name = "not_measured"
value = "fall * 0 + (fall > 100) / 0 * 0"
doc = "NaN on purpose (0 * inf)"
[[part]]
says = "it falls g t^2/2"
rule = "abs(fall - 9.81 * 0.25 / 2) < 0.05"
[[part]]
says = "it falls 10 m"
rule = "fall > 10"
[[part]]
says = "unmeasurable"
rule = "not_measured > 0"
[[part]]
says = "why"
untestable = "no reason to"
)toml";

TEST(Evaluate, RunsMeasuresAndDecides) {
  const fs::path dir = scratch("run");
  std::ofstream(dir / "S9.1.toml") << kFall;
  const Experiment ex = load_experiment(dir / "S9.1.toml");
  EvaluateOptions options;
  options.runs_dir = dir / "runs";
  const ClaimResult r = evaluate_claim(ex, options);
  ASSERT_EQ(r.runs.size(), 1u);
  EXPECT_EQ(r.runs[0].complete, 3);
  EXPECT_EQ(r.runs[0].reused, 0);
  ASSERT_EQ(r.measures.size(), 3u);
  EXPECT_EQ(r.measures[0].trials.size(), 3u);
  EXPECT_NEAR(r.measures[0].value, 9.81 * 0.25 / 2, 0.05);
  EXPECT_EQ(r.measures[1].value, 0.0);
  EXPECT_TRUE(std::isnan(r.measures[2].value));
  ASSERT_EQ(r.parts.size(), 4u);
  EXPECT_EQ(r.parts[0].verdict, Verdict::Supported);
  EXPECT_EQ(r.parts[1].verdict, Verdict::Contradicted);
  EXPECT_EQ(r.parts[2].verdict, Verdict::NotTestable);
  EXPECT_NE(r.parts[2].reason.find("not_measured"), std::string::npos) << r.parts[2].reason;
  EXPECT_EQ(r.parts[3].verdict, Verdict::NotTestable);
  EXPECT_EQ(r.parts[3].reason, "no reason to");
  EXPECT_EQ(r.verdict, Verdict::Contradicted);

  // The second time, the run files are current and read instead of run; the numbers are equal.
  const ClaimResult again = evaluate_claim(ex, options);
  EXPECT_EQ(again.runs[0].reused, 3);
  EXPECT_EQ(again.measures[0].value, r.measures[0].value);

  // Records: the same verdicts agree; a changed one is reported with its part.
  const std::string record = verdicts_toml({r}, Tier::Full);
  std::ofstream(dir / "verdicts.toml") << record;
  EXPECT_TRUE(verdict_differences({r}, dir / "verdicts.toml").empty());
  std::string changed = record;
  const std::string was = "\"S9.1.1\" = \"supported\"";
  changed.replace(changed.find(was), was.size(), "\"S9.1.1\" = \"contradicted\"");
  std::ofstream(dir / "changed.toml") << changed;
  const std::vector<std::string> diff = verdict_differences({r}, dir / "changed.toml");
  ASSERT_EQ(diff.size(), 1u);
  EXPECT_NE(diff[0].find("S9.1.1: recorded contradicted, now supported"), std::string::npos) << diff[0];

  // The report has the row, the rule and the verdicts.
  ReportContext ctx;
  ctx.command = "pbdbench claims";
  const std::string md = report_markdown({r}, ctx);
  EXPECT_NE(md.find("| [S9.1](#s91) | things fall |"), std::string::npos) << md;
  EXPECT_NE(md.find("`abs(fall - 9.81 * 0.25 / 2) < 0.05`"), std::string::npos);
  EXPECT_NE(md.find("**contradicted**"), std::string::npos);
  EXPECT_NE(md.find("not testable: no reason to"), std::string::npos);
  const std::string js = results_json({r}, ctx, dir);
  EXPECT_NE(js.find("\"runs/S9.1/xpbd-000.h5\""), std::string::npos) << js;
}

TEST(Evaluate, CombinesPartVerdicts) {
  auto parts = [](std::initializer_list<Verdict> vs) {
    std::vector<PartResult> out;
    for (Verdict v : vs) {
      PartResult p;
      p.verdict = v;
      out.push_back(p);
    }
    return out;
  };
  EXPECT_EQ(combine_verdicts(parts({Verdict::Supported, Verdict::NotTestable})), Verdict::Supported);
  EXPECT_EQ(combine_verdicts(parts({Verdict::Supported, Verdict::Contradicted})), Verdict::Contradicted);
  EXPECT_EQ(combine_verdicts(parts({Verdict::NotTestable})), Verdict::NotTestable);
  Verdict v;
  EXPECT_TRUE(parse_verdict("not testable", v));
  EXPECT_EQ(v, Verdict::NotTestable);
  EXPECT_FALSE(parse_verdict("maybe", v));
  EXPECT_STREQ(verdict_word(Verdict::Supported, ExperimentKind::Reproduction), "reproduced");
  EXPECT_STREQ(verdict_word(Verdict::Contradicted, ExperimentKind::Reproduction), "not reproduced");
  EXPECT_STREQ(verdict_word(Verdict::Contradicted, ExperimentKind::Claim), "contradicted");
}

// Shards keep timed comparisons in one task: every run a timing part reads (through derived
// measures) shares one group; every other trial is a group of its own.
TEST(Evaluate, PlanGroupsTheRunsATimingPartCompares) {
  const fs::path dir = scratch("groups");
  std::ofstream(dir / "S9.5.toml") << R"toml(id = "S9.5"
section = "9.5"
claim = "more iterations cost more"
experiment = "two timed runs, one untimed run with trials"
scenario = "free_fall"
[set]
"time.duration" = 0.1
[[run]]
name = "few"
set = { "solver.iterations" = 1 }
[[run]]
name = "other"
trials = 3
trial_key = "solver.shuffle_seed"
[[run]]
name = "many"
set = { "solver.iterations" = 50 }
[[measure]]
name = "time_few"
run = "few"
value = "mean(wall_step)"
doc = "time_few"
[[measure]]
name = "time_many"
run = "many"
value = "mean(wall_step)"
doc = "time_many"
[[measure]]
name = "fall"
run = "other"
value = "final(height_min)"
doc = "fall"
[[measure]]
name = "cost"
value = "time_many / time_few"
doc = "cost"
[[part]]
says = "many iterations cost more"
rule = "cost > 1"
timing = true
[[part]]
says = "it falls"
rule = "fall < 1"
)toml";
  const Experiment ex = load_experiment(dir / "S9.5.toml");
  EXPECT_EQ(timed_runs(ex), (std::vector<std::string>{"few", "many"}));
  EvaluateOptions options;
  options.runs_dir = dir / "runs";
  const std::vector<PlannedRun> plan = plan_runs(ex, options);
  ASSERT_EQ(plan.size(), 5u);  // few, other x 3, many
  EXPECT_EQ(plan[0].run, "few");
  EXPECT_EQ(plan[4].run, "many");
  EXPECT_EQ(plan[0].group, plan[4].group);
  for (size_t k = 1; k <= 3; ++k) {
    EXPECT_NE(plan[k].group, plan[0].group);
    for (size_t j = 1; j < k; ++j) EXPECT_NE(plan[k].group, plan[j].group);
  }
  EXPECT_FALSE(plan[0].config_toml.empty());
}

}  // namespace
}  // namespace pbdbench::experiments
