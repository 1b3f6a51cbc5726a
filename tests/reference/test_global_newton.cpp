// Tests of reference/global_newton.cpp: closed forms on one constraint, the three linear
// back-ends (CHOLMOD, assembled CG, matrix-free CG) and Ceres agreeing on the same steps, and
// XPBD driven to convergence reaching the global answer within its own residual.
#include <gtest/gtest.h>

#include <cmath>

#include "catalog/solver_catalog.hpp"
#include "reference/global_ceres.hpp"
#include "reference/global_newton.hpp"
#include "tests/reference/global_fixtures.hpp"

namespace pbdbench {
namespace {

using test::begin_global_step;
using test::catalog_scene;
using test::gap_rms;

GlobalResult solve_with(const std::string& backend, const GlobalProblem& p, Points& x,
                        std::vector<double>& lambda, SolverOptions o = {}) {
  lambda.assign(p.rows().size(), 0.0);
  x = p.x_pred();
  if (backend == "ceres") return solve_global_ceres(p, o, x, lambda);
  if (backend == "cg-matrix-free") o.global_matrix_free = true;
  GlobalNewton newton(o, backend == "cholmod" ? GlobalLinearSolver::Cholmod
                                              : GlobalLinearSolver::ConjugateGradient);
  return newton.solve(p, x, lambda);
}

const std::vector<std::string> kBackends = {"cholmod", "cg", "cg-matrix-free", "ceres"};

// One compliant link from a pinned particle, along gravity: the step minimises
// m/2 (y - y~)^2 + (L - |y| - ...)... written along the line, x* = (m x~ + L / alpha~) / (m + 1 / alpha~)
// for the free end's distance from the pin.
TEST(GlobalNewton, OneCompliantLinkReachesItsClosedForm) {
  Scene s = catalog_scene("hanging_chain", {"scene.links=1", "scene.compliance=1e-3",
                                            "scene.mass=2.0"});
  GlobalProblem p(s.model);
  const double h = 1.0 / 60.0;
  s.initial.v.row(1) = Vec3(0.0, -3.0, 0.0).transpose();  // moving away from the pin
  const Points x_pred = begin_global_step(p, s.initial, h);
  const double m = 2.0, L = 0.1, at = 1e-3 / (h * h);
  const double top = s.model.rest_positions(0, 1);
  const double dist_pred = top - x_pred(1, 1);
  const double dist = (m * dist_pred + L / at) / (m + 1.0 / at);
  for (const std::string& b : kBackends) {
    SCOPED_TRACE(b);
    Points x;
    std::vector<double> lambda;
    const GlobalResult r = solve_with(b, p, x, lambda);
    EXPECT_TRUE(r.converged);
    EXPECT_NEAR(top - x(1, 1), dist, 1e-9);
    EXPECT_NEAR(x(1, 0), x_pred(1, 0), 1e-12);
  }
}

// A rigid pendulum: x* is x~ projected onto the circle about the pivot.
TEST(GlobalNewton, RigidPendulumIsProjectedOntoItsCircle) {
  Scene s = catalog_scene("pendulum");
  GlobalProblem p(s.model);
  s.initial.v.row(s.model.observables.bob) = Vec3(2.0, 0.5, 0.0).transpose();
  const Points x_pred = begin_global_step(p, s.initial, 0.02);
  const int bob = s.model.observables.bob;
  const Vec3 pivot = s.model.observables.pivot;
  const double L = s.model.constraints[0].rest;
  const Vec3 expected = pivot + L * (x_pred.row(bob).transpose() - pivot).normalized();
  for (const std::string& b : kBackends) {
    SCOPED_TRACE(b);
    Points x;
    std::vector<double> lambda;
    const GlobalResult r = solve_with(b, p, x, lambda);
    EXPECT_TRUE(r.converged);
    EXPECT_LT((x.row(bob).transpose() - expected).norm(), 1e-8);
    EXPECT_LT(std::abs((x.row(bob).transpose() - pivot).norm() - L), 1e-9);
  }
}

// A particle predicted below a plane ends on the plane (x~ projected), with a pushing multiplier;
// one predicted above it is left at x~ with none.
TEST(GlobalNewton, PlaneContactProjectsPenetrationAndLeavesSeparationAlone) {
  for (double vy : {-2.0, -0.1}) {
    SCOPED_TRACE("vy = " + std::to_string(vy));
    Scene s = catalog_scene("free_fall");
    Model& m = s.model;
    m.planes = {{Vec3(0.0, 1.0, 0.0), 0.0, 0.0, 0.0}};
    m.radius.assign(static_cast<size_t>(m.particle_count()), 0.0);
    s.initial.x.setZero();
    s.initial.x.col(1).setConstant(0.02);
    s.initial.v.setZero();
    s.initial.v.col(1).setConstant(vy);
    s.initial.v.col(0).setConstant(0.5);
    GlobalProblem p(m);
    const Points x_pred = begin_global_step(p, s.initial, 1.0 / 60.0);
    const bool penetrates = x_pred(0, 1) < 0.0;
    EXPECT_EQ(penetrates, vy < -1.0);
    for (const std::string& b : kBackends) {
      SCOPED_TRACE(b);
      Points x;
      std::vector<double> lambda;
      const GlobalResult r = solve_with(b, p, x, lambda);
      EXPECT_TRUE(r.converged);
      for (int i = 0; i < m.particle_count(); ++i) {
        EXPECT_NEAR(x(i, 0), x_pred(i, 0), 1e-9);
        EXPECT_NEAR(x(i, 1), penetrates ? 0.0 : x_pred(i, 1), 1e-9);
      }
      for (double l : lambda) EXPECT_EQ(l > 0.0, penetrates);
    }
  }
}

// The same steps of a cloth (bending, damping, pins) and of a tet beam solved by every back-end:
// the answers agree far below the tolerance's effect on positions.
TEST(GlobalNewton, EveryBackendReachesTheSameStep) {
  struct Case {
    std::string scene;
    std::vector<std::string> sets;
    int warmup;
  };
  const std::vector<Case> cases = {
      {"hanging_cloth", {"scene.resolution=[8, 8]", "scene.stretch_damping=0.01"}, 20},
      {"cantilever_beam", {"scene.cells=[4, 1, 1]"}, 10},
      {"hanging_chain", {"scene.links=6", "scene.compliance=0", "scene.angle_deg=60"}, 5},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.scene);
    Scene s = catalog_scene(c.scene, c.sets);
    test::advance(s.model, s.initial, "xpbd", c.warmup, 1.0 / 60.0);
    GlobalProblem p(s.model);
    begin_global_step(p, s.initial, 1.0 / 60.0);
    Points x_ref;
    std::vector<double> l_ref;
    ASSERT_TRUE(solve_with("cholmod", p, x_ref, l_ref).converged);
    for (const std::string& b : kBackends) {
      SCOPED_TRACE(b);
      Points x;
      std::vector<double> lambda;
      const GlobalResult r = solve_with(b, p, x, lambda);
      // Ceres judges a step by the change of the cost, which it cannot see below ~1e-16 of the
      // cost: on the cloth that floor is ~1e-9 m of position (sqrt(2e-16 E* / m_min) with
      // E* = 6.2e-5 kg m^2, m_min = 0.0156 kg), and its Gauss-Newton steps stop there, at
      // 1.8e-9 m (reference/global_ceres.cpp). The Newton solvers reach the tolerance.
      const double tolerance = SolverOptions{}.global_tolerance * (b == "ceres" ? 5.0 : 1.0);
      EXPECT_EQ(r.converged, r.residual <= SolverOptions{}.global_tolerance);
      EXPECT_LE(r.residual, tolerance);
      EXPECT_LT((x - x_ref).cwiseAbs().maxCoeff(), 1e-7);
      ASSERT_FALSE(r.history.empty());
      EXPECT_EQ(r.history.front().iteration, 0);
      EXPECT_DOUBLE_EQ(r.history.back().residual, r.residual);
    }
  }
}

// XPBD's fixed point has h = 0 but g != 0 (Macklin et al. 2016, sec. 4: the multipliers'
// gradients are taken at different points), so converged XPBD reaches x* only up to its g. On a
// chain in tension E is strongly convex with Hessian >= M, which bounds the distance:
// |x - x*|_M <= |grad E(x)|_{M^-1}, and at XPBD's h = 0 grad E(x) is XPBD's g. A chain swinging at
// 40 degrees turns its links during the step, and XPBD's fixed point stays measurably away from
// x* (7.9e-5 m, mass-weighted RMS, here); a chain hanging straight keeps its gradients, and
// XPBD reaches x* to rounding.
struct XpbdTrial {
  double gap = 0.0;         // m, mass-weighted RMS distance from x*
  double bound = 0.0;       // m, |g|_2 / sqrt(m_min) / sqrt(total mass): the bound on gap
  double residual_h = 0.0;
};

XpbdTrial xpbd_against_global(const std::vector<std::string>& sets, int iterations) {
  Scene s = catalog_scene("hanging_chain", sets);
  const double h = 1.0 / 60.0;
  test::advance(s.model, s.initial, "xpbd", 5, h);
  GlobalProblem p(s.model);
  begin_global_step(p, s.initial, h);
  Points x_star;
  std::vector<double> lambda;
  EXPECT_TRUE(solve_with("cholmod", p, x_star, lambda).converged);
  State st = s.initial;
  SolverOptions o;
  o.name = "xpbd";
  o.iterations = iterations;
  const StepReport r = make_solver(o, s.model)->step(s.model, st, h);
  double mass = 0.0, m_min = 1e300;
  for (double w : s.model.inv_mass)
    if (w > 0.0) {
      mass += 1.0 / w;
      m_min = std::min(m_min, 1.0 / w);
    }
  return {gap_rms(s.model, st.x, x_star), r.residual_g / std::sqrt(m_min) / std::sqrt(mass),
          r.residual_h};
}

TEST(GlobalNewton, ConvergedXpbdReachesTheGlobalStepWithinItsResidual) {
  const std::vector<std::string> swinging = {"scene.links=8", "scene.angle_deg=40",
                                             "scene.compliance=1e-6"};
  double previous = std::numeric_limits<double>::infinity();
  for (int iterations : {10, 100, 1000}) {
    const XpbdTrial t = xpbd_against_global(swinging, iterations);
    EXPECT_LT(t.gap, previous) << iterations << " iterations";
    previous = t.gap;
  }
  const XpbdTrial converged = xpbd_against_global(swinging, 20000);
  EXPECT_LT(converged.residual_h, 1e-12);
  EXPECT_NEAR(converged.gap, previous, 1e-9);  // 1000 sweeps had already converged
  EXPECT_LE(converged.gap, converged.bound * (1.0 + 1e-6));
  EXPECT_GT(converged.gap, 1e-6);  // a real gap, not rounding

  const XpbdTrial straight =
      xpbd_against_global({"scene.links=8", "scene.compliance=1e-6"}, 20000);
  EXPECT_LT(straight.gap, 1e-9);
}

}  // namespace
}  // namespace pbdbench
