// experiments/evaluate and experiments/report: a small experiment run end to end, its verdicts, the reuse of
// current run files, the records and the report; what makes a part inconclusive.
#include <gtest/gtest.h>

#include <cmath>
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
quote = "落下"
translation = "falls"
judges = "method"
truth = "the closed form g t^2 / 2"
rule = "abs(fall - 9.81 * 0.25 / 2) < 0.05"
[part.counterfactual]
why = "in 0.7 s it falls 2.4 m, not 1.23 m"
runs = { xpbd = { "time.duration" = 0.7 } }
[[part]]
says = "it falls 10 m"
quote = "落下十米"
translation = "falls ten metres"
judges = "method"
rule = "fall > 10"
[part.counterfactual]
why = "in 1.5 s it falls 11 m"
runs = { xpbd = { "time.duration" = 1.5 } }
[[part]]
says = "unmeasurable"
quote = "无"
translation = "none"
judges = "method"
rule = "not_measured > 0"
[[part]]
says = "why"
quote = "为什么"
translation = "why"
judges = "method"
untestable = "no reason to"
[[part]]
says = "it falls less than 2 m, beyond the regime"
quote = "落下"
translation = "falls"
judges = "method"
regime = "beyond"
rule = "fall < 2"
[part.counterfactual]
why = "in 0.7 s it falls 2.4 m"
runs = { xpbd = { time = { duration = 0.7 } } }
[[part]]
says = "decided only when it fell at all"
quote = "落下"
translation = "falls"
judges = "method"
rule = "fall > 0"
requires = "fall > 100"
requires_why = "the particle must fall more than 100 m"
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
  EXPECT_EQ(r.runs[0].solver, "xpbd");
  ASSERT_EQ(r.measures.size(), 3u);
  EXPECT_EQ(r.measures[0].trials.size(), 3u);
  EXPECT_NEAR(r.measures[0].value, 9.81 * 0.25 / 2, 0.05);
  EXPECT_EQ(r.measures[1].value, 0.0);
  EXPECT_TRUE(std::isnan(r.measures[2].value));
  ASSERT_EQ(r.parts.size(), 6u);
  EXPECT_EQ(r.parts[0].verdict, Verdict::Supported);
  EXPECT_EQ(r.parts[1].verdict, Verdict::Contradicted);
  EXPECT_EQ(r.parts[2].verdict, Verdict::Inconclusive);  // a measure it needs is NaN
  EXPECT_NE(r.parts[2].reason.find("not_measured"), std::string::npos) << r.parts[2].reason;
  // ... because of a 0 / 0 in its expression, which the reason quotes.
  EXPECT_NE(r.parts[2].reason.find("not_measured (not finite: `(fall > 100) / 0` (column 12) is NaN (of 0 / 0))"),
            std::string::npos) << r.parts[2].reason;
  // A rule that divides by zero is inconclusive, not decided by inf > 5.
  PartSpec divides = ex.parts[1];
  divides.rule = Expression("fall / 0 > 5");
  const PartResult by_zero = decide_part(ex, divides, r);
  EXPECT_EQ(by_zero.verdict, Verdict::Inconclusive);
  EXPECT_NE(by_zero.reason.find("the rule's value is not finite: `fall / 0` (column 1) is inf (of 1.2"),
            std::string::npos) << by_zero.reason;
  EXPECT_EQ(r.parts[3].verdict, Verdict::NotTestable);
  EXPECT_EQ(r.parts[3].reason, "no reason to");
  EXPECT_EQ(r.parts[4].verdict, Verdict::Supported);
  EXPECT_TRUE(r.parts[4].beyond);
  EXPECT_EQ(r.parts[5].verdict, Verdict::Inconclusive);  // requires fails
  EXPECT_NE(r.parts[5].reason.find("the particle must fall more than 100 m"), std::string::npos) << r.parts[5].reason;
  ASSERT_EQ(r.parts[0].judged_with.size(), 1u);
  EXPECT_EQ(r.parts[0].judged_with[0], "xpbd (xpbd)");
  // Supported and contradicted among the decided parts in the article's regime: mixed.
  EXPECT_EQ(r.verdict, Verdict::Mixed);
  const PartCounts counts = count_parts({r});
  EXPECT_EQ(counts.article[static_cast<int>(Verdict::Supported)], 1);
  EXPECT_EQ(counts.article[static_cast<int>(Verdict::Contradicted)], 1);
  EXPECT_EQ(counts.article[static_cast<int>(Verdict::Inconclusive)], 2);
  EXPECT_EQ(counts.article[static_cast<int>(Verdict::NotTestable)], 1);
  EXPECT_EQ(counts.beyond[static_cast<int>(Verdict::Supported)], 1);
  EXPECT_EQ(part_counts_line({r}),
            "5 parts in the article's regime: 1 supported, 1 contradicted, 2 inconclusive, 1 not testable; "
            "0 identities and 0 not shown able to fail, shown but not counted; "
            "1 beyond it: 1 supported, 0 contradicted, 0 inconclusive, 0 not testable, 0 identity, "
            "0 not shown able to fail");
  // Each decided part was shown able to fail: its counterfactual gave the other verdict. The
  // variants of parts 1 and 5 are equal, so their runs were made once.
  EXPECT_EQ(r.parts[0].can_fail, CanFail::Shown);
  EXPECT_EQ(r.parts[0].counterfactual_verdict, Verdict::Contradicted);
  EXPECT_EQ(r.parts[1].can_fail, CanFail::Shown);
  EXPECT_EQ(r.parts[1].counterfactual_verdict, Verdict::Supported);
  EXPECT_EQ(r.parts[4].can_fail, CanFail::Shown);
  EXPECT_EQ(r.parts[0].counterfactual_variant, "xpbd: time.duration = 0.7");
  EXPECT_EQ(r.parts[4].counterfactual_variant, "xpbd: time.duration = 0.7");
  EXPECT_NE(r.parts[0].counterfactual_measured.find("fall = 2.4"), std::string::npos) << r.parts[0].counterfactual_measured;
  EXPECT_EQ(r.parts[2].can_fail, CanFail::NotDecided);
  EXPECT_EQ(varied_runs(ex).size(), 2u);
  size_t counterfactual_files = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir / "runs" / "S9.1" / "counterfactual"))
    counterfactual_files += e.path().extension() == ".h5";
  EXPECT_EQ(counterfactual_files, 6u);  // two variants x three trials
  EXPECT_EQ(plan_runs(ex, options).size(), 9u);  // the experiment's three, the variants' six

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

  // The report has the counts first, the row, the words of the article, the rules and the verdicts.
  ReportContext ctx;
  ctx.command = "pbdbench claims";
  const std::string md = report_markdown({r}, ctx);
  EXPECT_NE(md.find("**5 parts in the article's regime: 1 supported"), std::string::npos) << md;
  EXPECT_NE(md.find("| [S9.1](#s91) | things fall | 1 supported, 1 contradicted, 2 inconclusive, 1 not testable, 1 beyond | **mixed** |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("> 落下十米"), std::string::npos);
  EXPECT_NE(md.find("`abs(fall - 9.81 * 0.25 / 2) < 0.05`"), std::string::npos);
  EXPECT_NE(md.find("**not testable**: no reason to"), std::string::npos);
  EXPECT_NE(md.find("beyond the article's regime"), std::string::npos);
  // What a part is judged against is said beside its rule, and only where the file states it.
  EXPECT_EQ(r.parts[0].truth, "the closed form g t^2 / 2");
  EXPECT_NE(md.find("- Judged against: the closed form g t^2 / 2\n"), std::string::npos) << md;
  EXPECT_EQ(md.find("- Judged against: \n"), std::string::npos) << md;
  // A run with warnings (metrics/health.hpp): counted in the runs' table, its first warning
  // under the table (claims and paper reports alike).
  EXPECT_EQ(md.find("Warnings (what a reader would call a failure"), std::string::npos) << md;
  ClaimResult warned = r;
  ASSERT_FALSE(warned.runs.empty());
  ASSERT_FALSE(warned.runs[0].timing_only);
  warned.runs[0].warned = 2;
  warned.runs[0].first_warning = "volume @1 (t = 0.01667 s): tet volume lost 38.2 %";
  const std::string wmd = report_markdown({warned}, ctx);
  EXPECT_NE(wmd.find("| 2 |\n"), std::string::npos) << wmd;
  EXPECT_NE(wmd.find("Warnings (what a reader would call a failure"), std::string::npos) << wmd;
  EXPECT_NE(wmd.find("- " + warned.runs[0].name + ": volume @1 (t = 0.01667 s): tet volume lost 38.2 %"),
            std::string::npos)
      << wmd;
  const std::string js = results_json({r}, ctx, dir);
  EXPECT_NE(js.find("\"truth\": \"the closed form g t^2 / 2\""), std::string::npos) << js;
  EXPECT_NE(js.find("\"runs/S9.1/xpbd-000.h5\""), std::string::npos) << js;
}

// Whether a verdict could have failed: a counterfactual that flips the rule, one that does not
// (an identity), a decided part without one (not shown able to fail, not counted), a part that
// is an identity by construction, and a comparison whose measures agree to round-off.
const char* kCounterfactuals = R"toml(kind = "reproduction"
paper = "nobody 2026"
id = "cf"
section = "1"
claim = "things fall alike"
experiment = "a particle falls for 0.3 s under pbd and under xpbd"
scenario = "free_fall"
[set]
"time.duration" = 0.3
"scene.velocity" = [0.0, 0.0, 0.0]
[[setup]]
what = "fall"
value = "0.3 s"
from = "assumed"
why = "short"
[[run]]
name = "pbd"
set = { "solver.name" = "pbd" }
[[run]]
name = "xpbd"
set = { "solver.name" = "xpbd" }
[[measure]]
name = "fall_pbd"
run = "pbd"
value = "initial(potential_energy) - final(potential_energy)"
doc = "energy released"
[[measure]]
name = "fall_xpbd"
run = "xpbd"
value = "initial(potential_energy) - final(potential_energy)"
doc = "energy released"
[[part]]
says = "it releases less than 10 J"
published = "10 J"
source = "nowhere"
rule = "fall_xpbd < 10"
[part.counterfactual]
why = "in 1 s it releases 48 J"
runs = { xpbd = { "time.duration" = 1.0 } }
[[part]]
says = "it releases energy"
published = "yes"
source = "nowhere"
rule = "fall_xpbd > 0"
[part.counterfactual]
why = "a longer fall still releases energy: this cannot flip"
runs = { xpbd = { "time.duration" = 1.0 } }
[[part]]
says = "it falls at all (no counterfactual)"
published = "yes"
source = "nowhere"
rule = "fall_xpbd > 0"
[[part]]
says = "energy is energy"
published = "yes"
source = "nowhere"
rule = "fall_xpbd == fall_xpbd"
identity = "a number equals itself"
[[part]]
says = "pbd and xpbd release the same energy"
published = "yes"
source = "nowhere"
rule = "abs(fall_pbd - fall_xpbd) < 0.01"
[part.counterfactual]
why = "a pbd particle that falls for 1 s releases more"
runs = { pbd = { "time.duration" = 1.0 } }
)toml";

