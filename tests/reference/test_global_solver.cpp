// Tests of reference/global_solver.cpp: the global solvers as whole simulations.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "config/config.hpp"
#include "metrics/metrics.hpp"
#include "reference/global_solver.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {
namespace {

Scene scene(const std::string& name, const std::vector<std::string>& sets = {}) {
  std::vector<config::Override> o;
  for (const std::string& s : sets) o.push_back(config::parse_override(s));
  return config::build_scene(config::load(name, o));
}

State run(const Model& model, State state, const std::string& solver, int steps, double dt,
          std::vector<StepReport>* reports = nullptr) {
  SolverOptions o;
  o.name = solver;
  auto s = make_solver(o, model);
  EXPECT_EQ(s->name(), solver);
  for (int k = 0; k < steps; ++k) {
    const StepReport r = s->step(model, state, dt);
    if (reports) reports->push_back(r);
  }
  return state;
}

const std::vector<std::string> kGlobal = {"global-cholmod", "global-cg", "global-ceres"};

TEST(GlobalSolvers, AreRegisteredAndListed) {
  for (const std::string& name : kGlobal) {
    const SolverEntry* entry = find_solver(name);
    ASSERT_NE(entry, nullptr) << name;
    EXPECT_EQ(entry->family, SolverFamily::Global) << name;
    EXPECT_TRUE(entry->can.shadow) << name;
  }
  EXPECT_EQ(find_solver("xpbd")->family, SolverFamily::Xpbd);
}

// Twenty steps of a small damped cloth by each: every step converged, the same trajectory to far
// below the tolerance's effect, and each run bit for bit repeatable.
TEST(GlobalSolvers, AgreeOnAWholeSimulationAndAreDeterministic) {
  const Scene s = scene("hanging_cloth", {"scene.resolution=[6, 6]", "scene.stretch_damping=0.01"});
  const double dt = 1.0 / 60.0;
  std::vector<StepReport> reports;
  const State reference = run(s.model, s.initial, "global-cholmod", 20, dt, &reports);
  for (const StepReport& r : reports) {
    EXPECT_EQ(r.convergence_failures, 0);
    EXPECT_LE(r.residual_position, SolverOptions{}.global_tolerance);
    EXPECT_GT(r.newton_iterations, 0);
  }
  for (const std::string& name : kGlobal) {
    SCOPED_TRACE(name);
    const State a = run(s.model, s.initial, name, 20, dt);
    const State b = run(s.model, s.initial, name, 20, dt);
    EXPECT_EQ(std::memcmp(a.x.data(), b.x.data(), sizeof(double) * static_cast<size_t>(a.x.size())), 0);
    EXPECT_LT((a.x - reference.x).cwiseAbs().maxCoeff(), 1e-6);
    EXPECT_NEAR(a.time, 20 * dt, 1e-12);
    EXPECT_EQ(a.step, 20);
  }
}

// Why the step stopped: converged below solver.global.tolerance, or at the iteration limit (one
// Newton iteration against a tolerance of 1e-15 m on a falling cloth), which is not trusted.
TEST(GlobalSolvers, SayWhyTheStepStopped) {
  const Scene s = scene("hanging_cloth", {"scene.resolution=[6, 6]"});
  for (const std::string& name : kGlobal) {
    SCOPED_TRACE(name);
    SolverOptions o;
    o.name = name;
    auto converged = make_solver(o, s.model);
    State state = s.initial;
    EXPECT_EQ(converged->step(s.model, state, 1.0 / 60.0).stop, StopReason::Converged);
    o.global_max_iterations = 1;
    o.global_tolerance = 1e-15;
    auto limited = make_solver(o, s.model);
    state = s.initial;
    const StepReport r = limited->step(s.model, state, 1.0 / 60.0);
    EXPECT_EQ(r.convergence_failures, 1);
    // global-ceres may end its one round on its own trust-region tests: stalled.
    if (name == "global-ceres")
      EXPECT_TRUE(r.stop == StopReason::IterationLimit || r.stop == StopReason::Stalled) << stop_reason_info(r.stop).name;
    else
      EXPECT_EQ(r.stop, StopReason::IterationLimit) << stop_reason_info(r.stop).name;
    EXPECT_FALSE(stop_reason_info(r.stop).trusted);
  }
}

// A rigid chain hanging at rest: the step predicts every particle h^2 g below its place and the
// global step puts it back, so the chain stays at rest and the support holds the whole weight,
// exactly, from the first step (the references' support_force metric, metrics/metrics.hpp).
TEST(GlobalSolvers, RigidChainAtRestHoldsItsWeight) {
  const Scene s = scene("hanging_chain", {"scene.compliance=0"});
  for (const std::string& name : kGlobal) {
    SCOPED_TRACE(name);
    const State st = run(s.model, s.initial, name, 3, 1.0 / 60.0);
    EXPECT_LT((st.x - s.initial.x).cwiseAbs().maxCoeff(), 1e-9);
    const Vec3 f = support_force(s.model, st);
    EXPECT_NEAR(f.y(), 19 * 9.81, 1e-6 * 19 * 9.81);
    EXPECT_NEAR(f.x(), 0.0, 1e-9);
  }
}

// The soft cube dropped on the ground: contacts as inequalities hold it on the plane (no
// penetration beyond the tolerance once it has landed), where xpbd with its catalog 2 iterations
// leaves some.
TEST(GlobalSolvers, ContactsHoldAFallingBodyOnTheGround) {
  const Scene s = scene("soft_cube_drop", {"scene.cells=[2, 2, 2]"});
  for (const std::string& name : {std::string("global-cholmod"), std::string("global-ceres")}) {
    SCOPED_TRACE(name);
    std::vector<StepReport> reports;
    State st = run(s.model, s.initial, name, 90, 1.0 / 60.0, &reports);  // 1.5 s: landed
    int touching = 0;
    for (const StepReport& r : reports) {
      EXPECT_EQ(r.convergence_failures, 0);
      touching += r.active_contacts > 0 ? 1 : 0;
    }
    EXPECT_GT(touching, 10);
    const Sample m = measure(s.model, st, measure_baseline(s.model, s.initial));
    EXPECT_LT(m.penetration_max, 1e-8);
    EXPECT_LT(m.max_speed, 0.5);
  }
}

// global-cholmod's factorisation reused (solver.global.factor_reuse, reference/global_newton.hpp):
// a 16 x 16 cloth with bending, 12 steps. Against a factorisation every Newton iteration, with
// the default tolerance and iterations: the same Newton iterations in every step, positions
// within 1e-12 m, and fewer factorisations (the solves preconditioned with an earlier one counted
// in linear_iterations). A tolerance that 4 iterations cannot reach (1e-300, reuse_iterations 1)
// sends every reuse to its limit and then to the factorisation: the steps are those without
// reuse, bit for bit. (Given more iterations, the recurrence's residual can reach exactly 0 on a
// system this small, which meets any tolerance.)
TEST(GlobalSolvers, CholmodReusesItsFactorisationAndKeepsTheNewtonSteps) {
  const Scene s = scene("hanging_cloth", {"scene.resolution=[16, 16]"});
  const double dt = 1.0 / 60.0;
  auto simulate = [&](bool reuse, double tolerance, int iterations, std::vector<StepReport>& reports) {
    SolverOptions o;
    o.name = "global-cholmod";
    o.global_factor_reuse = reuse;
    o.global_reuse_tolerance = tolerance;
    o.global_reuse_iterations = iterations;
    auto solver = make_solver(o, s.model);
    State st = s.initial;
    for (int k = 0; k < 12; ++k) reports.push_back(solver->step(s.model, st, dt));
    return st;
  };
  const SolverOptions defaults;
  std::vector<StepReport> direct, reused, failing;
  const State a = simulate(false, defaults.global_reuse_tolerance, defaults.global_reuse_iterations, direct);
  const State b = simulate(true, defaults.global_reuse_tolerance, defaults.global_reuse_iterations, reused);
  const State c = simulate(true, 1e-300, 1, failing);
  long factorised_direct = 0, factorised_reused = 0, iterations_reused = 0, newton = 0;
  long iterations_failing = 0;
  for (size_t k = 0; k < direct.size(); ++k) {
    SCOPED_TRACE(k);
    EXPECT_EQ(direct[k].convergence_failures, 0);
    EXPECT_EQ(reused[k].convergence_failures, 0);
    EXPECT_EQ(reused[k].newton_iterations, direct[k].newton_iterations);
    EXPECT_EQ(direct[k].cholesky_factorizations, direct[k].newton_iterations);
    EXPECT_EQ(direct[k].linear_iterations, 0);
    EXPECT_EQ(failing[k].newton_iterations, direct[k].newton_iterations);
    EXPECT_EQ(failing[k].cholesky_factorizations, direct[k].cholesky_factorizations);
    // The pattern's cost ratio is reported whether or not the reuse is on, and it is what
    // lets the reuse be tried here.
    EXPECT_GE(reused[k].factor_cost_ratio, 2.0);
    EXPECT_EQ(direct[k].factor_cost_ratio, reused[k].factor_cost_ratio);
    newton += direct[k].newton_iterations;
    factorised_direct += direct[k].cholesky_factorizations;
    factorised_reused += reused[k].cholesky_factorizations;
    iterations_reused += reused[k].linear_iterations;
    iterations_failing += failing[k].linear_iterations;
  }
  EXPECT_GT(newton, 24);
  EXPECT_LT(factorised_reused, factorised_direct / 2);
  EXPECT_GT(iterations_reused, 0);
  EXPECT_GT(iterations_failing, 0);  // the reuse was tried, and gave up
  EXPECT_LT((a.x - b.x).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(std::memcmp(a.x.data(), c.x.data(), sizeof(double) * static_cast<size_t>(a.x.size())), 0);
  EXPECT_EQ(std::memcmp(a.v.data(), c.v.data(), sizeof(double) * static_cast<size_t>(a.v.size())), 0);
}

// Where a factorisation costs less than two iterations of the preconditioned solve (the chain of
// 19 links, released horizontally: 0.67 of one, by CHOLMOD's flop count), the reuse is not
// tried: a factorisation every Newton iteration and no preconditioned iteration, with
// factor_reuse on.
TEST(GlobalSolvers, CholmodDoesNotReuseWhereAFactorisationIsCheap) {
  const Scene s = scene("hanging_chain", {"scene.angle_deg=90"});  // released horizontally
  std::vector<StepReport> reports;
  run(s.model, s.initial, "global-cholmod", 10, 1.0 / 60.0, &reports);
  long newton = 0;
  for (const StepReport& r : reports) {
    EXPECT_EQ(r.cholesky_factorizations, r.newton_iterations);
    EXPECT_EQ(r.linear_iterations, 0);
    EXPECT_GT(r.factor_cost_ratio, 0.0);  // reported, and below the rule's 2
    EXPECT_LT(r.factor_cost_ratio, 2.0);
    newton += r.newton_iterations;
  }
  EXPECT_GT(newton, 10);
  // No factorisation, no ratio: NaN for global-cg.
  std::vector<StepReport> cg;
  run(s.model, s.initial, "global-cg", 1, 1.0 / 60.0, &cg);
  ASSERT_EQ(cg.size(), 1u);
  EXPECT_TRUE(std::isnan(cg[0].factor_cost_ratio));
}

TEST(GlobalSolvers, RefuseWhatTheGlobalProblemCannotHold) {
  const Scene rigid_bending =
      scene("hanging_cloth", {"scene.resolution=[3, 3]", "scene.bending_compliance=0"});
  for (const std::string& name : kGlobal) {
    SolverOptions o;
    o.name = name;
    EXPECT_THROW(make_solver(o, rigid_bending.model), std::invalid_argument) << name;
  }
}

}  // namespace
}  // namespace pbdbench
