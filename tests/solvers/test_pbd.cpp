// Tests of solvers/pbd.cpp: Mueller et al. 2007, Algorithm 1.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "catalog/solver_catalog.hpp"
#include "core/constraint_functions.hpp"
#include "solver_test_util.hpp"

namespace pbdbench::test {
namespace {

// Free fall under symplectic Euler, exact in discrete form (references.md, closed form 1):
// x_n = x0 + v0 t_n - 1/2 g t_n^2 - 1/2 g h t_n (with g the downward magnitude; here the
// gravity vector G = -g: x_n = x0 + v0 t_n + 1/2 G t_n^2 + 1/2 G h t_n).
void expect_free_fall(const std::string& solver, int substeps) {
  const Vec3 G(0.3, -9.81, 0.1);
  Model m = empty_model(G);
  add_particle(m, Vec3(1.0, 2.0, -0.5), 2.0);
  SolverOptions o = options_for(solver, 5, substeps);
  if (solver == "pbd-seed") o.seed_fixes = {"D1", "D2", "D10"};
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  const Vec3 x0(1.0, 2.0, -0.5), v0(0.5, 3.0, -1.0);
  s.v.row(0) = v0.transpose();
  const double dt = 1.0 / 60.0, h = dt / substeps;
  for (int n = 1; n <= 120; ++n) {
    const StepReport r = sv->step(m, s, dt);
    EXPECT_EQ(r.substeps, substeps);
    const double t = n * dt;
    const Vec3 x = x0 + v0 * t + 0.5 * G * t * t + 0.5 * G * h * t;
    const Vec3 v = v0 + G * t;
    // Round-off: the velocity is rebuilt as (p - x)/h every substep, which loses up to
    // ulp(|x|)/h of speed; summed over k substeps that moves x by up to ~ k^2 ulp(|x|) / 2.
    // We allow k^2 eps (1 + |x|) (1e-12 relative after 10 substeps, 2e-9 m after 480).
    const double k = static_cast<double>(n) * substeps;
    const double tol = k * k * 2.2e-16 * (1.0 + x.norm());
    ASSERT_LE((Vec3(s.x.row(0)) - x).norm(), tol) << solver << " n " << n;
    ASSERT_LE((Vec3(s.v.row(0)) - v).norm(), tol / h) << solver << " n " << n;
  }
  EXPECT_NEAR(s.time, 120 * dt, 1e-12);
  EXPECT_EQ(s.step, 120);
}

TEST(Pbd, FreeFallIsDiscreteExact) {
  for (int substeps : {1, 3, 8}) expect_free_fall("pbd", substeps);
}

TEST(Xpbd, FreeFallIsDiscreteExact) {
  for (int substeps : {1, 3, 8}) expect_free_fall("xpbd", substeps);
}

// One particle of mass m on one linear constraint: a distance constraint to a pinned anchor
// at the origin, the particle on the +x axis (C = x - L, gradient exactly (1, 0, 0)). n sweeps
// with stiffness k scale the error of the prediction by (1-k)^n, which is backward Euler on a
// spring of constant K_eff = (m/h^2)((1-k)^(-n) - 1) (references.md, Mueller 2007 section).
void expect_backward_euler(double k, int n, double dt, int substeps, bool corrected) {
  const double mass = 2.5, L = 1.0;
  Model m = empty_model();
  add_particle(m, Vec3::Zero(), 0.0);
  add_particle(m, Vec3(L, 0, 0), mass);
  add_distance(m, 0, 1, L, k);
  SolverOptions o = options_for("pbd", n, substeps);
  o.pbd_stiffness_correction = corrected;
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  s.x(1, 0) = L + 0.3;
  s.v(1, 0) = 0.7;
  const double h = dt / substeps;
  const double K = corrected ? (mass / (h * h)) * k / (1.0 - k)
                             : (mass / (h * h)) * (std::pow(1.0 - k, -n) - 1.0);
  double x = L + 0.3, v = 0.7;
  for (int step = 0; step < 40; ++step) {
    sv->step(m, s, dt);
    for (int sub = 0; sub < substeps; ++sub) {
      // Backward Euler: m (x' - x - h v) / h^2 = -K (x' - L),  v' = (x' - x) / h.
      const double x_new = (mass * (x + h * v) + K * h * h * L) / (mass + K * h * h);
      v = (x_new - x) / h;
      x = x_new;
    }
    ASSERT_NEAR(s.x(1, 0), x, kRoundoff)
        << "k " << k << " n " << n << " h " << h << " step " << step;
    ASSERT_NEAR(s.v(1, 0), v, kRoundoff / h) << "k " << k << " n " << n << " h " << h;
    ASSERT_EQ(s.x(1, 1), 0.0);
    ASSERT_EQ(s.x(1, 2), 0.0);
  }
}

TEST(Pbd, EffectiveStiffnessIsBackwardEuler) {
  for (double k : {0.05, 0.5, 0.9})
    for (int n : {1, 3, 10})
      for (double dt : {0.01, 0.002}) expect_backward_euler(k, n, dt, 1, false);
  expect_backward_euler(0.3, 4, 0.02, 4, false);  // with substeps
}

TEST(Pbd, CorrectedStiffnessIsIndependentOfIterations) {
  // With k' the effective spring is K = (m/h^2) k/(1-k) for every n.
  for (double k : {0.05, 0.5, 0.9})
    for (int n : {1, 3, 10, 40})
      for (double dt : {0.01, 0.002}) expect_backward_euler(k, n, dt, 1, true);
}

TEST(Pbd, ZeroStiffnessDoesNothing) {
  Model m = empty_model();
  add_particle(m, Vec3::Zero(), 1.0);
  add_particle(m, Vec3(1, 0, 0), 1.0);
  add_distance(m, 0, 1, 0.5, 0.0);
  auto sv = make_solver(options_for("pbd", 10), m);
  State s = rest_state(m);
  sv->step(m, s, 0.01);
  EXPECT_EQ(s.x(1, 0), 1.0);
}

TEST(Pbd, KinematicParticlesFollowTheirMotion) {
  Model m = empty_model(Vec3(0, -9.81, 0));
  add_particle(m, Vec3::Zero(), 0.0);
  add_particle(m, Vec3(0, -0.5, 0), 1.0);
  add_distance(m, 0, 1, 0.5);
  Motion motion;
  motion.kind = MotionKind::Linear;
  motion.velocity = Vec3(0.4, 0.0, 0.0);
  m.motions.push_back(motion);
  m.attachments[0].motion = 0;
  for (const std::string name : {"pbd", "xpbd", "pbd-seed"}) {
    SolverOptions o = options_for(name, 20, 2);
    if (name == "pbd-seed") {  // the listing's D3 would push the bob away, its D2 blends
      o.seed_fixes = {"D3", "D10"};
      o.seed_damping = 1.0;
    }
    auto sv = make_solver(o, m);
    State s = rest_state(m);
    for (int i = 0; i < 30; ++i) sv->step(m, s, 0.01);
    EXPECT_NEAR(s.x(0, 0), 0.4 * 0.3, kRoundoff) << name;
    EXPECT_NEAR(s.v(0, 0), 0.4, kRoundoff) << name;
    // The pendulum is dragged along: its bob has moved in +x (the listing's bob has no
    // gravity, D1, and follows less).
    EXPECT_GT(s.x(1, 0), name == "pbd-seed" ? 0.0 : 0.01) << name;
    EXPECT_NEAR((s.x.row(1) - s.x.row(0)).norm(), 0.5, 1e-6) << name;
  }
}

TEST(Pbd, ReportCountsSweepsAndContacts) {
  Model m = chain_model(3, 0.1, 1.0, Vec3(0, -9.81, 0));
  m.planes.push_back({Vec3::UnitY(), 0.25, 0.0, 0.0});  // floor at y = -0.25 + radius
  SolverOptions o = options_for("pbd", 7, 3);
  o.contact_margin = 0.5;  // every particle is a candidate
  auto sv = make_solver(o, m);
  State s = rest_state(m);
  const StepReport r = sv->step(m, s, 0.01);
  EXPECT_EQ(r.substeps, 3);
  EXPECT_EQ(r.iterations, 21);
  EXPECT_EQ(r.contacts, 9);  // 3 dynamic particles x 3 substeps
  // The bottom particle (y = -0.3 < -0.24) penetrates in the first substep at least; the link
  // above it pushes it back down in the later ones.
  EXPECT_GE(r.active_contacts, 1);
  EXPECT_LE(r.active_contacts, 9);
  EXPECT_EQ(r.skipped, 0);
  EXPECT_TRUE(std::isnan(r.residual_g));
  EXPECT_GE(r.time_project, 0.0);
  EXPECT_EQ(s.lambda.size(), 3u);
}

TEST(Pbd, SkipsUndefinedGradients) {
  Model m = empty_model();
  add_particle(m, Vec3::Zero(), 1.0);
  add_particle(m, Vec3::Zero(), 1.0);  // coincident: the distance gradient is undefined
  add_distance(m, 0, 1, 0.1);
  auto sv = make_solver(options_for("pbd", 4), m);
  State s = rest_state(m);
  const StepReport r = sv->step(m, s, 0.01);
  EXPECT_EQ(r.skipped, 4);
  EXPECT_TRUE(s.x.allFinite());
}

}  // namespace
}  // namespace pbdbench::test