TEST(Evaluate, ACountedVerdictNeedsACounterfactualThatFlipsIt) {
  const fs::path dir = scratch("counterfactuals");
  std::ofstream(dir / "cf.toml") << kCounterfactuals;
  const Experiment ex = load_experiment(dir / "cf.toml");
  EvaluateOptions options;
  options.runs_dir = dir / "runs";
  const ClaimResult r = evaluate_claim(ex, options);
  ASSERT_EQ(r.parts.size(), 5u);
  // Flipped: counted.
  EXPECT_EQ(r.parts[0].verdict, Verdict::Supported) << r.parts[0].reason;
  EXPECT_EQ(r.parts[0].can_fail, CanFail::Shown);
  EXPECT_EQ(r.parts[0].counterfactual_verdict, Verdict::Contradicted);
  // Not flipped: an identity, with the reason, not counted.
  EXPECT_EQ(r.parts[1].measured, Verdict::Supported);
  EXPECT_EQ(r.parts[1].verdict, Verdict::Identity);
  EXPECT_EQ(r.parts[1].can_fail, CanFail::NotFlipped);
  EXPECT_NE(r.parts[1].reason.find("leaves the rule holding"), std::string::npos) << r.parts[1].reason;
  // No counterfactual: not shown able to fail, not counted.
  EXPECT_EQ(r.parts[2].measured, Verdict::Supported);
  EXPECT_EQ(r.parts[2].verdict, Verdict::NotShown);
  EXPECT_EQ(r.parts[2].can_fail, CanFail::NoCounterfactual);
  // Declared an identity.
  EXPECT_EQ(r.parts[3].verdict, Verdict::Identity);
  EXPECT_EQ(r.parts[3].can_fail, CanFail::ByConstruction);
  // Flipped, but the two runs it compares agree to round-off (no constraint: the same fall).
  EXPECT_EQ(r.parts[4].counterfactual_verdict, Verdict::Contradicted);
  EXPECT_EQ(r.parts[4].verdict, Verdict::Identity) << r.parts[4].reason;
  EXPECT_EQ(r.parts[4].can_fail, CanFail::NoVariation);
  EXPECT_NE(r.parts[4].reason.find("do not vary beyond round-off"), std::string::npos) << r.parts[4].reason;
  // One variant of xpbd shared by parts 1 and 2, one of pbd.
  EXPECT_EQ(varied_runs(ex).size(), 2u);
  const PartCounts counts = count_parts({r});
  EXPECT_EQ(counts.decided(), 1);
  EXPECT_EQ(counts.article[static_cast<int>(Verdict::Identity)], 3);
  EXPECT_EQ(counts.article[static_cast<int>(Verdict::NotShown)], 1);
  EXPECT_EQ(part_counts_line({r}),
            "5 published results, counted by part: 1 reproduced, 0 not reproduced, 0 inconclusive, 0 setup unknown, "
            "0 not testable; 3 identities and 1 not shown able to fail, shown but not counted");
  // Both reports show them: the column, the section, the JSON.
  ReportContext ctx;
  ctx.command = "pbdbench paper";
  const std::string md = report_markdown({r}, ctx);
  EXPECT_NE(md.find("## Identities and parts not shown able to fail"), std::string::npos) << md;
  EXPECT_NE(md.find("| could fail |"), std::string::npos) << md;
  EXPECT_NE(md.find("yes (counterfactual: not reproduced)"), std::string::npos) << md;
  EXPECT_NE(md.find("| [cf.3](#cf) | it falls at all (no counterfactual) | `fall_xpbd > 0` | not shown able to fail |"),
            std::string::npos) << md;
  const std::string js = results_json({r}, ctx, dir);
  EXPECT_NE(js.find("\"can_fail\": \"yes\""), std::string::npos) << js;
  EXPECT_NE(js.find("\"counterfactual\": {\"why\": \"in 1 s it releases 48 J\""), std::string::npos) << js;
  // The claims' report has the section too.
  ClaimResult as_claim = r;
  as_claim.kind = ExperimentKind::Claim;
  EXPECT_NE(report_markdown({as_claim}, ctx).find("## Identities and parts not shown able to fail"), std::string::npos);
}

