// harness/plan: the planned run's time against what short runs of catalog scenes measure.
//
// A step's cost is compared in the CPU time of the whole process (every thread: the solver's,
// the step logger's, the frame and disk workers'), per step, over a few hundred steps: what other
// processes on a shared machine do not inflate, unlike the wall clock. The estimate is meant to
// be within a factor of 2 of it.
//
//   build/tests/harness/test_harness --gtest_also_run_disabled_tests --gtest_filter='Plan.DISABLED_CatalogTable'
// prints the estimate beside the measurement for every catalog scene with its own solver (what
// plan.cpp's costs were fitted to).
#include "harness/plan.hpp"

#include <sys/resource.h>
#include <unistd.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "config/config.hpp"
#include "harness/runner.hpp"

namespace fs = std::filesystem;

namespace pbdbench {
namespace {

double process_cpu_seconds() {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

struct Measured {
  std::string name;
  long steps = 0;
  double estimate = 0.0;  // s per step
  double cpu = 0.0;       // s per step, the process
  double wall = 0.0;      // s per step, the run's steps (wall_time less setup_time)
  RunPlan plan;
  std::string features;  // what the cost depends on
};

// `steps` steps of the catalog scene `name` (its own solver, or `sets`), after `warmup` steps
// not counted (the first steps of a scene that starts apart cost less than its contacts later).
Measured measure(const std::string& name, long steps, std::vector<config::Override> sets = {}) {
  const config::Config base = config::load(name, sets);
  const double dt = config::run_options(base).dt;
  sets.push_back({"time.duration", fmt::format("{:.17g}", dt * static_cast<double>(steps))});
  const config::Config cfg = config::load(name, sets);
  const Scene scene = config::build_scene(cfg);
  Measured m;
  m.name = name;
  m.plan = plan_run(scene.model, config::solver_options(cfg), config::run_options(cfg));
  m.steps = m.plan.steps;
  m.estimate = m.plan.seconds / static_cast<double>(std::max(1L, m.plan.steps));
  {
    const Model& mo = scene.model;
    std::array<int, kConstraintKindCount> kinds{};
    for (const Constraint& c : mo.constraints) ++kinds[static_cast<size_t>(c.kind)];
    const SolverOptions o = config::solver_options(cfg);
    m.features = fmt::format("{} n={} kinds={} planes={} spheres={} meshes={} pc={} sc={} self={} tris={} sub={} it={} pairs={} every={}",
                             o.name, mo.particle_count(), fmt::join(kinds, "/"), mo.planes.size(), mo.spheres.size(),
                             mo.meshes.size(), mo.particle_contact, mo.surface_contact, mo.self_contact,
                             mo.triangles.size(), o.substeps, o.iterations, m.plan.contact_pairs,
                             config::run_options(cfg).every_frame());
  }
  const fs::path dir = fs::temp_directory_path() / ("pbdbench_test_plan_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  RunControl control;
  control.force = true;
  const double cpu0 = process_cpu_seconds();
  const RunOutcome out = run_config(cfg, dir / (name + ".h5"), control);
  const double cpu = process_cpu_seconds() - cpu0 - out.setup_cpu_time;
  fs::remove_all(dir);
  m.cpu = cpu / static_cast<double>(std::max(1L, out.steps_completed));
  m.wall = (out.wall_time - out.setup_time) / static_cast<double>(std::max(1L, out.steps_completed));
  return m;
}

std::string line(const Measured& m) {
  return fmt::format("{:<22} {:>6} steps  estimate {:9.3g} s/step  measured cpu {:9.3g} wall {:9.3g}  ratio {:5.2f}",
                     m.name, m.steps, m.estimate, m.cpu, m.wall, m.estimate / m.cpu);
}

// A few catalog scenes whose costs lie in different terms: the projections of a cloth's distance
// and bending constraints, FEM elements over 40 substeps, balls in contact with each other in a
// bowl, a cape against a mesh collider, cubes stacked with surface contact between them. (The
// smallest scenes, a step of some 50 microseconds, are left out: their time is the step's fixed
// cost, what the machine's other work moves most.)
TEST(Plan, TheTimeEstimateIsWithinAFactorOfTwoOnCatalogScenes) {
  for (const char* name : {"hanging_cloth", "cantilever_fem", "balls_in_bowl", "cape_on_character", "soft_cube_stack"}) {
    const Measured m = measure(name, 120);
    std::cout << line(m) << "\n";
    EXPECT_LT(m.estimate, 2.0 * m.cpu) << line(m);
    EXPECT_GT(m.estimate, 0.5 * m.cpu) << line(m);
  }
}

// PBDBENCH_PLAN_SOLVER=ref-be (say) measures every scene with that solver instead, and
// PBDBENCH_PLAN_STEPS the steps (default 200), PBDBENCH_PLAN_SCENES a comma-separated subset.
TEST(Plan, DISABLED_CatalogTable) {
  const char* solver = std::getenv("PBDBENCH_PLAN_SOLVER");
  const char* steps = std::getenv("PBDBENCH_PLAN_STEPS");
  const std::string only = std::getenv("PBDBENCH_PLAN_SCENES") ? std::getenv("PBDBENCH_PLAN_SCENES") : "";
  for (const config::ScenarioInfo& info : config::list_scenarios()) {
    if (info.name.find('/') != std::string::npos) continue;  // failures/: scenes that fail on purpose
    if (!only.empty() && ("," + only + ",").find("," + info.name + ",") == std::string::npos) continue;
    std::vector<config::Override> sets;
    if (solver) sets.push_back({"solver.name", solver});
    Measured m;
    try {
      m = measure(info.name, steps ? std::atol(steps) : 200, sets);
    } catch (const std::exception& e) {
      std::cout << info.name << ": " << e.what() << "\n";
      continue;
    }
    std::cout << line(m) << "\n    " << m.features << "\n";
  }
}

}  // namespace
}  // namespace pbdbench
