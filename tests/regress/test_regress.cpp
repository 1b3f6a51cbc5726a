// regress/: the tolerance rule, the registry, and the demonstration the issue asks for: broken
// solver variants (defined here, never shipped) are each caught by the regression, the metric
// named.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "catalog/solver_catalog.hpp"
#include "core/constraint_functions.hpp"
#include "regress/regress.hpp"
#include "solver_api/solver.hpp"
#include "tests/temp_dir.hpp"

namespace pbdbench::regress {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Each test's files in a folder of its own (unique to the process, removed after the test).
using TempDir = pbdbench::testing::TempDir;

MetricSpec metric(Worse worse, double rel, double abs) {
  MetricSpec m;
  m.name = "m";
  m.worse = worse;
  m.rel = rel;
  m.abs = abs;
  return m;
}

TEST(Regress, ToleranceAndDirection) {
  const CaseSpec c;
  const MetricSpec higher = metric(Worse::Higher, 0.01, 1e-6);
  EXPECT_EQ(compare_value(higher, c, 1.0, 1.0).verdict, Verdict::Same);
  EXPECT_EQ(compare_value(higher, c, 1.0, 1.0 + 0.0099).verdict, Verdict::Same);  // within rel
  EXPECT_EQ(compare_value(higher, c, 1.0, 1.02).verdict, Verdict::Worse);
  EXPECT_EQ(compare_value(higher, c, 1.0, 0.98).verdict, Verdict::Better);
  EXPECT_EQ(compare_value(higher, c, 0.0, 5e-7).verdict, Verdict::Same);  // within abs
  EXPECT_EQ(compare_value(metric(Worse::Lower, 0.01, 0.0), c, 1.0, 0.98).verdict, Verdict::Worse);
  EXPECT_EQ(compare_value(metric(Worse::Either, 0.01, 0.0), c, 1.0, 0.98).verdict, Verdict::Worse);
  EXPECT_EQ(compare_value(higher, c, kNaN, kNaN).verdict, Verdict::Same);
  EXPECT_EQ(compare_value(higher, c, 1.0, kNaN).verdict, Verdict::Worse);  // a run that turned NaN
  EXPECT_EQ(compare_value(higher, c, kNaN, 1.0).verdict, Verdict::Worse);
  const Row r = compare_value(higher, c, 2.0, 2.5);
  EXPECT_DOUBLE_EQ(r.change, 0.5);
  EXPECT_DOUBLE_EQ(r.allowed, 1e-6 + 0.02);
  MetricSpec timing = higher;
  timing.timing = true;
  const Row t = compare_value(timing, c, 2.0, 3.0);
  EXPECT_EQ(t.verdict, Verdict::Ratio);  // never a verdict
  EXPECT_DOUBLE_EQ(t.change, 1.5);
  CaseSpec loose;
  loose.tolerance["m"] = {0.5, 0.0};
  EXPECT_EQ(compare_value(higher, loose, 1.0, 1.4).verdict, Verdict::Same);  // the case's override
}

// The console: the verdict table first, then the timings apart, under their own heading.
TEST(Regress, TheConsoleShowsTheVerdictsFirstAndTheTimingsApart) {
  Report rep;
  const auto add = [&](const std::string& c, const std::string& m, double base, double now, Verdict v) {
    Row r;
    r.case_name = c;
    r.metric = m;
    r.baseline = base;
    r.now = now;
    r.change = v == Verdict::Ratio ? now / base : now - base;
    r.allowed = 0.01;
    r.verdict = v;
    rep.rows.push_back(r);
  };
  add("chain_xpbd", "wall_per_step", 2e-4, 3e-4, Verdict::Ratio);  // a timing row listed first
  add("chain_xpbd", "constraint_error_final", 0.1, 0.2, Verdict::Worse);
  add("chain_pbd", "wall_per_step", 1e-4, 1e-4, Verdict::Ratio);
  add("chain_pbd", "energy_change", 1.0, 1.0, Verdict::Same);
  add("spring_xpbd", "tip_displacement", 0.5, 0.4, Verdict::Better);
  rep.worse = 1;
  rep.better = 1;
  rep.same = 1;
  const std::string text = report_table(rep);
  const size_t header = text.find("verdict\n");
  const size_t worse = text.find("constraint_error_final");
  const size_t better = text.find("tip_displacement");
  const size_t summary = text.find("5 metrics: 1 same, 1 better, 1 worse");
  const size_t timings = text.find("\ntimings (2): now / baseline, never a verdict");
  ASSERT_NE(header, std::string::npos) << text;
  ASSERT_NE(summary, std::string::npos) << text;
  ASSERT_NE(timings, std::string::npos) << text;
  EXPECT_EQ(text.find("case"), 0u) << text;  // the verdict table's header is the first line
  EXPECT_LT(header, worse) << text;
  EXPECT_LT(worse, better) << text;
  EXPECT_LT(better, summary) << text;
  EXPECT_LT(summary, timings) << text;
  EXPECT_EQ(text.find("energy_change"), std::string::npos) << text;  // same: not a row
  // Both timing rows, and only they, under the heading, as ratios without a verdict.
  EXPECT_GT(text.find("wall_per_step"), timings) << text;
  EXPECT_NE(text.find("x1.5"), std::string::npos) << text;
  EXPECT_NE(text.find("x1\n"), std::string::npos) << text;
  // The Markdown report: the same order.
  const std::string md = report_markdown(rep, "header");
  EXPECT_LT(md.find("| chain_xpbd | constraint_error_final"), md.find("## Timings")) << md;
  EXPECT_GT(md.find("| chain_xpbd | wall_per_step"), md.find("## Timings")) << md;
  EXPECT_LT(md.find("## Timings"), md.find("## Bitwise tier")) << md;
  // Nothing changed and no timing: one line.
  Report quiet;
  quiet.rows.push_back(rep.rows[3]);
  quiet.same = 1;
  EXPECT_EQ(report_table(quiet),
            "1 metrics: 1 same, 0 better, 0 worse; none changed beyond its tolerance (timings and new metrics "
            "aside)\n");
}

TEST(Regress, TheRegistryLoadsAndBadOnesAreRefused) {
  const Registry reg = load_registry(registry_file());
  EXPECT_GE(reg.cases.size(), 10u);
  EXPECT_NE(reg.metric("constraint_error_final"), nullptr);
  const TempDir dir("regress_registry");
  auto error_of = [&](const std::string& text) {
    std::ofstream(dir / "cases.toml") << text;
    try {
      load_registry(dir / "cases.toml");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string metric_ok = "[[metric]]\nname = \"e\"\nvalue = \"final(constraint_error_max)\"\ndoc = \"d\"\n";
  EXPECT_NE(error_of(metric_ok + "[[case]]\nname = \"a\"\nscenario = \"spring\"\nbogus = 1\n").find("cases.toml:8: case.bogus: unknown key"),
            std::string::npos);
  EXPECT_NE(error_of("[[metric]]\nname = \"e\"\nvalue = \"final(nope)\"\ndoc = \"d\"\n").find("no series named 'nope'"),
            std::string::npos);
  EXPECT_NE(error_of(metric_ok + "[[case]]\nname = \"a\"\nscenario = \"spring\"\nmetrics = [\"x\"]\n").find("no metric named 'x'"),
            std::string::npos);
  EXPECT_NE(error_of(metric_ok + "[[case]]\nname = \"a\"\nscenario = \"spring\"\nset = { \"solver.iterations\" = 0 }\n")
                .find("case 'a'"),
            std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Broken variants, for the demonstration only.

// xpbd, with the multipliers dropped after each step (a solver that forgot to keep lambda).
class DroppedLambda final : public Solver {
 public:
  DroppedLambda(const SolverOptions& o, const Model& m) : inner_(make_solver(o, m)) {}
  StepReport step(const Model& m, State& s, double dt) override {
    const StepReport r = inner_->step(m, s, dt);
    std::fill(s.lambda.begin(), s.lambda.end(), 0.0);
    return r;
  }
  std::string name() const override { return "xpbd-dropped-lambda"; }

 private:
  std::unique_ptr<Solver> inner_;
};

// A PBD step whose distance correction has the wrong sign (Mueller et al. 2007, sec. 3.3, with
// dp1 = +w1/(w1+w2) C n instead of -): every projection pushes a stretched link further apart.
class WrongSignPbd final : public Solver {
 public:
  StepReport step(const Model& m, State& s, double dt) override {
    StepReport r;
    r.substeps = 1;
    const Points x0 = s.x;
    for (int i = 0; i < m.particle_count(); ++i) {
      if (m.inv_mass[static_cast<size_t>(i)] == 0.0) continue;
      s.v.row(i) += dt * m.gravity.transpose();
      s.x.row(i) += dt * s.v.row(i);
    }
    for (int it = 0; it < 10; ++it, ++r.iterations)
      for (const Constraint& c : m.constraints) {
        if (c.kind != ConstraintKind::Distance) continue;
        const int a = c.particles[0], b = c.particles[1];
        const double wa = m.inv_mass[static_cast<size_t>(a)], wb = m.inv_mass[static_cast<size_t>(b)];
        const Vec3 d = s.x.row(a) - s.x.row(b);
        const double len = d.norm();
        if (len == 0.0 || wa + wb == 0.0) continue;
        const Vec3 corr = (len - c.rest) / (wa + wb) * d / len;
        s.x.row(a) += wa * corr.transpose();  // the wrong sign (correct: -=)
        s.x.row(b) -= wb * corr.transpose();  // (correct: +=)
      }
    s.v = (s.x - x0) / dt;
    s.lambda.assign(m.constraints.size(), kNaN);
    s.time += dt;
    s.step += 1;
    return r;
  }
  std::string name() const override { return "pbd-wrong-sign"; }
};

// xpbd whose velocity update keeps the predicted velocity (the constraints never reach v).
class StaleVelocity final : public Solver {
 public:
  StaleVelocity(const SolverOptions& o, const Model& m) : inner_(make_solver(o, m)) {}
  StepReport step(const Model& m, State& s, double dt) override {
    Points v = s.v;
    const StepReport r = inner_->step(m, s, dt);
    for (int i = 0; i < m.particle_count(); ++i)
      if (m.inv_mass[static_cast<size_t>(i)] > 0.0) v.row(i) += dt * m.gravity.transpose();
    s.v = v;
    return r;
  }
  std::string name() const override { return "xpbd-stale-velocity"; }

 private:
  std::unique_ptr<Solver> inner_;
};

// Measures `case_name` with the real solver (the baseline) and with `factory`, and returns the
// metrics found worse.
std::vector<std::string> worse_metrics(const std::string& case_name,
                                       std::function<std::unique_ptr<Solver>(const SolverOptions&, const Model&)> factory) {
  const Registry reg = load_registry(registry_file());
  const CaseSpec* c = nullptr;
  for (const CaseSpec& k : reg.cases)
    if (k.name == case_name) c = &k;
  EXPECT_NE(c, nullptr) << case_name;
  const TempDir dir("regress_" + case_name);
  Baseline base;
  const CaseResult good = measure_case(reg, *c, dir / "good", true);
  base.values[c->name] = good.values;
  RunControl control;
  control.make_solver = std::move(factory);
  const CaseResult bad = measure_case(reg, *c, dir / "bad", true, control);
  const Report rep = compare(reg, {c}, {bad}, base);
  std::vector<std::string> out;
  for (const Row& r : rep.rows)
    if (r.verdict == Verdict::Worse) out.push_back(r.metric);
  // The real solver against its own baseline: nothing worse.
  EXPECT_EQ(compare(reg, {c}, {good}, base).worse, 0);
  return out;
}

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

TEST(Regress, ADroppedLambdaIsCaughtByTheSupportForce) {
  const auto worse = worse_metrics("chain_xpbd", [](const SolverOptions& o, const Model& m) {
    return std::make_unique<DroppedLambda>(o, m);
  });
  EXPECT_TRUE(contains(worse, "support_force_y")) << ::testing::PrintToString(worse);
  EXPECT_EQ(worse.size(), 1u) << ::testing::PrintToString(worse);  // nothing else changed
}

TEST(Regress, AWrongGradientSignIsCaughtByTheConstraintError) {
  const auto worse = worse_metrics("chain_pbd", [](const SolverOptions&, const Model&) {
    return std::make_unique<WrongSignPbd>();
  });
  EXPECT_TRUE(contains(worse, "constraint_error_final") || contains(worse, "exploded"))
      << ::testing::PrintToString(worse);
}

TEST(Regress, AStaleVelocityIsCaughtByTheEnergy) {
  const auto worse = worse_metrics("chain_xpbd", [](const SolverOptions& o, const Model& m) {
    return std::make_unique<StaleVelocity>(o, m);
  });
  EXPECT_TRUE(contains(worse, "energy_change") || contains(worse, "exploded")) << ::testing::PrintToString(worse);
}

// The bitwise tier on the terminal: silent when the hashes match; each differing case named when
// the stored hashes come from this source; one line when another commit stored them; every case
// with --bitwise; a repeated run that changed its bits always.
TEST(Regress, TheBitwiseTierSpeaksOnlyOfDifferences) {
  Report rep;
  rep.hash_lines = {"a: 0000000000000001 bit for bit as stored", "b: 0000000000000002 differs from the stored 0000000000000003",
                    "c: 0000000000000004 differs from the stored 0000000000000005"};
  rep.hash_differences = {rep.hash_lines[1], rep.hash_lines[2]};
  rep.hash_compared = 3;
  rep.hash_stored_by = "e2ebcc1e15083f6816184c41dc36c0b20dd8e5e7+dirty";
  EXPECT_EQ(bitwise_text(rep, false),
            "bitwise: 2 of 3 cases differ from the hashes stored by e2ebcc1e1508 with local changes, not this "
            "source (changed code may change the bits; the metrics above are the comparison; --bitwise lists them)\n");
  EXPECT_EQ(bitwise_text(rep, true), "bitwise: " + rep.hash_lines[0] + "\nbitwise: " + rep.hash_lines[1] +
                                         "\nbitwise: " + rep.hash_lines[2] + "\n");
  rep.hash_same_source = true;
  EXPECT_EQ(bitwise_text(rep, false), "bitwise: " + rep.hash_lines[1] + "\nbitwise: " + rep.hash_lines[2] + "\n");
  Report same;
  same.hash_lines = {rep.hash_lines[0]};
  same.hash_compared = 1;
  EXPECT_EQ(bitwise_text(same, false), "");
  same.hash_lines.push_back("a: run twice, different bits: 0000000000000001 then 0000000000000006");
  EXPECT_EQ(bitwise_text(same, false), "bitwise: " + same.hash_lines[1] + "\n");
}

TEST(Regress, BaselinesRoundTripAndTheHashIsDeterministic) {
  const Registry reg = load_registry(registry_file());
  const CaseSpec& c = reg.cases.front();
  const TempDir dir("regress_roundtrip");
  const CaseResult a = measure_case(reg, c, dir / "a", true);
  const CaseResult b = measure_case(reg, c, dir / "b", true);
  EXPECT_EQ(a.hash, b.hash);  // the same build, the same bits
  EXPECT_EQ(a.hash.size(), 16u);
  std::ofstream(dir / "base.toml") << baseline_toml({a}, experiments::Tier::Quick);
  const Baseline base = read_baseline(dir / "base.toml");
  EXPECT_EQ(base.hashes.at(c.name), a.hash);
  for (const auto& [name, v] : a.values) {
    if (std::isnan(v)) EXPECT_TRUE(std::isnan(base.values.at(c.name).at(name))) << name;
    else EXPECT_EQ(base.values.at(c.name).at(name), v) << name;  // shortest round-trip text
  }
  std::ofstream(dir / "regress.json") << results_json({a});
  const Baseline json = read_baseline(dir / "regress.json");
  EXPECT_EQ(json.hashes.at(c.name), a.hash);
  EXPECT_EQ(compare(reg, {&c}, {a}, json).worse, 0);
  // Stored by this build: compared, and nothing to say.
  const Report rep = compare(reg, {&c}, {a}, json);
  EXPECT_EQ(rep.hash_compared, 1);
  EXPECT_TRUE(rep.hash_differences.empty());
  EXPECT_EQ(bitwise_text(rep, false), "");
}

}  // namespace
}  // namespace pbdbench::regress
