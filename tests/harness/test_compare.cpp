// Tests of harness/compare: the gap between two runs, on run files written by the run-file writer
// with positions and series known in closed form.
#include "harness/compare.hpp"

#include <gtest/gtest.h>


#include <cmath>
#include <filesystem>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include "metrics/metrics.hpp"
#include "runfile/compare_file.hpp"
#include "runfile/run_file.hpp"
#include "runfile/series.hpp"

namespace fs = std::filesystem;

namespace pbdbench {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

fs::path temp_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(PBDBENCH_BINARY_DIR) / "tests" / "harness" / "tmp" /
                       (std::string(info->test_suite_name()) + "." + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Three particles on the x axis, the first pinned; no constraints.
Model line_model(double spacing = 1.0, int particles = 3) {
  Model m;
  m.name = "line";
  m.rest_positions.resize(particles, 3);
  for (int i = 0; i < particles; ++i) m.rest_positions.row(i) = Eigen::RowVector3d(spacing * i, 0, 0);
  m.inv_mass.assign(static_cast<size_t>(particles), 1.0);
  m.inv_mass[0] = 0.0;
  m.radius.assign(static_cast<size_t>(particles), 0.01);
  return m;
}

// What a synthetic run holds as a function of time.
struct Motion {
  std::function<Points(const Model&, double)> positions = [](const Model& m, double) {
    return m.rest_positions;
  };
  std::function<void(double, Sample&)> sample = [](double, Sample&) {};
};

// Rows at k dt_rows (k = 0..rows-1) and frames at k dt_frames up to the last row's time.
fs::path write_run(const fs::path& path, const Model& m, const std::string& solver, double dt_rows,
                   int rows, double dt_frames, const Motion& motion = {}) {
  RunHeader h;
  h.scenario = m.name;
  h.scenario_file = "scenarios/" + m.name + ".toml";
  h.solver = solver;
  h.config = "[solver]\nname = \"" + solver + "\"\n";
  h.dt = dt_rows;
  h.steps_planned = rows - 1;
  RunFileWriter w(path, h, m, 1e9);
  const StepReport report;
  for (int k = 0; k < rows; ++k) {
    const double t = k * dt_rows;
    Sample s;
    s.kinetic_energy = 2.0 + 3.0 * t;  // linear in time
    s.total_energy = 1.0;
    s.linear_momentum = Vec3(t, 0, 0);
    motion.sample(t, s);
    w.append({t, k, 1e-3 * k, &s, &report});  // wall_step differs between runs on purpose below
  }
  const double end = (rows - 1) * dt_rows;
  for (int f = 0; f * dt_frames <= end + 1e-12; ++f) w.append_frame(f * dt_frames, motion.positions(m, f * dt_frames));
  w.finish(RunStatus::Complete, "", rows - 1, 1.0);
  return path;
}

TEST(Compare, ARunAgainstItselfHasNoGaps) {
  const fs::path dir = temp_dir();
  const Model m = line_model();
  Motion motion;
  motion.positions = [](const Model& model, double t) {
    Points x = model.rest_positions;
    x.col(1).array() -= 0.5 * 9.81 * t * t;
    return x;
  };
  motion.sample = [](double t, Sample& s) {
    s.tip_displacement = Vec3(0, -t, 0);
    s.support_force = Vec3(0, 20.0 + std::sin(t), 0);
    s.pendulum_angle = 0.4 * std::sin(2 * std::numbers::pi * t / 0.7);
  };
  const fs::path a = write_run(dir / "a.h5", m, "xpbd", 0.01, 301, 0.1, motion);
  const CompareRun run = read_compare_run(a);
  const CompareResult r = compare_runs(run, run);
  ASSERT_EQ(r.frames.time.size(), 31u);
  EXPECT_EQ(r.frames.exact, 31);
  ASSERT_EQ(r.rows.time.size(), 301u);
  EXPECT_EQ(r.rows.exact, 301);
  for (size_t k = 0; k < r.frames.time.size(); ++k) {
    EXPECT_EQ(r.position_error_rms[k], 0.0);
    EXPECT_EQ(r.position_error_max[k], 0.0);
  }
  EXPECT_FALSE(r.diff.empty());
  for (const auto& [name, d] : r.diff)
    for (double v : d)
      if (!std::isnan(v)) {  // NaN - NaN: a series the model lacks
        ASSERT_EQ(v, 0.0) << name;
      }
  ASSERT_TRUE(r.tip_displacement.present);
  ASSERT_TRUE(r.support_force.present);
  ASSERT_TRUE(r.pendulum);
  for (size_t k = 0; k < r.rows.time.size(); ++k) {
    EXPECT_EQ(r.tip_displacement.gap[k], 0.0);
    EXPECT_EQ(r.support_force.gap[k], 0.0);
    EXPECT_EQ(r.support_force.relative_gap[k], 0.0);
  }
  EXPECT_EQ(r.periods_run, 3);  // crossings at 0.7, 1.4, 2.1, 2.8 s (none at 0: no sample before)
  EXPECT_NEAR(r.period_run, 0.7, 1e-6);  // see MeanPeriodOfASinusoid
  EXPECT_EQ(r.period_relative_difference, 0.0);
  EXPECT_TRUE(r.warnings.empty());
}

TEST(Compare, ShiftedPositionsGiveTheShift) {
  const fs::path dir = temp_dir();
  const Model m = line_model();
  const Vec3 d(0.3, -0.4, 1.2);  // |d| = 1.3 m
  Motion shifted;
  shifted.positions = [&](const Model& model, double) {
    Points x = model.rest_positions;
    x.rowwise() += d.transpose();
    return x;
  };
  const CompareRun run = read_compare_run(write_run(dir / "run.h5", m, "xpbd", 0.01, 101, 0.05, shifted));
  const CompareRun ref = read_compare_run(write_run(dir / "ref.h5", m, "pbd", 0.01, 101, 0.05));
  const CompareResult r = compare_runs(run, ref);
  ASSERT_EQ(r.frames.time.size(), 21u);
  for (size_t k = 0; k < r.frames.time.size(); ++k) {
    // |(X + d) - X| = |d| up to the round-off of adding d to coordinates of up to 2 m: a few
    // ulps of 2 m.
    EXPECT_NEAR(r.position_error_rms[k], 1.3, 2e-15);
    EXPECT_NEAR(r.position_error_max[k], 1.3, 2e-15);
  }
  EXPECT_EQ(r.run.at("solver"), "xpbd");
  EXPECT_EQ(r.reference.at("solver"), "pbd");
}

TEST(Compare, InterpolationBetweenReferenceFramesIsExactForLinearMotion) {
  const fs::path dir = temp_dir();
  const Model m = line_model();
  Motion linear;  // x(t) = X + v t, kinetic_energy linear in t (write_run)
  linear.positions = [](const Model& model, double t) {
    Points x = model.rest_positions;
    x.rowwise() += Eigen::RowVector3d(1.5, -2.0, 0.25) * t;
    return x;
  };
  // The run: rows and frames every 0.01 s; the reference: rows and frames every 0.03 s.
  const CompareRun run = read_compare_run(write_run(dir / "run.h5", m, "xpbd", 0.01, 101, 0.01, linear));
  const CompareRun ref = read_compare_run(write_run(dir / "ref.h5", m, "pbd", 0.03, 34, 0.03, linear));
  const CompareResult r = compare_runs(run, ref);
  // Common times: the run's, up to the shorter run's end (the run: 1.0 s; the reference 0.99 s).
  ASSERT_EQ(r.frames.time.size(), 100u);
  EXPECT_NEAR(r.frames.time.back(), 0.99, 1e-12);
  EXPECT_EQ(r.frames.exact, 34);  // t = 0, 0.03, ..., 0.99
  ASSERT_EQ(r.rows.time.size(), 100u);
  EXPECT_EQ(r.rows.exact, 34);
  for (size_t k = 0; k < r.frames.time.size(); ++k) {
    // Linear interpolation of a linear motion: exact up to the round-off of coordinates of order
    // 1 m and of the weights (a few ulps).
    EXPECT_LE(r.position_error_max[k], 1e-14) << "t = " << r.frames.time[k];
    // Which frames were used: the two around t, with the weight of the later.
    const double t0 = ref.frame_time[static_cast<size_t>(r.frames.lo[k])];
    const double t1 = ref.frame_time[static_cast<size_t>(r.frames.hi[k])];
    EXPECT_LE(t0, r.frames.time[k] + 1e-12);
    EXPECT_GE(t1, r.frames.time[k] - 1e-12);
    if (r.frames.lo[k] != r.frames.hi[k]) {
      EXPECT_EQ(r.frames.hi[k], r.frames.lo[k] + 1);
      EXPECT_NEAR(r.frames.weight[k], (r.frames.time[k] - t0) / (t1 - t0), 1e-12);
    }
  }
  EXPECT_NEAR(r.frames.weight[1], 1.0 / 3.0, 1e-12);  // t = 0.01 between 0 and 0.03
  for (double v : r.diff.at("kinetic_energy")) EXPECT_LE(std::abs(v), 1e-14);
  for (double v : r.diff.at("linear_momentum")) EXPECT_LE(std::abs(v), 1e-15);
  // The reference's frames are three times sparser: said.
  EXPECT_NEAR(r.frame_spacing_run, 0.01, 1e-12);
  EXPECT_NEAR(r.frame_spacing_reference, 0.03, 1e-12);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("sparser"), std::string::npos) << r.warnings[0];

  // The other way round nothing is interpolated: the reference has a frame at each of the run's.
  const CompareResult back = compare_runs(ref, run);
  EXPECT_EQ(back.frames.exact, static_cast<long>(back.frames.time.size()));
  EXPECT_TRUE(back.warnings.empty());

  // --until cuts the common times.
  CompareOptions until;
  until.until = 0.5;
  const CompareResult cut = compare_runs(run, ref, until);
  EXPECT_NEAR(cut.frames.time.back(), 0.5, 1e-12);
  EXPECT_EQ(cut.frames.time.size(), 51u);
  EXPECT_EQ(cut.rows.time.size(), 51u);
}

TEST(Compare, ObservablesGapsAndPeriods) {
  const fs::path dir = temp_dir();
  const Model m = line_model();
  auto with = [](double force, double tip, double period) {
    Motion mo;
    mo.sample = [=](double t, Sample& s) {
      s.support_force = Vec3(0, force, 0);
      s.tip_displacement = Vec3(0, tip * t, 0);
      s.pendulum_angle = std::sin(2 * std::numbers::pi * (t / period + 0.1));
    };
    return mo;
  };
  const CompareRun run = read_compare_run(write_run(dir / "run.h5", m, "xpbd", 0.001, 4001, 0.1, with(21.0, -1.0, 1.1)));
  const CompareRun ref = read_compare_run(write_run(dir / "ref.h5", m, "ref-bdf", 0.001, 4001, 0.1, with(20.0, -0.5, 1.0)));
  const CompareResult r = compare_runs(run, ref);
  ASSERT_TRUE(r.support_force.present);
  EXPECT_EQ(r.support_force.gap.back(), 1.0);
  EXPECT_EQ(r.support_force.relative_gap.back(), 1.0 / 20.0);
  EXPECT_EQ(r.support_force.run(static_cast<Eigen::Index>(r.rows.time.size()) - 1, 1), 21.0);
  ASSERT_TRUE(r.tip_displacement.present);
  EXPECT_NEAR(r.tip_displacement.gap.back(), 0.5 * 4.0, 1e-12);  // |(-1 + 0.5) t| at t = 4 s
  ASSERT_TRUE(r.pendulum);
  // Upward crossings at (k - 0.1) T in 4 s: the run (T = 1.1 s) at 0.99, 2.09, 3.19 s, 2 full
  // periods; the reference (T = 1 s) at 0.9, 1.9, 2.9, 3.9 s, 3 full periods.
  EXPECT_EQ(r.periods_run, 2);
  EXPECT_EQ(r.periods_reference, 3);
  EXPECT_NEAR(r.period_run, 1.1, 1e-6);
  EXPECT_NEAR(r.period_reference, 1.0, 1e-6);
  EXPECT_NEAR(r.period_relative_difference, 0.1, 1e-5);
  EXPECT_NE(compare_summary(r).find("gap 1 N (0.05 relative)"), std::string::npos) << compare_summary(r);

  // A support force of zero in the reference (a scene without pins): no relative gap to print,
  // and no "nan relative" in its place.
  Motion unsupported;
  unsupported.sample = [](double, Sample& s) { s.support_force = Vec3::Zero(); };
  const CompareRun zero = read_compare_run(write_run(dir / "zero.h5", m, "xpbd", 0.01, 11, 0.1, unsupported));
  const CompareResult unpinned = compare_runs(zero, zero);
  ASSERT_TRUE(unpinned.support_force.present);
  const std::string text = compare_summary(unpinned);
  EXPECT_NE(text.find("support force: run (0, 0, 0) N, reference (0, 0, 0) N, gap 0 N\n"), std::string::npos) << text;
  EXPECT_EQ(text.find("nan"), std::string::npos) << text;

  // A scene without observables: none present (NaN throughout in both).
  const CompareRun plain = read_compare_run(write_run(dir / "plain.h5", m, "xpbd", 0.01, 11, 0.1));
  const CompareResult none = compare_runs(plain, plain);
  EXPECT_FALSE(none.tip_displacement.present);
  EXPECT_FALSE(none.support_force.present);
  EXPECT_FALSE(none.pendulum);
}

TEST(Compare, LeavesOutTimingsAndStepCounters) {
  const fs::path dir = temp_dir();
  const Model m = line_model();
  const CompareRun run = read_compare_run(write_run(dir / "run.h5", m, "xpbd", 0.01, 11, 0.1));
  const CompareResult r = compare_runs(run, run);
  for (const SeriesSpec& s : series_table()) {
    const std::string name(s.name);
    const bool expected = s.deterministic && !uncompared_series().count(name);
    EXPECT_EQ(r.diff.count(name), expected ? 1u : 0u) << name;
    if (expected) {
      EXPECT_EQ(r.diff_width.at(name), s.width) << name;
      EXPECT_EQ(r.diff_units.at(name), s.units) << name;
    }
  }
  // Every name in the list is a series (a renamed series must not slip into the diffs).
  for (const std::string& name : uncompared_series()) {
    bool found = false;
    for (const SeriesSpec& s : series_table()) found = found || s.name == name;
    EXPECT_TRUE(found) << name;
  }
}

TEST(Compare, RefusesRunsOfDifferentScenes) {
  const fs::path dir = temp_dir();
  const CompareRun three = read_compare_run(write_run(dir / "three.h5", line_model(1.0, 3), "xpbd", 0.01, 11, 0.1));
  const CompareRun four = read_compare_run(write_run(dir / "four.h5", line_model(1.0, 4), "xpbd", 0.01, 11, 0.1));
  const CompareRun wider = read_compare_run(write_run(dir / "wider.h5", line_model(1.1, 3), "xpbd", 0.01, 11, 0.1));
  try {
    compare_runs(three, four);
    FAIL() << "different particle counts accepted";
  } catch (const CompareInputError& e) {
    EXPECT_NE(std::string(e.what()).find("3 particles against 4"), std::string::npos) << e.what();
  }
  try {
    compare_runs(three, wider);
    FAIL() << "different rest positions accepted";
  } catch (const CompareInputError& e) {
    EXPECT_NE(std::string(e.what()).find("rest positions differ by up to 0.2 m (particle 2)"),
              std::string::npos)
        << e.what();
  }
  CompareOptions bad;
  bad.until = -1.0;
  EXPECT_THROW(compare_runs(three, three, bad), CompareInputError);
  bad.until = kNaN;
  EXPECT_THROW(compare_runs(three, three, bad), CompareInputError);
  EXPECT_THROW(read_compare_run(dir / "missing.h5"), std::runtime_error);
}

TEST(Compare, MeanPeriodOfASinusoid) {
  // Upward zero crossings of sin(w t + phi), located by linear interpolation between samples dt
  // apart: sin has no curvature at its zeros, so each crossing is off by at most about
  // w^2 dt^3 / 60 (2e-7 s here), and the mean period by less.
  const double T = 1.7, w = 2 * std::numbers::pi / T, dt = 0.01;
  std::vector<double> t, a;
  for (int k = 0; k <= 1000; ++k) {  // 10 s
    t.push_back(k * dt);
    a.push_back(0.3 * std::sin(w * t.back() + 0.4));
  }
  int periods = 0;
  EXPECT_NEAR(mean_period(t, a, &periods), T, 1e-6);
  EXPECT_EQ(periods, 4);  // upward crossings at (k - 0.4 / 2 pi) T: 1.59, 3.29, ..., 8.39 s
  // Less than one full period: NaN.
  const std::vector<double> t1(t.begin(), t.begin() + 200), a1(a.begin(), a.begin() + 200);
  EXPECT_TRUE(std::isnan(mean_period(t1, a1, &periods)));
  EXPECT_EQ(periods, 0);
  // An angle that goes round and round wraps from pi to -pi: that is not a crossing of 0.
  std::vector<double> spin;
  for (double x : t) spin.push_back(std::remainder(3.0 * x, 2 * std::numbers::pi));
  // It crosses 0 upward once per turn (2 pi / 3 s), at x = 2 pi k / 3.
  EXPECT_NEAR(mean_period(t, spin), 2 * std::numbers::pi / 3.0, 1e-9);
  const std::vector<double> backwards = [&] {
    std::vector<double> out;
    for (double x : t) out.push_back(std::remainder(-3.0 * x + 0.5, 2 * std::numbers::pi));
    return out;
  }();
  EXPECT_TRUE(std::isnan(mean_period(t, backwards)));  // only downward crossings and wraps
  // NaN samples are no crossings.
  std::vector<double> gappy = a;
  for (size_t k = 0; k < gappy.size(); k += 2) gappy[k] = kNaN;
  EXPECT_TRUE(std::isnan(mean_period(t, gappy)));
}

TEST(Compare, WritesTheCompareFile) {
  const fs::path dir = temp_dir();
  const Model m = line_model();
  const CompareRun run = read_compare_run(write_run(dir / "run.h5", m, "xpbd", 0.01, 101, 0.05));
  const CompareRun ref = read_compare_run(write_run(dir / "ref.h5", m, "pbd", 0.01, 101, 0.1));
  const CompareResult r = compare_runs(run, ref);
  const fs::path out = dir / "out" / "compare.h5";
  write_compare_file(out, r);
  // Read back through runfile/'s reader (HDF5 is known only in runfile/; tests/runfile checks
  // the layout against the file itself).
  const CompareFile f = read_compare_file(out);
  auto str = [&](const char* name) { return f.attributes.count(name) ? f.attributes.at(name) : "<missing>"; };
  EXPECT_EQ(str("run_solver"), "xpbd");
  EXPECT_EQ(str("reference_solver"), "pbd");
  EXPECT_EQ(str("run_file"), (dir / "run.h5").string());
  EXPECT_EQ(str("reference_file"), (dir / "ref.h5").string());
  EXPECT_NE(str("run_config").find("xpbd"), std::string::npos);
  EXPECT_FALSE(f.provenance.git_commit.empty());
  EXPECT_NE(str("warnings").find("sparser"), std::string::npos);
  const CompareResult& back = f.result;
  EXPECT_EQ(back.frames.time.size(), 21u);
  EXPECT_EQ(back.position_error_rms.size(), 21u);
  EXPECT_EQ(back.position_error_max.size(), 21u);
  EXPECT_EQ(back.frames.lo.size(), 21u);  // /compare/reference_frame, (21, 2)
  EXPECT_EQ(back.frames.hi.size(), 21u);
  EXPECT_EQ(back.rows.time.size(), 101u);
  ASSERT_TRUE(back.diff.count("kinetic_energy"));
  ASSERT_TRUE(back.diff.count("linear_momentum"));
  EXPECT_EQ(back.diff.at("kinetic_energy").size(), 101u);
  EXPECT_EQ(back.diff.at("linear_momentum").size(), 101u);
  ASSERT_EQ(back.frames.weight.size(), 21u);
  EXPECT_NEAR(back.frames.weight[1], 0.5, 1e-12);  // t = 0.05 halfway between the reference's 0 and 0.1

  const std::string summary = compare_summary(r);
  EXPECT_NE(summary.find("21 common frames"), std::string::npos) << summary;
  EXPECT_NE(summary.find("11 at the same times, 10 interpolated"), std::string::npos) << summary;
  EXPECT_NE(summary.find("largest max position error"), std::string::npos) << summary;
}

}  // namespace
}  // namespace pbdbench