// A run that explodes: the listing to the letter tears a cloth within a few steps (D3).
const char* kExplodes = R"toml(id = "S9.2"
section = "9.2"
experiment = "the listing on a cloth"
scenario = "hanging_cloth"
[set]
"time.duration" = 0.2
"scene.resolution" = [8, 8]
[[run]]
name = "letter"
set = { "solver.name" = "pbd-seed" }
[[measure]]
name = "stretch"
run = "letter"
value = "max(constraint_error_max)"
doc = "largest link error"
[[measure]]
name = "exploded_letter"
run = "letter"
value = "exploded"
doc = "1 when it exploded"
[[part]]
says = "reads the exploded run without accounting for it"
quote = "一"
translation = "one"
judges = "listing"
rule = "stretch < 0.1"
[[part]]
says = "accounts for the explosion"
quote = "二"
translation = "two"
judges = "listing"
rule = "exploded_letter == 1 or stretch < 0.1"
)toml";

TEST(Evaluate, AnExplosionThePartDoesNotAccountForMakesItInconclusive) {
  const fs::path dir = scratch("explodes");
  std::ofstream(dir / "S9.2.toml") << kExplodes;
  const Experiment ex = load_experiment(dir / "S9.2.toml");
  EvaluateOptions options;
  options.runs_dir = dir / "runs";
  const ClaimResult r = evaluate_claim(ex, options);
  ASSERT_EQ(r.runs[0].exploded, 1) << "the listing to the letter was expected to explode here";
  EXPECT_EQ(r.parts[0].verdict, Verdict::Inconclusive);
  EXPECT_NE(r.parts[0].reason.find("run letter exploded"), std::string::npos) << r.parts[0].reason;
  // Decided on the runs, but with no counterfactual it is not counted.
  EXPECT_EQ(r.parts[1].measured, Verdict::Supported);
  EXPECT_EQ(r.parts[1].verdict, Verdict::NotShown);
  EXPECT_EQ(r.verdict, Verdict::Inconclusive);
  EXPECT_EQ(r.parts[1].judged_with[0], "letter (pbd-seed, the listing to the letter)");
}

