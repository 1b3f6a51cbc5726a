// Tests of solvers/xpbd.cpp: Macklin et al. 2016 with substeps (Macklin et al. 2019).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <complex>

#include "catalog/solver_catalog.hpp"
#include "core/constraint_functions.hpp"
#include "solver_test_util.hpp"

namespace pbdbench::test {
namespace {

// A particle of mass m on a compliant distance constraint to a pinned anchor, moving along the
// +x axis: C = x - L is linear, its gradient exactly (1, 0, 0).
Model spring_model(double mass, double compliance, double damping = 0.0) {
  Model m = empty_model();
  add_particle(m, Vec3::Zero(), 0.0);
  add_particle(m, Vec3(1.0, 0, 0), mass);
  add_distance(m, 0, 1, 1.0, 1.0, compliance, damping);
  return m;
}

TEST(Xpbd, OneIterationOnALinearConstraintIsBackwardEuler) {
  // references.md, closed form 2: omega = 1/sqrt(alpha m); backward Euler shrinks the amplitude
  // by (1 + omega^2 h^2)^(-1/2) a step and advances the phase by atan(omega h).
  for (int substeps : {1, 4}) {
    const double mass = 1.0, alpha = 1e-3, dt = 0.02, L = 1.0;
    const double h = dt / substeps;
    const double omega = 1.0 / std::sqrt(alpha * mass);
    const Model m = spring_model(mass, alpha);
    auto sv = make_solver(options_for("xpbd", 1, substeps), m);
    State s = rest_state(m);
    s.x(1, 0) = 1.5;  // the spring experiment of Macklin et al. 2016: rest 1, start 1.5
    double x = 1.5, v = 0.0;
    const double K = 1.0 / alpha;
    std::complex<double> z_prev(s.x(1, 0) - L, s.v(1, 0) / omega);
    for (int step = 0; step < 100; ++step) {
      sv->step(m, s, dt);
      for (int sub = 0; sub < substeps; ++sub) {
        const double x_new = (mass * (x + h * v) + K * h * h * L) / (mass + K * h * h);
        v = (x_new - x) / h;
        x = x_new;
      }
      ASSERT_NEAR(s.x(1, 0), x, kRoundoff) << "step " << step;
      ASSERT_NEAR(s.v(1, 0), v, kRoundoff / h) << "step " << step;
      // The complex amplitude z = (x - L) + i v / omega is multiplied by 1/(1 + i omega h) per
      // substep. v is rebuilt as (x' - x)/h, which costs |x| eps / (h omega |z|) relative
      // (2e-15 / |z| here): 1e-11 covers it while |z| > 1e-2.
      const std::complex<double> z(s.x(1, 0) - L, s.v(1, 0) / omega);
      const std::complex<double> ratio = z / z_prev;
      if (std::abs(z) > 1e-2) {  // the relative round-off grows as |z| decays
        EXPECT_NEAR(std::abs(ratio), std::pow(1.0 + omega * omega * h * h, -0.5 * substeps), 1e-11);
        EXPECT_NEAR(-std::arg(ratio), substeps * std::atan(omega * h), 1e-11);
      }
      z_prev = z;
    }
  }
}

TEST(Xpbd, LambdaGivesTheForce) {
  // A particle hanging at rest at its static equilibrium (stretch C = m g alpha): lambda is the
  // constraint force per unit of C (State::lambda's convention, core/state.hpp), -m g along the
  // gradient, which points down to the particle: the force on it, grad C lambda, is +m g up.
  // With substeps the force is the last substep's multiplier over h^2, not dt^2.
  const double mass = 2.0, alpha = 1e-4, g = 9.81, dt = 0.01;
  Model m = empty_model(Vec3(0, -g, 0));
  add_particle(m, Vec3::Zero(), 0.0);
  add_particle(m, Vec3(0, -1.0, 0), mass);
  add_distance(m, 0, 1, 1.0, 1.0, alpha);
  for (int substeps : {1, 4}) {
    State s = rest_state(m);
    s.x(1, 1) = -(1.0 + mass * g * alpha);
    auto sv = make_solver(options_for("xpbd", 1, substeps), m);
    for (int i = 0; i < 10; ++i) sv->step(m, s, dt);
    EXPECT_NEAR(s.lambda[0], -mass * g, 1e-9 * mass * g) << substeps << " substeps";
    EXPECT_NEAR(s.x(1, 1), -(1.0 + mass * g * alpha), kRoundoff) << substeps << " substeps";
  }
}

// The backward-Euler step of a chain with compliant distance constraints is the root of
//   F(x) = M (x - x~) + sum_j (C_j / alpha~_j) grad C_j,
// the optimality condition of 1/2 |x - x~|_M^2 + sum_j C_j^2 / (2 alpha~_j), alpha~ = alpha/h^2.
// Unknowns: the dynamic particles (rows of pinned particles are zero). J = dF/dx.
void backward_euler_residual(const Model& m, const Points& x, const Points& x_pred, double h,
                             Eigen::VectorXd& F, Eigen::MatrixXd* J) {
  const int n = m.particle_count();
  F = Eigen::VectorXd::Zero(3 * n);
  if (J) *J = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int i = 0; i < n; ++i) {
    const double w = m.inv_mass[static_cast<size_t>(i)];
    if (w > 0.0) {
      F.segment<3>(3 * i) = (x.row(i) - x_pred.row(i)).transpose() / w;
      if (J) J->block<3, 3>(3 * i, 3 * i) += Mat3::Identity() / w;
    } else if (J) {
      J->block<3, 3>(3 * i, 3 * i) = Mat3::Identity();  // pinned: dx = 0
    }
  }
  for (const Constraint& c : m.constraints) {
    const int a = c.particles[0], b = c.particles[1];
    const Vec3 d = x.row(b) - x.row(a);
    const double len = d.norm();
    const Vec3 nrm = d / len;
    const double C = len - c.rest;
    const double k = 1.0 / (c.compliance / (h * h));
    const Mat3 H = (Mat3::Identity() - nrm * nrm.transpose()) / len;  // d2C/dxb2
    const Mat3 block = k * (nrm * nrm.transpose() + C * H);
    const bool da = m.inv_mass[static_cast<size_t>(a)] > 0.0;
    const bool db = m.inv_mass[static_cast<size_t>(b)] > 0.0;
    if (da) F.segment<3>(3 * a) -= k * C * nrm;
    if (db) F.segment<3>(3 * b) += k * C * nrm;
    if (!J) continue;
    if (da) J->block<3, 3>(3 * a, 3 * a) += block;
    if (db) J->block<3, 3>(3 * b, 3 * b) += block;
    if (da && db) {
      J->block<3, 3>(3 * a, 3 * b) -= block;
      J->block<3, 3>(3 * b, 3 * a) -= block;
    }
  }
}

// Newton's method on F(x) = 0 from x~, to round-off.
Points newton_backward_euler(const Model& m, const Points& x_pred, double h) {
  Points x = x_pred;
  Eigen::VectorXd F;
  Eigen::MatrixXd J;
  for (int it = 0; it < 50; ++it) {
    backward_euler_residual(m, x, x_pred, h, F, &J);
    if (F.norm() < 1e-15) break;
    const Eigen::VectorXd dx = J.partialPivLu().solve(-F);
    for (int i = 0; i < m.particle_count(); ++i) x.row(i) += dx.segment<3>(3 * i).transpose();
  }
  return x;
}

struct ChainRun {
  State state;
  StepReport report;
};

ChainRun run_chain(const Model& m, const State& s0, double dt, int iterations,
                   ProjectionOrder order = ProjectionOrder::Sequential) {
  SolverOptions o = options_for("xpbd", iterations);
  o.order = order;
  auto sv = make_solver(o, m);
  ChainRun r{s0, {}};
  r.report = sv->step(m, r.state, dt);
  return r;
}

Points predicted(const Model& m, const State& s0, double dt) {
  Points x_pred = s0.x;
  for (int i = 0; i < m.particle_count(); ++i)
    if (m.inv_mass[static_cast<size_t>(i)] > 0.0)
      x_pred.row(i) += dt * (s0.v.row(i) + dt * m.gravity.transpose());
  return x_pred;
}

// Converged XPBD satisfies h = C + alpha~ lambda = 0, so lambda = -C / alpha~ and XPBD's
// g = M (x - x~) - grad C^T lambda is exactly the backward-Euler residual F(x). Its distance to
// the Newton solution is then J^-1 g, and |x - x_newton| <= |g| / m to first order (J is M plus a
// positive semidefinite part for stretched links). g is not zero for nonlinear constraints:
// Gauss-Seidel sums M^-1 grad C(x_k) dlambda_k with the gradients of the iterates x_k, not of
// the final x; the difference is second order in the corrections.
void expect_converged_is_backward_euler(const Model& m, const State& s0, double dt, double mass,
                                        double expected_max_error) {
  const Points x_pred = predicted(m, s0, dt);
  const Points x_newton = newton_backward_euler(m, x_pred, dt);
  double previous_h = INFINITY, previous_err = INFINITY;
  for (int iterations : {1, 10, 100, 1000}) {
    const ChainRun r = run_chain(m, s0, dt, iterations);
    const double err = max_abs_diff(r.state.x, x_newton);
    Eigen::VectorXd F;
    backward_euler_residual(m, r.state.x, x_pred, dt, F, nullptr);
    std::printf(
        "iterations %5d  |x - x_newton| %.3e  residual_g %.3e  |F(x)| %.3e  residual_h %.3e\n",
        iterations, err, r.report.residual_g, F.norm(), r.report.residual_h);
    EXPECT_TRUE(r.report.residual_h < previous_h || r.report.residual_h < 1e-15)
        << r.report.residual_h;  // falls until round-off
    EXPECT_LE(err, previous_err * 1.000001);
    previous_h = r.report.residual_h;
    previous_err = err;
    if (iterations == 1000) {
      EXPECT_LT(r.report.residual_h, 1e-14);
      EXPECT_NEAR(r.report.residual_g, F.norm(), 1e-9 * F.norm() + 1e-15);
      EXPECT_LE(err, 1.05 * r.report.residual_g / mass + 1e-15);
      EXPECT_LT(err, expected_max_error);
    }
  }
}

TEST(Xpbd, ConvergedChainIsBackwardEuler) {
  // A 4-link chain with compliance, nearly at rest (corrections of ~10 micrometres):
  // converged XPBD is backward Euler to 1e-10 m (measured 2.3e-11 m, = |g|/m).
  const double mass = 1.0;
  const Model m = chain_model(4, 0.1, mass, Vec3(0, -9.81, 0), 1.0, 1e-5);
  State s0 = rest_state(m);
  for (int i = 1; i < m.particle_count(); ++i) s0.v.row(i) = Vec3(0.01 * i, 0.0, 0.005).transpose();
  expect_converged_is_backward_euler(m, s0, 1.0 / 240.0, mass, 1e-10);
}

TEST(Xpbd, ConvergedSwingingChainDiffersFromBackwardEulerByG) {
  // The same chain swinging fast (0.2 rad per step): the links rotate between the iterates and
  // converged XPBD is backward Euler only up to its own g (a few micrometres here).
  const double mass = 1.0;
  const Model m = chain_model(4, 0.1, mass, Vec3(0, -9.81, 0), 1.0, 1e-5);
  State s0 = rest_state(m);
  for (int i = 1; i < m.particle_count(); ++i) s0.v.row(i) = Vec3(0.3 * i, 0.0, 0.1).transpose();
  expect_converged_is_backward_euler(m, s0, 1.0 / 60.0, mass, 1e-4);
}

TEST(Xpbd, ResidualHShrinksWithIterationsGDoesNot) {
  // A stiff chain, far from converged at 1 sweep: h falls with every sweep; g starts near zero
  // (one pass: each gradient is taken near the final positions) and grows to the floor set by
  // the nonlinearity, where it stays.
  const Model m = chain_model(8, 0.1, 1.0, Vec3(0, -9.81, 0), 1.0, 1e-7);
  State s0 = rest_state(m);
  for (int i = 1; i < m.particle_count(); ++i) s0.v.row(i) = Vec3(0.5 * i, 0.2, 0.0).transpose();
  std::vector<double> g, hres;
  for (int iterations : {1, 4, 16, 64, 256, 1024, 4096}) {
    const ChainRun r = run_chain(m, s0, 1.0 / 60.0, iterations);
    g.push_back(r.report.residual_g);
    hres.push_back(r.report.residual_h);
    std::printf("iterations %4d  residual_g %.3e  residual_h %.3e\n", iterations,
                r.report.residual_g, r.report.residual_h);
  }
  for (size_t i = 1; i < g.size(); ++i) EXPECT_LT(hres[i], hres[i - 1]);
  EXPECT_GT(g.back(), 100.0 * g.front());
  EXPECT_NEAR(g.back(), g[g.size() - 2], 0.01 * g.back());  // converged to its floor
}

TEST(Xpbd, JacobiAveragingLeavesGNonZeroAtTheFixedPoint) {
  // A straight chain moving along its own line keeps every gradient exactly (+-1, 0, 0), so
  // Gauss-Seidel accumulates M (x - x~) = grad C^T lambda exactly: g = 0 up to round-off.
  // Jacobi without averaging moves x by omega * correction and lambda by omega * dlambda: also
  // g = 0. With averaging x moves by less than lambda says: h -> 0 but g != 0.
  const Model m = chain_model(5, 0.1, 1.0, Vec3::Zero(), 1.0, 1e-5, Vec3::Zero(), Vec3(1, 0, 0));
  State s0 = rest_state(m);
  for (int i = 1; i < m.particle_count(); ++i) s0.x(i, 0) *= 1.0 + 0.05 * i;
  const ChainRun gs = run_chain(m, s0, 0.01, 2000);
  EXPECT_LT(gs.report.residual_h, 1e-13);
  EXPECT_LT(gs.report.residual_g, 1e-13);
  for (bool averaging : {false, true}) {
    SolverOptions o = options_for("xpbd", 4000);
    o.order = ProjectionOrder::Jacobi;
    o.jacobi_averaging = averaging;
    o.jacobi_relaxation = averaging ? 1.0 : 0.4;  // without averaging omega = 1 oscillates
    auto sv = make_solver(o, m);
    State s = s0;
    const StepReport r = sv->step(m, s, 0.01);
    EXPECT_LT(r.residual_h, 1e-12) << "averaging " << averaging;
    if (averaging) {
      EXPECT_GT(r.residual_g, 1e-3) << "averaging: g stays away from 0";
    } else {
      EXPECT_LT(r.residual_g, 1e-12);
    }
  }
}

TEST(Xpbd, ZeroComplianceEqualsPbdWithUnitStiffness) {
  // Macklin et al. 2016: with alpha = 0 XPBD is PBD with k = 1. One step from the same state,
  // the same order: to round-off (the compiled kernels group the same operations differently:
  // pbd multiplies by w_i / (w0 + w1), xpbd by 1 / D; measured 1e-17 m and 2e-15 m/s).
  const Model m = chain_model(6, 0.1, 1.3, Vec3(0, -9.81, 0), 1.0, 0.0);
  State s0 = rest_state(m);
  Random rng(4);
  for (int i = 1; i < m.particle_count(); ++i) {
    s0.x.row(i) += 0.02 * rng.vec(-1, 1).transpose();
    s0.v.row(i) = rng.vec(-1, 1).transpose();
  }
  for (ProjectionOrder order : all_orders()) {
    SolverOptions op = options_for("pbd", 7, 2), ox = options_for("xpbd", 7, 2);
    op.order = ox.order = order;
    State sp = s0, sx = s0;
    make_solver(op, m)->step(m, sp, 0.01);
    make_solver(ox, m)->step(m, sx, 0.01);
    EXPECT_LE(max_abs_diff(sp.x, sx.x), kRoundoff) << to_string(order);
    EXPECT_LE(max_abs_diff(sp.v, sx.v), kRoundoff) << to_string(order);
  }
}

TEST(Xpbd, DampingDecaysTheOscillation) {
  // Eq. 26 is the dissipative force -beta grad C (grad C . v): on the linear spring a
  // damper of coefficient c = beta (N s/m), which multiplies the amplitude by exp(-beta t/(2m))
  // on top of backward Euler's own decay. Over t = 0.25 s with beta = 5: 0.535. The time
  // discretisation of the damper (omega h = 0.16) shifts that by O(omega h): 10 % tolerance.
  const double alpha = 1e-3, beta = 5.0, mass = 1.0, dt = 0.005;
  double amplitude[2];
  for (int i = 0; i < 2; ++i) {
    const Model m = spring_model(mass, alpha, i == 0 ? 0.0 : beta);
    auto sv = make_solver(options_for("xpbd", 20, 1), m);
    State s = rest_state(m);
    s.x(1, 0) = 1.5;
    for (int k = 0; k < 50; ++k) sv->step(m, s, dt);
    amplitude[i] = std::hypot(s.x(1, 0) - 1.0, s.v(1, 0) * std::sqrt(alpha * mass));
  }
  const double expected = std::exp(-beta * 50 * dt / (2 * mass));
  EXPECT_NEAR(amplitude[1] / amplitude[0], expected, 0.1 * expected);
}

TEST(Xpbd, LambdaIsStoredPerConstraint) {
  const Model m = chain_model(3, 0.1, 1.0, Vec3(0, -9.81, 0), 1.0, 1e-6);
  auto sv = make_solver(options_for("xpbd", 20, 2), m);
  State s = rest_state(m);
  s.lambda.clear();
  sv->step(m, s, 0.01);
  ASSERT_EQ(s.lambda.size(), 3u);
  // Tension: the top link carries the most; lambda < 0 pulls the links together.
  EXPECT_LT(s.lambda[0], s.lambda[1]);
  EXPECT_LT(s.lambda[1], s.lambda[2]);
  EXPECT_LT(s.lambda[2], 0.0);
}

}  // namespace
}  // namespace pbdbench::test

namespace pbdbench::test {
namespace {

TEST(Xpbd, InternalConstraintsConserveLinearMomentum) {
  // As for pbd: dx_i = w_i grad_i C dlambda with sum_i grad_i C = 0, damping included (its
  // term is a scalar). Jacobi with averaging breaks it.
  for (ProjectionOrder order : all_orders()) {
    for (bool averaging : {false, true}) {
      if (averaging && order != ProjectionOrder::Jacobi) continue;
      for (std::uint64_t seed = 1; seed <= 10; ++seed) {
        SolverOptions o = options_for("xpbd", 5, 2);
        o.order = order;
        o.jacobi_averaging = averaging;
        o.jacobi_relaxation = 0.5;
        const MomentumChange c = step_momentum_change(o, seed);
        if (averaging) {
          EXPECT_GT(c.linear, 1e-6) << "seed " << seed;
        } else {
          EXPECT_LT(c.linear, kRoundoff) << to_string(order) << " seed " << seed;
        }
      }
    }
  }
}

}  // namespace
}  // namespace pbdbench::test
