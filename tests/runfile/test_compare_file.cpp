// Tests of runfile/compare_file: a compare result written and read back field by field, with
// and without observables; files of another kind are refused naming the path.
#include "runfile/compare_file.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "runfile/run_file.hpp"
#include "tests/runfile/fixture_model.hpp"
#include "tests/runfile/test_support.hpp"

namespace pbdbench {
namespace {

namespace fs = std::filesystem;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using test::temp_dir;

// Three frame times, the second interpolated; four series rows, all exact.
CompareResult sample_result(bool observables) {
  CompareResult r;
  r.run = {{"file", "a.h5"}, {"solver", "xpbd"}, {"scenario", "line"}, {"status", "complete"},
           {"config", "[solver]\nname = \"xpbd\"\n"}, {"git_commit", "abc"}};
  r.reference = {{"file", "b.h5"}, {"solver", "ref-bdf"}, {"scenario", "line"},
                 {"status", "exploded"}, {"config", ""}, {"git_commit", "def"}};
  r.until = 2.5;
  r.frames.time = {0.0, 0.05, 0.1};
  r.frames.run = {0, 1, 2};
  r.frames.lo = {0, 0, 1};
  r.frames.hi = {0, 1, 1};
  r.frames.weight = {0.0, 0.5, 0.0};
  r.frames.exact = 2;
  r.position_error_rms = {0.0, 1e-3, 2e-3};
  r.position_error_max = {0.0, 2e-3, kNaN};
  r.frame_spacing_run = 0.05;
  r.frame_spacing_reference = 0.1;
  r.rows.time = {0.0, 0.01, 0.02, 0.03};
  r.rows.run = {0, 1, 2, 3};
  r.rows.lo = r.rows.hi = {0, 1, 2, 3};
  r.rows.weight = {0.0, 0.0, 0.0, 0.0};
  r.rows.exact = 4;
  r.diff["kinetic_energy"] = {0.0, 0.1, 0.2, 0.3};
  r.diff_width["kinetic_energy"] = 1;
  r.diff_units["kinetic_energy"] = "J";
  r.diff["linear_momentum"] = {0.0, 1.0, kNaN, 3.0};
  r.diff_width["linear_momentum"] = 3;
  r.diff_units["linear_momentum"] = "kg m/s";
  r.diff["constraint_error_max_stretch"] = {1.0, 2.0, 3.0, 4.0};
  r.diff_width["constraint_error_max_stretch"] = 1;
  r.diff_units["constraint_error_max_stretch"] = "1";
  r.warnings = {"the reference's frames are sparser", "the scenario names differ"};
  if (observables) {
    Points p(4, 3), q(4, 3);
    for (int k = 0; k < 4; ++k) {
      p.row(k) << 0.0, -0.1 * k, 0.0;
      q.row(k) << 0.0, -0.11 * k, 1.0;
    }
    r.tip_displacement = {true, p, q, {0.0, 1.0, 2.0, 3.0}, {}};
    r.support_force = {true, q, p, {4.0, 5.0, 6.0, 7.0}, {0.1, 0.2, kNaN, 0.4}};
    r.pendulum = true;
    r.pendulum_angle_run = {0.1, 0.2, 0.3, 0.4};
    r.pendulum_angle_reference = {0.1, 0.25, 0.35, 0.45};
    r.period_run = 1.7;
    r.period_reference = 1.75;
    r.periods_run = 3;
    r.periods_reference = 2;
    r.period_relative_difference = (1.7 - 1.75) / 1.75;
  }
  return r;
}

// Vectors with NaN where the expected value is NaN.
void expect_same(const std::vector<double>& a, const std::vector<double>& b, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (size_t k = 0; k < a.size(); ++k)
    if (std::isnan(b[k]))
      EXPECT_TRUE(std::isnan(a[k])) << what << "[" << k << "]";
    else
      EXPECT_EQ(a[k], b[k]) << what << "[" << k << "]";
}

void expect_same(const TimeMatch& a, const TimeMatch& b) {
  EXPECT_EQ(a.time, b.time);
  EXPECT_EQ(a.run, b.run);
  EXPECT_EQ(a.lo, b.lo);
  EXPECT_EQ(a.hi, b.hi);
  EXPECT_EQ(a.weight, b.weight);
  EXPECT_EQ(a.exact, b.exact);
}

void expect_same(const VectorObservable& a, const VectorObservable& b, const char* what) {
  EXPECT_EQ(a.present, b.present) << what;
  EXPECT_EQ(a.run, b.run) << what;
  EXPECT_EQ(a.reference, b.reference) << what;
  expect_same(a.gap, b.gap, what);
  expect_same(a.relative_gap, b.relative_gap, what);
}

TEST(runfile_compare_file, RoundTrip) {
  for (const bool observables : {true, false}) {
    SCOPED_TRACE(observables ? "with observables" : "without observables");
    const fs::path path = temp_dir() / (observables ? "with.h5" : "without.h5");
    const CompareResult w = sample_result(observables);
    write_compare_file(path, w);
    const CompareFile f = read_compare_file(path);
    const CompareResult& r = f.result;

    EXPECT_EQ(r.run, w.run);
    EXPECT_EQ(r.reference, w.reference);
    EXPECT_EQ(r.until, w.until);
    expect_same(r.frames, w.frames);
    expect_same(r.position_error_rms, w.position_error_rms, "position_error_rms");
    expect_same(r.position_error_max, w.position_error_max, "position_error_max");
    EXPECT_EQ(r.frame_spacing_run, w.frame_spacing_run);
    EXPECT_EQ(r.frame_spacing_reference, w.frame_spacing_reference);
    expect_same(r.rows, w.rows);
    ASSERT_EQ(r.diff.size(), w.diff.size());
    for (const auto& [name, v] : w.diff) {
      expect_same(r.diff.at(name), v, name.c_str());
      EXPECT_EQ(r.diff_width.at(name), w.diff_width.at(name)) << name;
      EXPECT_EQ(r.diff_units.at(name), w.diff_units.at(name)) << name;
    }
    expect_same(r.tip_displacement, w.tip_displacement, "tip_displacement");
    expect_same(r.support_force, w.support_force, "support_force");
    EXPECT_EQ(r.pendulum, w.pendulum);
    EXPECT_EQ(r.pendulum_angle_run, w.pendulum_angle_run);
    EXPECT_EQ(r.pendulum_angle_reference, w.pendulum_angle_reference);
    if (observables) {
      EXPECT_EQ(r.period_run, w.period_run);
      EXPECT_EQ(r.period_reference, w.period_reference);
      EXPECT_EQ(r.periods_run, w.periods_run);
      EXPECT_EQ(r.periods_reference, w.periods_reference);
      EXPECT_EQ(r.period_relative_difference, w.period_relative_difference);
    } else {
      EXPECT_TRUE(std::isnan(r.period_run));
    }
    EXPECT_EQ(r.warnings, w.warnings);

    // The derived attributes and the provenance.
    EXPECT_EQ(f.attributes.at("content"), "pbdbench compare");
    EXPECT_EQ(f.numbers.at("compare_format_version"), 1.0);
    EXPECT_EQ(f.numbers.at("end_time"), 0.1);
    EXPECT_EQ(f.attributes.at("frames_used"), match_line(w.frames, "frames"));
    EXPECT_EQ(f.attributes.at("rows_used"), match_line(w.rows, "rows"));
    EXPECT_NE(f.attributes.at("frames_used").find("3 common frames"), std::string::npos);
    for (const char* key : {"created", "pbdbench_version", "git_commit", "compiler", "build_type", "cxx_flags"})
      EXPECT_TRUE(f.attributes.count(key)) << key;
  }
}

// The root attributes are compare_root_attributes() (compare_file.cpp's tables and the
// provenance), and the reader returns the provenance.
TEST(runfile_compare_file, RootAttributesAreTheDeclaredTable) {
  const fs::path path = temp_dir() / "compare.h5";
  write_compare_file(path, sample_result(true));
  const CompareFile f = read_compare_file(path);
  test::expect_declared(f, compare_root_attributes());
  for (const char* key : {"file", "solver", "scenario", "status", "config", "git_commit"}) {
    EXPECT_TRUE(f.attributes.count(std::string("run_") + key)) << key;
    EXPECT_TRUE(f.attributes.count(std::string("reference_") + key)) << key;
  }
  EXPECT_EQ(f.provenance.git_commit, f.attributes.at("git_commit"));
  EXPECT_EQ(f.provenance.created, f.attributes.at("created"));
  EXPECT_EQ(f.provenance.cxx_flags, f.attributes.at("cxx_flags"));
  EXPECT_FALSE(f.provenance.compiler.empty());
  test::expect_readme_carries(attributes_markdown(compare_root_attributes()), "compare_root_attributes()");
}

TEST(runfile_compare_file, RefusesOtherFiles) {
  const fs::path dir = temp_dir();
  test::expect_error([&] { read_compare_file(dir / "missing.h5"); }, {"missing.h5"});
  const fs::path run = dir / "run.h5";
  {
    RunHeader h;
    h.scenario = "fixture";
    h.solver = "xpbd";
    RunFileWriter w(run, h, test::fixture_model());
    w.finish(RunStatus::Complete, "done", 0, 0.0);
  }
  test::expect_error([&] { read_compare_file(run); }, {"not a compare file", run.string()});
}

}  // namespace
}  // namespace pbdbench