// Timing: a group of two runs; a rule far from the interval is decided, one inside it is not.
const char* kTimed = R"toml(id = "S9.3"
section = "9.3"
experiment = "costs"
scenario = "free_fall"
[set]
"time.duration" = 0.05
[[run]]
name = "light"
set = { "solver.name" = "xpbd", "solver.iterations" = 1 }
[[run]]
name = "heavy"
scenario = "hanging_cloth"
set = { "solver.name" = "xpbd", "solver.iterations" = 40, "scene.resolution" = [24, 24] }
[[timing]]
name = "cost"
runs = ["light", "heavy"]
repeats = 7
[[measure]]
name = "ratio"
timing = "cost"
value = "heavy / light"
doc = "cost ratio"
[[measure]]
name = "ratio_2"
value = "2 * ratio"
doc = "twice"
[[part]]
says = "the cloth costs more"
quote = "一"
translation = "one"
judges = "method"
rule = "ratio_2 > 2"
)toml";

TEST(Evaluate, TimingGroupsGiveMediansWithIntervalsAndRulesReadThem) {
  const fs::path dir = scratch("timed");
  std::ofstream(dir / "S9.3.toml") << kTimed;
  const Experiment ex = load_experiment(dir / "S9.3.toml");
  EXPECT_TRUE(ex.timing_only(ex.runs[0]));
  EvaluateOptions options;
  options.runs_dir = dir / "runs";
  const ClaimResult r = evaluate_claim(ex, options);
  EXPECT_TRUE(r.runs[0].files.empty());  // timed only: no accuracy run made
  ASSERT_EQ(r.timings.size(), 1u);
  // Three sessions of 7 repeats (here in this process: no executable to start them apart).
  ASSERT_EQ(r.timings[0].seconds_per_step.size(), 21u);
  EXPECT_EQ(r.timings[0].sessions.size(), 3u);
  EXPECT_EQ(r.timings[0].processes, 1);
  const MeasureResult& ratio = r.measures[0];
  EXPECT_TRUE(ratio.interval);
  EXPECT_EQ(ratio.trials.size(), 21u);
  // The interval holds every session's interval of the median.
  for (int k = 0; k < 3; ++k) {
    std::vector<double> mine;
    for (size_t i = 0; i < ratio.trials.size(); ++i)
      if (r.timings[0].session[i] == k) mine.push_back(ratio.trials[i]);
    ASSERT_EQ(mine.size(), 7u);
    const MedianInterval one = median_interval(mine);
    EXPECT_LE(ratio.lo, one.lo);
    EXPECT_GE(ratio.hi, one.hi);
  }
  EXPECT_LE(ratio.lo, ratio.value);
  EXPECT_LE(ratio.value, ratio.hi);
  // The least coverage: that of all 21 repeats' interval, or a session's (n = 7: [min, max]).
  EXPECT_NEAR(ratio.coverage, std::min(median_interval(ratio.trials).coverage, 1.0 - 2.0 / 128.0), 1e-12);
  EXPECT_TRUE(r.measures[1].interval);
  EXPECT_DOUBLE_EQ(r.measures[1].lo, 2 * ratio.lo);
  EXPECT_DOUBLE_EQ(r.measures[1].hi, 2 * ratio.hi);
  // Timed in one process: a timing verdict needs three.
  EXPECT_EQ(r.parts[0].verdict, Verdict::Inconclusive) << r.parts[0].reason;
  EXPECT_NE(r.parts[0].reason.find("timing group cost was timed in 1 separate process; a timing verdict needs 3"),
            std::string::npos) << r.parts[0].reason;
  EXPECT_TRUE(r.parts[0].timing);
  // The record is read back the second time.
  const ClaimResult again = evaluate_claim(ex, options);
  EXPECT_TRUE(again.timings[0].reused);
  EXPECT_EQ(again.measures[0].value, ratio.value);

  // Timed in three processes, the part is decided; without a counterfactual it is not counted.
  ClaimResult measured = r;
  measured.timings[0].processes = 3;
  PartResult three = decide_part(ex, ex.parts[0], measured);
  EXPECT_EQ(three.verdict, Verdict::Supported) << three.reason;
  check_can_fail(ex, ex.parts[0], measured, nullptr, three);
  EXPECT_EQ(three.verdict, Verdict::NotShown);
  // A threshold inside the interval leaves the part inconclusive (decided from the same numbers).
  measured.measures[1].lo = 3.0;
  measured.measures[1].value = 4.0;
  measured.measures[1].hi = 5.0;
  PartSpec straddles = ex.parts[0];
  straddles.rule = Expression("ratio_2 > 4.5");
  const PartResult p = decide_part(ex, straddles, measured);
  EXPECT_EQ(p.verdict, Verdict::Inconclusive);
  EXPECT_NE(p.reason.find("straddles the threshold: ratio_2 in [3, 5]"), std::string::npos) << p.reason;
  straddles.rule = Expression("ratio_2 > 2.5");
  EXPECT_EQ(decide_part(ex, straddles, measured).verdict, Verdict::Supported);
  straddles.rule = Expression("ratio_2 > 5.5");
  EXPECT_EQ(decide_part(ex, straddles, measured).verdict, Verdict::Contradicted);
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
  EXPECT_EQ(combine_verdicts(parts({Verdict::Supported, Verdict::Contradicted})), Verdict::Mixed);
  EXPECT_EQ(combine_verdicts(parts({Verdict::Contradicted, Verdict::Inconclusive})), Verdict::Contradicted);
  EXPECT_EQ(combine_verdicts(parts({Verdict::Inconclusive, Verdict::NotTestable})), Verdict::Inconclusive);
  EXPECT_EQ(combine_verdicts(parts({Verdict::NotTestable})), Verdict::NotTestable);
  EXPECT_EQ(combine_verdicts(parts({Verdict::Identity, Verdict::SetupUnknown})), Verdict::SetupUnknown);
  std::vector<PartResult> beyond = parts({Verdict::Supported, Verdict::Contradicted});
  beyond[1].beyond = true;  // beyond the regime: not in the verdict
  EXPECT_EQ(combine_verdicts(beyond), Verdict::Supported);
  Verdict v;
  EXPECT_TRUE(parse_verdict("not testable", v));
  EXPECT_EQ(v, Verdict::NotTestable);
  EXPECT_TRUE(parse_verdict("not reproduced", v));
  EXPECT_EQ(v, Verdict::Contradicted);
  EXPECT_TRUE(parse_verdict("inconclusive", v));
  EXPECT_FALSE(parse_verdict("maybe", v));
  EXPECT_STREQ(verdict_word(Verdict::Supported, ExperimentKind::Reproduction), "reproduced");
  EXPECT_STREQ(verdict_word(Verdict::Contradicted, ExperimentKind::Reproduction), "not reproduced");
  EXPECT_STREQ(verdict_word(Verdict::Contradicted, ExperimentKind::Claim), "contradicted");
  EXPECT_STREQ(verdict_word(Verdict::SetupUnknown, ExperimentKind::Reproduction), "setup unknown");
}

}  // namespace
}  // namespace pbdbench::experiments
