// Tests of runfile/converge_file: a convergence result written and read back field by field
// (an xpbd order and a global solver); files of another kind are refused naming the path.
#include "runfile/converge_file.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "runfile/compare_file.hpp"
#include "tests/runfile/test_support.hpp"

namespace pbdbench {
namespace {

namespace fs = std::filesystem;

using test::temp_dir;

ConvergeResult sample_result() {
  ConvergeResult r;
  r.scene = "hanging_cloth";
  r.scenario_file = "scenarios/hanging_cloth.toml";
  r.config = "[solver]\nname = \"xpbd\"\n";
  r.dt = 1.0 / 60.0;
  r.time = 0.5;
  r.warmup_steps = 30;
  r.warmup_solver = "xpbd";
  r.particles = 100;
  r.dynamic_particles = 98;
  r.constraints = 500;
  r.rows = 12;
  r.contacts = 3;
  r.tolerance = 1e-10;
  r.start_residual = 0.25;
  r.residual_note = "scored with the solver's own multipliers";
  r.machine = "Test CPU @ 1 GHz";
  ConvergeMethod x;
  x.key = "xpbd-sequential";
  x.description = "xpbd, Gauss-Seidel";
  x.iteration_kind = "sweeps";
  x.xpbd = true;
  x.iteration = {1, 2, 3, 5};
  x.residual = {1e-1, 1e-2, 1e-3, 1e-4};
  x.time = {1e-4, 2e-4, 3e-4, 5e-4};
  x.error = {0.5, 0.25, 0.125, 0.0625};
  x.final_error = 0.0625;
  ConvergeMethod g;
  g.key = "global-cholmod";
  g.description = "Newton, CHOLMOD";
  g.iteration_kind = "Newton iterations";
  g.iteration = {0, 1, 2};
  g.residual = {0.25, 1e-5, 1e-12};
  g.time = {0.0, 1e-3, 2e-3};
  g.inner_iterations = {0, 0, 0};
  g.converged = true;
  g.final_error = 0.0;
  r.methods = {x, g};
  return r;
}

TEST(runfile_converge_file, RoundTrip) {
  const fs::path path = temp_dir() / "converge.h5";
  const ConvergeResult w = sample_result();
  write_converge_file(path, w);
  const ConvergeFile f = read_converge_file(path);
  const ConvergeResult& r = f.result;
  EXPECT_EQ(r.scene, w.scene);
  EXPECT_EQ(r.scenario_file, w.scenario_file);
  EXPECT_EQ(r.config, w.config);
  EXPECT_EQ(r.dt, w.dt);
  EXPECT_EQ(r.time, w.time);
  EXPECT_EQ(r.warmup_steps, w.warmup_steps);
  EXPECT_EQ(r.warmup_solver, w.warmup_solver);
  EXPECT_EQ(r.particles, w.particles);
  EXPECT_EQ(r.dynamic_particles, w.dynamic_particles);
  EXPECT_EQ(r.constraints, w.constraints);
  EXPECT_EQ(r.rows, w.rows);
  EXPECT_EQ(r.contacts, w.contacts);
  EXPECT_EQ(r.tolerance, w.tolerance);
  EXPECT_EQ(r.start_residual, w.start_residual);
  EXPECT_EQ(r.residual_note, w.residual_note);
  EXPECT_EQ(r.machine, w.machine);
  ASSERT_EQ(r.methods.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    const ConvergeMethod &a = r.methods[k], &b = w.methods[k];
    SCOPED_TRACE(b.key);
    EXPECT_EQ(a.key, b.key);
    EXPECT_EQ(a.description, b.description);
    EXPECT_EQ(a.iteration_kind, b.iteration_kind);
    EXPECT_EQ(a.xpbd, b.xpbd);
    EXPECT_EQ(a.iteration, b.iteration);
    EXPECT_EQ(a.residual, b.residual);
    EXPECT_EQ(a.time, b.time);
    EXPECT_EQ(a.error, b.error);
    EXPECT_EQ(a.inner_iterations, b.inner_iterations);
    EXPECT_EQ(a.converged, b.converged);
    EXPECT_EQ(a.final_error, b.final_error);
  }
  // The derived attributes.
  EXPECT_EQ(f.attributes.at("content"), "pbdbench converge");
  EXPECT_EQ(f.attributes.at("methods"), "xpbd-sequential,global-cholmod");
  EXPECT_EQ(f.numbers.at("h"), w.dt);
  EXPECT_EQ(f.numbers.at("substeps"), 1.0);
  EXPECT_EQ(f.numbers.at("converge_format_version"), 1.0);
  EXPECT_NE(f.attributes.at("error_note").find("global-cholmod"), std::string::npos);
  EXPECT_TRUE(f.attributes.count("created"));
  EXPECT_TRUE(f.attributes.count("git_commit"));
}

// The root attributes are converge_root_attributes() (converge_file.cpp's table and the
// provenance), and the reader returns the provenance.
TEST(runfile_converge_file, RootAttributesAreTheDeclaredTable) {
  const fs::path path = temp_dir() / "converge.h5";
  write_converge_file(path, sample_result());
  const ConvergeFile f = read_converge_file(path);
  test::expect_declared(f, converge_root_attributes());
  EXPECT_EQ(f.provenance.git_commit, f.attributes.at("git_commit"));
  EXPECT_EQ(f.provenance.created, f.attributes.at("created"));
  EXPECT_FALSE(f.provenance.build_type.empty());
  std::vector<std::string> method;
  for (const AttributeInfo& a : converge_method_attributes()) method.push_back(a.name);
  EXPECT_EQ(method, (std::vector<std::string>{"method", "iteration_kind", "xpbd", "converged", "final_error"}));
  test::expect_readme_carries(attributes_markdown(converge_root_attributes()), "converge_root_attributes()");
  test::expect_readme_carries(attributes_markdown(converge_method_attributes()), "converge_method_attributes()");
}

TEST(runfile_converge_file, RefusesOtherFiles) {
  const fs::path dir = temp_dir();
  test::expect_error([&] { read_converge_file(dir / "missing.h5"); }, {"missing.h5"});
  const fs::path other = dir / "compare.h5";
  write_compare_file(other, CompareResult{});
  test::expect_error([&] { read_converge_file(other); }, {"not a converge file", other.string()});
}

}  // namespace
}  // namespace pbdbench