namespace pbdbench::test {
namespace {

TEST(Pbd, InternalConstraintsConserveLinearMomentum) {
  // Each projection moves its particles by dx_i = -k s w_i grad_i C with sum_i grad_i C = 0
  // (translation invariance), so sum m_i dx_i = 0 and v = (p - x)/h keeps sum m v. This holds
  // for every Gauss-Seidel order and for Jacobi without averaging; Jacobi with averaging
  // divides particle i's sum by its own count n_i, which breaks the balance.
  for (ProjectionOrder order : all_orders()) {
    for (bool averaging : {false, true}) {
      if (averaging && order != ProjectionOrder::Jacobi) continue;
      for (std::uint64_t seed = 1; seed <= 10; ++seed) {
        SolverOptions o = options_for("pbd", 5, 2);
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

TEST(Pbd, AngularMomentumIsConservedOnlyToSecondOrder) {
  // Each projection conserves angular momentum about the positions where it was evaluated
  // (test_kernels), but the state's L = sum m x x v after a step is not conserved exactly:
  // v = (p - x)/h pairs the final positions with corrections whose gradients were taken
  // elsewhere. The change is second order in the step: a quarter when h halves.
  std::vector<double> change;
  for (double dt : {0.004, 0.002, 0.001}) {
    double worst = 0.0;
    for (std::uint64_t seed = 1; seed <= 10; ++seed) {
      // Constraints at rest (a spinning random body): no correction but the ones the motion
      // itself causes, of order h^2.
      Random rng(seed);
      Model m = random_internal_model(rng);
      for (Constraint& c : m.constraints) {
        c.rest = eval_constraint(c, m.rest_positions).C + c.rest;
        c.stiffness = 1.0;
      }
      State s = rest_state(m);
      const Vec3 w = rng.vec(-2, 2);
      for (int i = 0; i < m.particle_count(); ++i)
        s.v.row(i) = w.cross(Vec3(s.x.row(i))).transpose();
      const Vec3 l0 = angular_momentum(m, s);
      make_solver(options_for("pbd", 20), m)->step(m, s, dt);
      worst = std::max(worst, (angular_momentum(m, s) - l0).norm() / l0.norm());
    }
    std::printf("dt %.3f: max relative change of L in one step %.3e\n", dt, worst);
    change.push_back(worst);
  }
  EXPECT_GT(change[0], 1e-9);  // not round-off: really not conserved
  for (size_t i = 1; i < change.size(); ++i) EXPECT_NEAR(change[i] / change[i - 1], 0.25, 0.05);
}

TEST(Pbd, StepIsRotationEquivariant) {
  // The symmetry behind angular momentum: rotating the initial state rotates the result, for
  // every order, to round-off. (bottom_up sorts by height along -gravity, +y without gravity:
  // it commutes only with rotations that turn gravity too; test_ordering checks that.)
  const Mat3 R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  for (ProjectionOrder order : all_orders()) {
    if (order == ProjectionOrder::BottomUp) continue;
    Random rng(5);
    const Model m = random_internal_model(rng);
    Model mr = m;
    mr.rest_positions = (m.rest_positions * R.transpose()).eval();
    State s = random_velocities(m, rng);
    State sr = rest_state(mr);
    sr.x = s.x * R.transpose();
    sr.v = s.v * R.transpose();
    SolverOptions o = options_for("pbd", 5, 2);
    o.order = order;
    make_solver(o, m)->step(m, s, 0.01);
    make_solver(o, mr)->step(mr, sr, 0.01);
    EXPECT_LT(max_abs_diff(Points(s.x * R.transpose()), sr.x), 1e-12) << to_string(order);
  }
}

}  // namespace
}  // namespace pbdbench::test
