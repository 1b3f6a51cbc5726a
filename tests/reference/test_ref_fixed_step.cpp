// Tests of reference/ref_fixed_step: ref-be is the backward-Euler recursion to round-off
// (harmonic oscillator: amplitude factor (1 + w^2 h^2)^(-1/2) and phase atan(w h) per step,
// references.md item 2; free fall: x_{n+1} = x_n + h v_{n+1}, v_{n+1} = v_n + h g), ref-sdirk2
// is second order, through hand-written systems and catalog scenes; step counts, report fields,
// determinism and refusals.
#include "catalog/solver_catalog.hpp"
#include "reference/ref_fixed_step.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "core/generators.hpp"
#include "reference/scene_system.hpp"
#include "solver_api/solver.hpp"
#include "tests/reference/integrator_fixtures.hpp"

namespace pbdbench {
namespace {

// Round-off: each step solves a 2 x 2 linear system (condition about 1 + w h) and forms a few
// sums, so one step is exact to a few units of 1e-16; over n steps the errors add up to
// n times that at most. The comparisons allow 1e-13 per step and 1e-13 n cumulative (100
// units of round-off per step): far below anything a method error could produce (the first
// neglected term of any other method is O(w^2 h^2) ~ 0.1 here).
constexpr double kPerStep = 1e-13;

// Amplitude sqrt(q^2 + (u/w)^2) and phase atan2(-u/w, q) of the oscillator's state.
struct Polar {
  double r, phi;
};
Polar polar(double q, double u, double w) { return {std::hypot(q, u / w), std::atan2(-u / w, q)}; }

double wrap(double a) {  // to (-pi, pi]
  while (a > std::numbers::pi) a -= 2.0 * std::numbers::pi;
  while (a <= -std::numbers::pi) a += 2.0 * std::numbers::pi;
  return a;
}

FixedStepSettings settings(FixedStepMethod method) {
  return FixedStepSettings{method, 1e-10, 1e-12, 50, 0.1, false};
}

TEST(RefBe, OscillatorAmplitudeAndPhasePerStepAreBackwardEulers) {
  const double m = 1.0, alpha = 1e-3, A = 0.5, h = 1.0 / 60.0;
  const double w = 1.0 / std::sqrt(alpha * m);
  test::LinearSystem sys = test::oscillator(m, 1.0 / alpha);
  FixedStepIntegrator be(sys, settings(FixedStepMethod::BackwardEuler));
  Eigen::VectorXd q = Eigen::VectorXd::Constant(1, A), u = Eigen::VectorXd::Zero(1);
  be.reset(0.0, q, u);
  const double decay = 1.0 / std::sqrt(1.0 + w * w * h * h);
  const double advance = std::atan(w * h);
  Polar prev = polar(q[0], u[0], w);
  double worst_ratio = 0.0, worst_phase = 0.0, worst_total = 0.0;
  const int n = 120;
  for (int k = 1; k <= n; ++k) {
    be.advance(1, h, q, u);
    const Polar now = polar(q[0], u[0], w);
    worst_ratio = std::max(worst_ratio, std::abs(now.r / prev.r / decay - 1.0));
    worst_phase = std::max(worst_phase, std::abs(wrap(now.phi - prev.phi - advance)));
    worst_total = std::max(worst_total, std::abs(now.r / (A * std::pow(decay, k)) - 1.0) / k);
    prev = now;
  }
  std::printf("[ measured ] per step: amplitude ratio %.3g, phase %.3g rad; cumulative/step %.3g\n",
              worst_ratio, worst_phase, worst_total);
  EXPECT_LT(worst_ratio, kPerStep);
  EXPECT_LT(worst_phase, kPerStep);
  EXPECT_LT(worst_total, kPerStep);
  EXPECT_NEAR(be.time(), n * h, 1e-12);
}

// The step is (I - h A)^-1 y for the linear system y' = A y + b, including a changed h.
TEST(RefBe, StepIsTheBackwardEulerRecursionForALinearSystem) {
  Eigen::MatrixXd K(3, 3), D(3, 3);
  K << 40, -10, 0, -10, 30, -5, 0, -5, 20;
  D << 0.5, -0.1, 0, -0.1, 0.4, 0, 0, 0, 0.3;
  Eigen::VectorXd m(3), g(3);
  m << 1.0, 2.0, 0.5;
  g << 0.1, -9.81, 0.3;
  test::LinearSystem sys(m, K, D, g);
  FixedStepIntegrator be(sys, settings(FixedStepMethod::BackwardEuler));
  Eigen::VectorXd q(3), u(3);
  q << 0.1, -0.2, 0.3;
  u << 0.0, 1.0, -0.5;
  be.reset(0.0, q, u);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(6, 6);
  A.topRightCorner(3, 3).setIdentity();
  A.bottomLeftCorner(3, 3) = -(m.cwiseInverse().asDiagonal() * K);
  A.bottomRightCorner(3, 3) = -(m.cwiseInverse().asDiagonal() * D);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(6);
  b.tail(3) = m.cwiseInverse().cwiseProduct(g);
  Eigen::VectorXd y(6);
  y << q, u;
  double worst = 0.0;
  for (int k = 0; k < 40; ++k) {
    const double h = k < 20 ? 0.01 : 0.025;  // the step size changes half way
    y = (Eigen::MatrixXd::Identity(6, 6) - h * A).partialPivLu().solve(y + h * b);
    be.advance(1, h, q, u);
    Eigen::VectorXd got(6);
    got << q, u;
    worst = std::max(worst, (got - y).cwiseAbs().maxCoeff() / y.cwiseAbs().maxCoeff());
  }
  std::printf("[ measured ] largest relative difference from the recursion: %.3g\n", worst);
  EXPECT_LT(worst, 40 * kPerStep);
}

TEST(RefBe, CatalogSpringWithSubsteps) {
  const int substeps = 3;
  auto c = test::catalog("spring", {{"solver.name", "ref-be"},
                                    {"solver.substeps", std::to_string(substeps)},
                                    {"solver.ref.rtol", "1e-10"},
                                    {"solver.ref.atol", "1e-12"}});
  const Model& model = c.scene.model;
  State state = c.scene.initial;
  auto solver = make_solver(c.options, model);
  const double alpha = c.config.get_double("scene.compliance");
  const double m = c.config.get_double("scene.mass");
  const double L = c.config.get_double("scene.rest_length");
  const double w = 1.0 / std::sqrt(alpha * m);
  const double dt = 1.0 / 60.0, h = dt / substeps;
  const double decay = std::pow(1.0 + w * w * h * h, -0.5 * substeps);
  const double advance = substeps * std::atan(w * h);
  Polar prev = polar(state.x(1, 0) - L, state.v(1, 0), w);
  double worst_ratio = 0.0, worst_phase = 0.0;
  for (int k = 0; k < 60; ++k) {
    const StepReport r = solver->step(model, state, dt);
    EXPECT_EQ(r.substeps, substeps);
    EXPECT_EQ(r.ref_steps, substeps);  // exactly the fixed steps, nothing rejected
    EXPECT_EQ(r.error_test_failures, 0);
    EXPECT_EQ(r.convergence_failures, 0);
    EXPECT_GE(r.newton_iterations, substeps);
    EXPECT_GE(r.linear_solves, r.newton_iterations);
    const Polar now = polar(state.x(1, 0) - L, state.v(1, 0), w);
    worst_ratio = std::max(worst_ratio, std::abs(now.r / prev.r / decay - 1.0));
    worst_phase = std::max(worst_phase, std::abs(wrap(now.phi - prev.phi - advance)));
    prev = now;
    EXPECT_EQ(state.x(1, 1), 0.0);
    EXPECT_DOUBLE_EQ(state.lambda[0], -(state.x(1, 0) - L) / alpha);
  }
  std::printf("[ measured ] per step of %d substeps: amplitude ratio %.3g, phase %.3g rad\n",
              substeps, worst_ratio, worst_phase);
  // Through the 3D distance constraint: still linear along the line, so Newton's first
  // iteration is exact and the recursion holds to round-off.
  EXPECT_LT(worst_ratio, substeps * kPerStep);
  EXPECT_LT(worst_phase, substeps * kPerStep);
}

TEST(RefBe, CatalogFreeFallIsTheDiscreteRecursion) {
  const int substeps = 3;
  auto c = test::catalog("free_fall", {{"solver.name", "ref-be"},
                                       {"solver.substeps", std::to_string(substeps)}});
  const Model& model = c.scene.model;
  State state = c.scene.initial;
  auto solver = make_solver(c.options, model);
  const double dt = 0.01, h = dt / substeps;
  Vec3 x = state.x.row(0), v = state.v.row(0);
  double worst = 0.0;
  for (int k = 0; k < 200; ++k) {
    solver->step(model, state, dt);
    for (int s = 0; s < substeps; ++s) {
      v = v + h * model.gravity;
      x = x + h * v;
    }
    worst = std::max(worst, (Vec3(state.x.row(0)) - x).cwiseAbs().maxCoeff() / x.cwiseAbs().maxCoeff());
    worst = std::max(worst, (Vec3(state.v.row(0)) - v).cwiseAbs().maxCoeff() / v.cwiseAbs().maxCoeff());
  }
  std::printf("[ measured ] largest relative difference from the recursion: %.3g\n", worst);
  EXPECT_LT(worst, 600 * kPerStep);  // 600 steps
  // And it is not the continuous solution: backward Euler's drift is O(h) (here about
  // g h t / 2 = 0.033 m at t = 2 s).
  const double t = state.time;
  const Vec3 exact = c.scene.initial.x.row(0).transpose() + c.scene.initial.v.row(0).transpose() * t +
                     0.5 * model.gravity * t * t;
  EXPECT_NEAR((Vec3(state.x.row(0)) - exact).norm(), 0.5 * 9.81 * h * t, 1e-9);
}

// Order of accuracy on the oscillator at a fixed time: halving h divides the error by 2^order.
double error_at(FixedStepMethod method, int steps, double T) {
  const double m = 1.0, alpha = 1e-3, A = 0.5, w = 1.0 / std::sqrt(alpha * m);
  test::LinearSystem sys = test::oscillator(m, 1.0 / alpha);
  FixedStepIntegrator it(sys, settings(method));
  Eigen::VectorXd q = Eigen::VectorXd::Constant(1, A), u = Eigen::VectorXd::Zero(1);
  it.reset(0.0, q, u);
  it.advance(steps, T / steps, q, u);
  return std::hypot(q[0] - A * std::cos(w * T), (u[0] + A * w * std::sin(w * T)) / w);
}

TEST(RefSdirk2, IsSecondOrder) {
  const double T = 0.5;  // 2.5 periods
  double e[3], e_be[3];
  for (int k = 0; k < 3; ++k) {
    e[k] = error_at(FixedStepMethod::Sdirk2, 400 << k, T);
    e_be[k] = error_at(FixedStepMethod::BackwardEuler, 400 << k, T);
  }
  const double r1 = e[0] / e[1], r2 = e[1] / e[2];
  std::printf("[ measured ] sdirk2 errors %.3g %.3g %.3g, ratios %.3f %.3f; backward Euler ratios "
              "%.3f %.3f\n", e[0], e[1], e[2], r1, r2, e_be[0] / e_be[1], e_be[1] / e_be[2]);
  // w h = 0.04 to 0.01: the asymptotic regime, where the ratio is 4 up to O(w h) corrections.
  EXPECT_NEAR(r1, 4.0, 0.3);
  EXPECT_NEAR(r2, 4.0, 0.3);
  EXPECT_NEAR(e_be[0] / e_be[1], 2.0, 0.15);  // and backward Euler is first order
  EXPECT_LT(e[0], e_be[0] / 10.0);
}

TEST(RefSdirk2, CatalogSpringRunsWithFixedSteps) {
  auto c = test::catalog("spring", {{"solver.name", "ref-sdirk2"}, {"solver.substeps", "2"}});
  auto solver = make_solver(c.options, c.scene.model);
  EXPECT_EQ(solver->name(), "ref-sdirk2");
  State state = c.scene.initial;
  const StepReport r = solver->step(c.scene.model, state, 1.0 / 60.0);
  EXPECT_EQ(r.ref_steps, 2);
  EXPECT_GE(r.newton_iterations, 4);  // two implicit stages a step
  EXPECT_GT(r.linear_setups, 0);
  EXPECT_GE(r.linear_solves, r.newton_iterations);
  EXPECT_GE(r.time_linear, 0.0);
}

TEST(RefBe, DeterministicRejectsBadDtAndRefuses) {
  for (const char* name : {"ref-be", "ref-sdirk2"}) {
    auto c = test::catalog("spring", {{"solver.name", name}, {"solver.substeps", "2"}});
    const Model& model = c.scene.model;
    auto run = [&](State s) {
      auto solver = make_solver(c.options, model);
      for (int k = 0; k < 20; ++k) solver->step(model, s, 1.0 / 60.0);
      return s;
    };
    const State a = run(c.scene.initial), b = run(c.scene.initial);
    EXPECT_EQ(a.x, b.x) << name;
    EXPECT_EQ(a.v, b.v) << name;
    EXPECT_EQ(a.lambda, b.lambda) << name;

    auto solver = make_solver(c.options, model);
    State s = c.scene.initial;
    EXPECT_THROW(solver->step(model, s, 0.0), std::invalid_argument) << name;
    EXPECT_THROW(solver->step(model, s, -1.0), std::invalid_argument) << name;

    Model rigid = model;
    rigid.constraints[0].compliance = 0.0;
    try {
      make_solver(c.options, rigid);
      ADD_FAILURE() << name << " accepted a rigid constraint";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(std::string(name) + " cannot simulate rigid constraints"), std::string::npos) << what;
      EXPECT_NE(what.find("constraint 0"), std::string::npos) << what;
    }
    Model with_sphere = model;
    with_sphere.spheres.push_back(SphereCollider{});
    if (std::string(name) == "ref-be") {
      // ref-be simulates contact (reference/ref_contact.hpp, tests in test_ref_contact.cpp).
      EXPECT_NO_THROW(make_solver(c.options, with_sphere));
      continue;
    }
    try {
      make_solver(c.options, with_sphere);
      ADD_FAILURE() << name << " accepted a collider";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("1 sphere collider(s)"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("use ref-be"), std::string::npos) << e.what();
    }
  }
}

// A cloth released flat has no transverse stiffness until it sags, so the Jacobian of the
// predicted state, which ARKODE's own Newton solver keeps for the whole stage (a chord
// iteration), is a poor one: it converges linearly, in many iterations. sun::FullNewton
// re-evaluates the Jacobian where the iteration is slow: several times fewer iterations.
TEST(RefBe, ClothReleasedFlatConvergesFasterWithFullNewton) {
  auto c = test::catalog("hanging_cloth", {{"solver.name", "ref-be"},
                                           {"scene.resolution", "[8, 8]"},
                                           {"scene.bending", "false"}});
  const Model& model = c.scene.model;
  const double h = 1.0 / 60.0;
  long iterations[2] = {0, 0};
  Eigen::VectorXd result[2];
  for (int package = 0; package < 2; ++package) {
    SceneSystem sys(model);
    FixedStepSettings s{FixedStepMethod::BackwardEuler, c.options.ref_rtol, c.options.ref_atol,
                        c.options.ref_max_newton, 0.1, package == 1};
    FixedStepIntegrator be(sys, s);
    Eigen::VectorXd q, u;
    sys.gather(c.scene.initial, q, u);
    be.reset(0.0, q, u);
    be.advance(20, h, q, u);
    const sun::Counters n = be.counters();
    iterations[package] = n.newton_iterations;
    result[package] = q;
    std::printf("[ measured ] %s: %ld Newton iterations, %ld factorisations in 20 steps\n",
                package ? "ARKODE's Newton" : "sun::FullNewton", n.newton_iterations,
                n.linear_setups);
  }
  EXPECT_LT(4 * iterations[0], iterations[1]);
  // The same solution, to the tolerance the Newton iterations were stopped at (rtol 1e-8).
  EXPECT_LT((result[0] - result[1]).cwiseAbs().maxCoeff(), 1e-7);
}

// The catalog chain (alpha = 1e-8: stiff links) at the default tolerances: it converges (the
// velocities' absolute tolerance is atol / h), and backward Euler's damping brings it to rest at
// the static stretch of the top link, alpha times the weight of the 19 particles below.
TEST(RefBe, StiffChainAtDefaultTolerances) {
  auto c = test::catalog("hanging_chain", {{"solver.name", "ref-be"}});
  const Model& model = c.scene.model;
  State state = c.scene.initial;
  auto solver = make_solver(c.options, model);
  for (int k = 0; k < 60; ++k) {
    const StepReport r = solver->step(model, state, 1.0 / 60.0);
    EXPECT_EQ(r.convergence_failures, 0);
  }
  const double alpha = c.config.get_double("scene.compliance");
  const double expected = alpha * 19 * c.config.get_double("scene.mass") * model.gravity.norm();
  const double stretch = (state.x.row(1) - state.x.row(0)).norm() - c.config.get_double("scene.link_length");
  std::printf("[ measured ] top link stretch %.6g m, static %.6g m\n", stretch, expected);
  EXPECT_NEAR(stretch, expected, 1e-3 * expected);
}

// The same chain released at 30 degrees: links go slack and compressed as it falls, the
// stiffness is indefinite, and a Newton iteration judged on the residual norm stalls (it failed
// at the first step, at every angle tried from 5 to 30 degrees, before the stage energy became
// the line search's merit). Each step must now converge and satisfy backward Euler's equations
//   M (q1 - q0 - h u0) / h^2 = f(t1, q1),   u1 = (q1 - q0) / h
// to the Newton tolerance, checked here from the states themselves.
TEST(RefBe, StiffChainReleasedAtAnAngleSatisfiesTheStepEquations) {
  auto c = test::catalog("hanging_chain", {{"solver.name", "ref-be"}, {"scene.angle_deg", "30"}});
  const Model& model = c.scene.model;
  State state = c.scene.initial;
  auto solver = make_solver(c.options, model);
  SceneSystem sys(model);
  const double h = 1.0 / 60.0;
  double worst = 0.0, worst_u = 0.0;
  for (int k = 0; k < 120; ++k) {
    Eigen::VectorXd q0, u0, q1, u1, f;
    sys.gather(state, q0, u0);
    const StepReport r = solver->step(model, state, h);
    ASSERT_EQ(r.convergence_failures, 0) << "step " << k;
    sys.gather(state, q1, u1);
    sys.force(state.time, q1, u1, f);
    const Eigen::VectorXd inertia = sys.mass().cwiseProduct(q1 - q0 - h * u0) / (h * h);
    // Relative to the largest force term: link tensions of ~200 N against round-off of
    // alpha^-1 |C| with |C| ~ 1e-6 m.
    worst = std::max(worst, (inertia - f).cwiseAbs().maxCoeff() / f.cwiseAbs().maxCoeff());
    worst_u = std::max(worst_u, (u1 - (q1 - q0) / h).cwiseAbs().maxCoeff());
  }
  std::printf("[ measured ] largest |M (q1 - q0 - h u0) / h^2 - f| / |f|: %.3g; |u1 - (q1 - q0) / h|: %.3g m/s\n",
              worst, worst_u);
  // The Newton iterations stop at rtol 1e-8 on positions: a position error e leaves a force
  // residual of about e / alpha = 1e8 e N against forces of 1e2 N, so 1e-8 of 2 m gives up to
  // ~1e-2 relative. Measured above; a step that had not converged (or a wrong stage) is off by
  // order 1.
  EXPECT_LT(worst, 1e-2);
  // u1 - (q1 - q0) / h: the stage's first block is linear, so what is left is the Newton
  // tolerance on the positions, rtol |q| (2e-8 m here, q ~ 2 m), divided by h: 1.2e-6 m/s.
  // Measured 2.6e-6; a wrong stage would be off by the velocities themselves (~1 m/s).
  const double position_tol = c.options.ref_rtol * 2.0 + c.options.ref_atol;
  EXPECT_LT(worst_u, 10.0 * position_tol / h);
}

// A stage that cannot converge in the allowed iterations cannot be retried with a smaller
// fixed step: the error names ARKODE's flag.
TEST(RefBe, NonConvergenceNamesTheArkodeFlag) {
  test::RandomSystem sys(6, 9, false);  // nonlinear: Newton needs more than one iteration
  FixedStepSettings s = settings(FixedStepMethod::BackwardEuler);
  s.max_newton = 1;
  FixedStepIntegrator be(sys, s);
  Eigen::VectorXd q = Eigen::VectorXd::Constant(6, 1.5), u = Eigen::VectorXd::Constant(6, 2.0);
  be.reset(0.0, q, u);
  try {
    be.advance(10, 0.5, q, u);
    ADD_FAILURE() << "no failure";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("ARKStepEvolve failed: ARK_CONV_FAILURE"), std::string::npos) << what;
  }
  EXPECT_FALSE(be.started());
}

}  // namespace
}  // namespace pbdbench
