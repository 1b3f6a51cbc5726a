// Tests of runfile/series: the table's names, order, shapes and flags, that each accessor reads
// the field its name says, and that results/README.md carries the Markdown table verbatim.
#include "runfile/series.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace pbdbench {
namespace {

std::vector<std::string> names() {
  std::vector<std::string> out;
  for (const SeriesSpec& s : series_table()) out.emplace_back(s.name);
  return out;
}

const SeriesSpec* find(const std::string& name) {
  for (const SeriesSpec& s : series_table())
    if (s.name == name) return &s;
  return nullptr;
}

TEST(runfile_series, NamesAreUniqueAndCannotCollideWithGroupSeries) {
  const auto all = names();
  const std::set<std::string> unique(all.begin(), all.end());
  EXPECT_EQ(unique.size(), all.size());
  std::set<std::string> prefixes;
  for (const GroupSeriesSpec& g : group_series_table()) {
    EXPECT_TRUE(prefixes.insert(std::string(g.prefix)).second) << g.prefix;
    for (const std::string& n : all)
      EXPECT_NE(n.rfind(std::string(g.prefix), 0), 0u)
          << n << " starts with the group prefix " << g.prefix;
  }
  for (const std::string& a : prefixes) {
    for (const std::string& b : prefixes) {
      if (a != b) {
        EXPECT_NE(a.rfind(b, 0), 0u) << a << " starts with " << b;
      }
    }
  }
}

TEST(runfile_series, RequiredSeriesInOrder) {
  const std::vector<std::string> required = {
      "time", "step", "constraint_error_max", "constraint_error_rms", "tet_volume",
      "volume_drift", "surface_volume", "surface_volume_drift", "kinetic_energy",
      "potential_energy", "elastic_energy", "total_energy", "linear_momentum",
      "angular_momentum", "penetration_max", "penetration_count", "height_min", "sunk_count",
      "sunk_depth", "velocity_hf_rms", "max_speed", "extent",
      "tip_displacement", "support_force", "pendulum_angle", "substeps", "iterations", "contacts", "active_contacts", "skipped", "stop_reason",
      "residual_g", "residual_h", "time_predict", "time_contacts", "time_project", "time_velocity",
      "wall_step"};
  const auto all = names();
  ASSERT_FALSE(all.empty());
  EXPECT_EQ(all.front(), "time");
  // `required` is a subsequence of the table, in this order.
  size_t pos = 0;
  for (const std::string& r : required) {
    auto it = std::find(all.begin() + static_cast<long>(pos), all.end(), r);
    ASSERT_NE(it, all.end()) << r << " missing or out of order";
    pos = static_cast<size_t>(it - all.begin()) + 1;
  }
}

TEST(runfile_series, ShapesUnitsDocsAndDeterminism) {
  const std::set<std::string> timings = {"time_predict", "time_contacts", "time_project", "time_residual",
                                         "time_velocity", "time_linear", "wall_step",
                                         "shadow_time", "shadow_cost_ratio"};
  const std::set<std::string> vectors = {"linear_momentum", "angular_momentum",
                                         "tip_displacement", "support_force"};
  for (const SeriesSpec& s : series_table()) {
    const std::string n(s.name);
    EXPECT_FALSE(s.units.empty()) << n;
    EXPECT_FALSE(s.doc.empty()) << n;
    EXPECT_NE(s.read, nullptr) << n;
    EXPECT_EQ(s.width, vectors.count(n) ? 3 : 1) << n;
    EXPECT_EQ(s.deterministic, timings.count(n) == 0) << n;
  }
  const std::map<std::string, std::string> units = {
      {"time", "s"}, {"step", "1"}, {"constraint_error_max", "1"}, {"constraint_error_rms", "1"},
      {"tet_volume", "m^3"}, {"volume_drift", "1"}, {"surface_volume", "m^3"},
      {"surface_volume_drift", "1"}, {"kinetic_energy", "J"}, {"potential_energy", "J"},
      {"elastic_energy", "J"}, {"total_energy", "J"}, {"linear_momentum", "kg m/s"},
      {"angular_momentum", "kg m^2/s"}, {"penetration_max", "m"}, {"penetration_count", "1"},
      {"max_speed", "m/s"}, {"extent", "m"}, {"wall_step", "s"}, {"time_project", "s"},
      {"tip_displacement", "m"}, {"support_force", "N"}, {"pendulum_angle", "rad"},
      {"height_min", "m"}, {"sunk_count", "1"}, {"sunk_depth", "m"}, {"velocity_hf_rms", "m/s"}};
  for (const auto& [name, unit] : units) {
    const SeriesSpec* s = find(name);
    ASSERT_NE(s, nullptr) << name;
    EXPECT_EQ(s->units, unit) << name;
  }
}

// Every accessor reads the field its name says: each field gets a distinct value.
TEST(runfile_series, AccessorsReadTheirOwnField) {
  Sample s;
  s.constraint_error_max = 1.5;
  s.constraint_error_rms = 2.5;
  s.tet_volume = 3.5;
  s.volume_drift = 4.5;
  s.surface_volume = 5.5;
  s.surface_volume_drift = 6.5;
  s.kinetic_energy = 7.5;
  s.potential_energy = 8.5;
  s.elastic_energy = 9.5;
  s.total_energy = 10.5;
  s.linear_momentum = Vec3(11.5, 12.5, 13.5);
  s.angular_momentum = Vec3(14.5, 15.5, 16.5);
  s.penetration_max = 17.5;
  s.penetration_count = 18;
  s.max_speed = 19.5;
  s.extent = 20.5;
  s.tip_displacement = Vec3(43.5, 44.5, 45.5);
  s.support_force = Vec3(46.5, 47.5, 48.5);
  s.pendulum_angle = 49.5;
  s.height_min = 64.5;
  s.sunk_count = 65;
  s.sunk_depth = 66.5;
  s.velocity_hf_rms = 67.5;
  StepReport r;
  r.substeps = 21;
  r.iterations = 22;
  r.contacts = 23;
  r.active_contacts = 24;
  r.skipped = 25;
  r.stop = StopReason::LineSearchFailed;
  r.residual_g = 26.5;
  r.residual_h = 27.5;
  r.time_predict = 28.5;
  r.time_contacts = 29.5;
  r.time_project = 30.5;
  r.time_velocity = 31.5;
  r.ref_steps = 35;
  r.newton_iterations = 36;
  r.linear_setups = 37;
  r.linear_solves = 38;
  r.error_test_failures = 39;
  r.convergence_failures = 40;
  r.constraint_drift = 41.5;
  r.time_linear = 42.5;
  r.cholesky_factorizations = 50;
  r.lu_factorizations = 51;
  r.linear_iterations = 52;
  r.residual_position = 53.5;
  r.line_search_cuts = 69;
  r.barrier_energy = 70.5;
  r.factor_cost_ratio = 71.5;
  ShadowSample sh;
  sh.gap = 54.5;
  sh.gap_rms = 55.5;
  sh.gap_max = 56.5;
  sh.error_max = 57.5;
  sh.residual_g = 58.5;
  sh.residual_h = 59.5;
  sh.residual_position = 60.5;
  sh.iterations = 61;
  sh.time = 62.5;
  sh.cost_ratio = 63.5;
  sh.force_error = 68.5;
  r.time_residual = 69.5;
  const SeriesRow row{32.5, 33, 34.5, &s, &r, &sh};

  const std::map<std::string, std::vector<double>> expected = {
      {"time", {32.5}}, {"step", {33}}, {"constraint_error_max", {1.5}},
      {"constraint_error_rms", {2.5}}, {"tet_volume", {3.5}}, {"volume_drift", {4.5}},
      {"surface_volume", {5.5}}, {"surface_volume_drift", {6.5}}, {"kinetic_energy", {7.5}},
      {"potential_energy", {8.5}}, {"elastic_energy", {9.5}}, {"total_energy", {10.5}},
      {"linear_momentum", {11.5, 12.5, 13.5}}, {"angular_momentum", {14.5, 15.5, 16.5}},
      {"penetration_max", {17.5}}, {"penetration_count", {18}}, {"max_speed", {19.5}},
      {"extent", {20.5}}, {"substeps", {21}}, {"iterations", {22}}, {"contacts", {23}},
      {"active_contacts", {24}}, {"skipped", {25}}, {"stop_reason", {5}}, {"residual_g", {26.5}},
      {"residual_h", {27.5}}, {"time_predict", {28.5}}, {"time_contacts", {29.5}},
      {"time_project", {30.5}}, {"time_velocity", {31.5}}, {"wall_step", {34.5}},
      {"ref_steps", {35}}, {"newton_iterations", {36}}, {"linear_setups", {37}},
      {"linear_solves", {38}}, {"error_test_failures", {39}}, {"convergence_failures", {40}},
      {"constraint_drift", {41.5}}, {"time_linear", {42.5}},
      {"tip_displacement", {43.5, 44.5, 45.5}}, {"support_force", {46.5, 47.5, 48.5}},
      {"pendulum_angle", {49.5}}, {"cholesky_factorizations", {50}},
      {"lu_factorizations", {51}}, {"linear_iterations", {52}}, {"residual_position", {53.5}},
      {"shadow_gap", {54.5}}, {"shadow_gap_rms", {55.5}}, {"shadow_gap_max", {56.5}},
      {"shadow_constraint_error_max", {57.5}}, {"shadow_residual_g", {58.5}},
      {"shadow_residual_h", {59.5}}, {"shadow_residual_position", {60.5}},
      {"shadow_iterations", {61}}, {"shadow_time", {62.5}}, {"shadow_cost_ratio", {63.5}},
      {"height_min", {64.5}}, {"sunk_count", {65}}, {"sunk_depth", {66.5}},
      {"velocity_hf_rms", {67.5}}, {"shadow_force_error", {68.5}}, {"time_residual", {69.5}},
      {"line_search_cuts", {69}}, {"barrier_energy", {70.5}}, {"factor_cost_ratio", {71.5}}};
  for (const SeriesSpec& spec : series_table()) {
    const auto it = expected.find(std::string(spec.name));
    ASSERT_NE(it, expected.end()) << spec.name << " is not covered by this test: add it";
    double out[3] = {-1, -1, -1};
    spec.read(row, out);
    ASSERT_EQ(static_cast<size_t>(spec.width), it->second.size()) << spec.name;
    for (int k = 0; k < spec.width; ++k)
      EXPECT_EQ(out[k], it->second[static_cast<size_t>(k)]) << spec.name << "[" << k << "]";
  }
  EXPECT_EQ(expected.size(), series_table().size());
}

TEST(runfile_series, GroupSeries) {
  const auto groups = group_series_table();
  ASSERT_EQ(groups.size(), 2u);
  EXPECT_EQ(groups[0].prefix, "constraint_error_max_");
  EXPECT_EQ(groups[1].prefix, "constraint_error_rms_");
  const GroupError g{0.25, 0.125, 7};
  EXPECT_EQ(groups[0].read(g), 0.25);
  EXPECT_EQ(groups[1].read(g), 0.125);
  for (const GroupSeriesSpec& s : groups) {
    EXPECT_EQ(s.units, "1");
    EXPECT_FALSE(s.doc.empty());
  }
}

TEST(runfile_series, MarkdownHasOneRowPerSeries) {
  const std::string md = series_markdown();
  std::istringstream in(md);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 2 + series_table().size() + group_series_table().size());
  EXPECT_EQ(lines[0], "| name | shape | units | description |");
  for (size_t i = 0; i < series_table().size(); ++i) {
    const SeriesSpec& s = series_table()[i];
    const std::string start = "| `" + std::string(s.name) + "` | " +
                              (s.width == 1 ? "(rows,)" : "(rows, 3)") + " | ";
    EXPECT_EQ(lines[2 + i].rfind(start, 0), 0u) << lines[2 + i];
  }
  EXPECT_NE(md.find("| `constraint_error_max_<group>` | (rows,) | 1 |"), std::string::npos);
  EXPECT_NE(md.find("| `constraint_error_rms_<group>` | (rows,) | 1 |"), std::string::npos);
  // Every row has exactly 5 unescaped '|': a '|' in a doc must not split its cell.
  for (const std::string& line : lines) {
    int bars = 0;
    for (size_t k = 0; k < line.size(); ++k)
      if (line[k] == '|' && (k == 0 || line[k - 1] != '\\')) ++bars;
    EXPECT_EQ(bars, 5) << line;
  }
}

TEST(runfile_series, ReadmeContainsTheTableVerbatim) {
  const std::string path = std::string(PBDBENCH_SOURCE_DIR) + "/results/README.md";
  std::ifstream in(path);
  ASSERT_TRUE(in) << "cannot read " << path;
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_NE(text.str().find(series_markdown()), std::string::npos)
      << path << " does not contain series_markdown() verbatim; paste this:\n"
      << series_markdown();
}

// The stop_reason series' doc names every reason with the value the series stores, so that a
// reader of the run file needs no source: it cannot drift from the table (solver_api/).
TEST(runfile_series, StopReasonDocNamesEveryReason) {
  const SeriesSpec* spec = nullptr;
  for (const SeriesSpec& s : series_table())
    if (s.name == "stop_reason") spec = &s;
  ASSERT_NE(spec, nullptr);
  const std::string doc(spec->doc);
  for (const StopReasonInfo& info : stop_reasons()) {
    const std::string entry = std::to_string(static_cast<int>(info.reason)) + " " + info.name;
    EXPECT_NE(doc.find(entry), std::string::npos) << entry;
  }
}

}  // namespace
}  // namespace pbdbench
