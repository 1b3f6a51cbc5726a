// Tests of reference/global_ceres: the global step solved by Ceres against closed forms (a
// compliant pendulum with and without damping, a rigid pendulum, a particle against a plane), its
// stationarity on compliant chains and on volume, bending and element terms, a model mixing every
// kind of row, and its bookkeeping (history, counts, determinism, the arguments it refuses).
//
// Closed forms. One dynamic particle of mass m joined to a pinned pivot p by a distance
// constraint of rest length L: E depends on x only through the mass term and |x - p|, so the
// minimiser lies on the ray from p through x~ (for any other point, the point of the ray at the
// same distance from p is closer to x~). With d = |x~ - p| and s = |x - p|:
//   compliant:  m (s - d) + (s - L) / alpha~ = 0         =>  s = (m alpha~ d + L) / (m alpha~ + 1)
//   damped, x_n on the same ray at s_n (grad C(x_n) is the ray's direction u):
//               m (s - d) + (s - L) / alpha~ + h beta (s - s_n) = 0
//   rigid:      s = L, and from g = m (x - x~) - u lambda = 0, lambda = m (L - d):
//               a bob predicted outside the circle (the rod in tension) has lambda < 0, inside
//               (compression) lambda > 0. XPBD's sign: x moves by M^-1 grad C^T lambda, and a
//               stretched constraint pulls back against its gradient.
// A particle predicted through a plane (unit normal n, C(x) = n . x + o - r < 0) is projected
// onto it, x = x~ - C(x~) n, with lambda = m (x - x~) . n = -m C(x~) > 0; predicted clear of it,
// x = x~ and lambda = 0.
#include "reference/global_ceres.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/constraint_functions.hpp"
#include "core/contacts.hpp"
#include "core/fem.hpp"
#include "core/model.hpp"
#include "reference/global_problem.hpp"
#include "solver_api/options.hpp"

namespace pbdbench {
namespace {

constexpr double kTolerance = 1e-9;  // m, SolverOptions::global_tolerance's default
constexpr double kStep = 0.01;       // s

SolverOptions ceres_options(const std::string& method = "levenberg_marquardt") {
  SolverOptions o;
  o.global_tolerance = kTolerance;
  o.global_ceres_method = method;
  return o;
}

const std::vector<std::string> kMethods = {"levenberg_marquardt", "dogleg"};

// Particles at `positions` (their rest positions), with the given inverse masses.
Model particles(const std::vector<Vec3>& positions, const std::vector<double>& inv_mass,
                const Vec3& gravity = Vec3(0.0, -9.81, 0.0)) {
  Model m;
  m.name = "global-ceres test";
  m.gravity = gravity;
  m.rest_positions.resize(static_cast<Eigen::Index>(positions.size()), 3);
  for (size_t i = 0; i < positions.size(); ++i)
    m.rest_positions.row(static_cast<Eigen::Index>(i)) = positions[i].transpose();
  m.inv_mass = inv_mass;
  m.radius.assign(positions.size(), 0.01);
  return m;
}

Constraint distance(int a, int b, double rest, double compliance, double damping = 0.0) {
  Constraint c;
  c.kind = ConstraintKind::Distance;
  c.particles = {a, b, -1, -1};
  c.rest = rest;
  c.compliance = compliance;
  c.damping = damping;
  return c;
}

// x~ = x_n + h v_n + h^2 g for the dynamic particles; the others stay where x_n has them.
Points predict(const Model& m, const Points& x_start, const Points& v, double h) {
  Points p = x_start;
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    if (m.inv_mass[static_cast<size_t>(i)] > 0.0)
      p.row(i) += h * v.row(i) + h * h * m.gravity.transpose();
  return p;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

// ---------------------------------------------------------------------------------------------
// Closed forms.

TEST(GlobalCeres, CompliantPendulumMatchesTheClosedForm) {
  const Vec3 pivot(0.1, 1.0, -0.2);
  const double mass = 2.0, L = 0.5;
  for (const double compliance : {1e-2, 1e-4, 1e-7}) {
    for (const std::string& method : kMethods) {
      SCOPED_TRACE("compliance " + std::to_string(compliance) + ", " + method);
      Model m = particles({pivot, pivot + Vec3(0.3, -0.4, 0.1)}, {0.0, 1.0 / mass});
      m.constraints.push_back(distance(0, 1, L, compliance));
      GlobalProblem problem(m);
      Points x_start = m.rest_positions;
      Points v = Points::Zero(2, 3);
      v.row(1) << 0.5, 0.2, -0.3;
      const Points x_pred = predict(m, x_start, v, kStep);
      problem.begin_step(x_start, x_pred, kStep, kStep, {});
      ASSERT_TRUE(problem.rows().empty());

      const Vec3 xt = x_pred.row(1).transpose();
      const double d = (xt - pivot).norm();
      const double at = compliance / (kStep * kStep);
      const double s = (mass * at * d + L) / (mass * at + 1.0);
      const Vec3 expected = pivot + s * (xt - pivot) / d;

      Points x = x_pred;
      std::vector<double> lambda;
      const GlobalResult r = solve_global_ceres(problem, ceres_options(method), x, lambda);
      EXPECT_TRUE(r.converged);
      EXPECT_LE(r.residual, kTolerance);
      EXPECT_EQ(r.iterations, 1) << "no rows: a single round";
      EXPECT_LE((x.row(1).transpose() - expected).norm(), kTolerance);
      EXPECT_EQ(x.row(0), m.rest_positions.row(0)) << "the pinned particle is not a parameter";
    }
  }
}

TEST(GlobalCeres, DampedCompliantPendulumMatchesTheClosedForm) {
  // x_n, x~ and the pivot on one ray: the step stays on it, and the frozen damping gradient is
  // the ray's direction.
  const Vec3 pivot(0.0, 0.0, 0.0);
  const Vec3 u = Vec3(0.2, -0.9, 0.3).normalized();
  const double mass = 0.7, L = 1.0, compliance = 1e-5, beta = 3.0;
  const double s_n = 1.02, d = 1.05;
  Model m = particles({pivot, pivot + s_n * u}, {0.0, 1.0 / mass}, Vec3::Zero());
  m.constraints.push_back(distance(0, 1, L, compliance, beta));
  GlobalProblem problem(m);
  ASSERT_EQ(problem.damped().size(), 1u);
  Points x_start = m.rest_positions;
  Points x_pred = x_start;
  x_pred.row(1) = (pivot + d * u).transpose();
  problem.begin_step(x_start, x_pred, kStep, kStep, {});

  const double at = compliance / (kStep * kStep);
  const double s = (mass * d + L / at + kStep * beta * s_n) / (mass + 1.0 / at + kStep * beta);
  for (const std::string& method : kMethods) {
    SCOPED_TRACE(method);
    Points x = x_pred;
    std::vector<double> lambda;
    const GlobalResult r = solve_global_ceres(problem, ceres_options(method), x, lambda);
    EXPECT_TRUE(r.converged);
    EXPECT_LE((x.row(1).transpose() - (pivot + s * u)).norm(), kTolerance);
  }
}

TEST(GlobalCeres, RigidPendulumIsTheProjectionOntoTheCircle) {
  const Vec3 pivot(0.0, 2.0, 0.0);
  const double mass = 1.5, L = 1.0;
  // Outside the circle (d > L: tension, lambda < 0) and inside (d < L: compression, > 0).
  for (const double d : {1.02, 0.98}) {
    for (const std::string& method : kMethods) {
      SCOPED_TRACE("d = " + std::to_string(d) + ", " + method);
      const Vec3 u = Vec3(0.6, -0.9, 0.2).normalized();
      Model m = particles({pivot, pivot + L * Vec3(0.0, -1.0, 0.0)}, {0.0, 1.0 / mass});
      m.constraints.push_back(distance(0, 1, L, 0.0));
      GlobalProblem problem(m);
      Points x_start = m.rest_positions;
      Points x_pred = x_start;
      x_pred.row(1) = (pivot + d * u).transpose();
      problem.begin_step(x_start, x_pred, kStep, kStep, {});
      ASSERT_EQ(problem.rows().size(), 1u);
      ASSERT_FALSE(problem.rows()[0].inequality);

      Points x = x_pred;
      std::vector<double> lambda(1, 0.0);
      const GlobalResult r = solve_global_ceres(problem, ceres_options(method), x, lambda);
      EXPECT_TRUE(r.converged);
      EXPECT_LE(r.residual, kTolerance);
      EXPECT_GE(r.iterations, 1);
      const Vec3 xb = x.row(1).transpose();
      EXPECT_LE((xb - (pivot + L * u)).norm(), 1e-8);
      EXPECT_LE(std::abs((xb - pivot).norm() - L), kTolerance) << "C = 0";
      EXPECT_NEAR(lambda[0], mass * (L - d), 1e-8);
      if (d > L) {
        EXPECT_LT(lambda[0], 0.0) << "tension: lambda < 0";
      } else {
        EXPECT_GT(lambda[0], 0.0) << "compression: lambda > 0";
      }
    }
  }
}

TEST(GlobalCeres, PlaneContactProjectsThroughAndLeavesClearParticlesAlone) {
  PlaneCollider plane;
  plane.normal = Vec3(0.3, 2.0, 0.1);  // not unit on purpose: C uses n / |n| and offset / |n|
  plane.offset = 0.4;
  const Vec3 n = plane.normal.normalized();
  const double o = plane.offset / plane.normal.norm();
  const double mass = 0.25, radius = 0.01;
  const auto C = [&](const Vec3& y) { return n.dot(y) + o - radius; };

  for (const std::string& method : kMethods) {
    SCOPED_TRACE(method);
    // Above the plane at the start, predicted through it.
    {
      Model m = particles({Vec3(0.3, 0.05, 0.2)}, {1.0 / mass});
      m.planes.push_back(plane);
      m.radius[0] = radius;
      GlobalProblem problem(m);
      Points x_start = m.rest_positions;
      Points x_pred = x_start;
      x_pred.row(0) << 0.32, -0.27, 0.21;  // 2 cm through
      ASSERT_LT(C(x_pred.row(0).transpose()), 0.0);
      problem.begin_step(x_start, x_pred, kStep, kStep, {Contact{ContactKind::Plane, 0, 0}});
      ASSERT_EQ(problem.rows().size(), 1u);
      ASSERT_TRUE(problem.rows()[0].inequality);

      const Vec3 xt = x_pred.row(0).transpose();
      const Vec3 expected = xt - C(xt) * n;
      Points x = x_pred;
      std::vector<double> lambda(1, 0.0);
      const GlobalResult r = solve_global_ceres(problem, ceres_options(method), x, lambda);
      EXPECT_TRUE(r.converged);
      EXPECT_LE((x.row(0).transpose() - expected).norm(), 1e-8);
      EXPECT_GE(C(x.row(0).transpose()), -kTolerance);
      EXPECT_GT(lambda[0], 0.0);
      EXPECT_NEAR(lambda[0], -mass * C(xt), 1e-8);
    }
    // Predicted clear of the plane: the contact (within the finder's margin) does not push.
    {
      Model m = particles({Vec3(0.3, 0.05, 0.2)}, {1.0 / mass});
      m.planes.push_back(plane);
      m.radius[0] = radius;
      GlobalProblem problem(m);
      Points x_start = m.rest_positions;
      Points x_pred = x_start;
      x_pred.row(0) << 0.31, 0.02, 0.2;
      ASSERT_GT(C(x_pred.row(0).transpose()), 0.0);
      problem.begin_step(x_start, x_pred, kStep, kStep, {Contact{ContactKind::Plane, 0, 0}});
      // From x~ it is already the solution; from x_n it has to get there.
      for (const bool from_prediction : {true, false}) {
        Points x = from_prediction ? x_pred : x_start;
        std::vector<double> lambda(1, 0.0);
        const GlobalResult r = solve_global_ceres(problem, ceres_options(method), x, lambda);
        EXPECT_TRUE(r.converged);
        EXPECT_LE((x.row(0) - x_pred.row(0)).norm(), kTolerance);
        EXPECT_EQ(lambda[0], 0.0);
        if (from_prediction) {
          EXPECT_EQ(r.iterations, 0) << "converged at the starting point";
        }
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Stationarity on chains.

// A chain: pinned particle 0 and `links` dynamic ones along x, each link and every second
// diagonal a compliant distance constraint (some damped), shorter than at the start by the
// fraction `prestrain` (and a little more down the chain), started moving.
//
// Gauss-Newton leaves out the curvature term sum_j (C_j / alpha~_j) hess C_j of E's Hessian, so
// its rate is about |lambda_j| |hess C_j| / m: fast where the constraint forces are those of a
// simulation step, slow for a stiff chain started far from its rest lengths (compliance 1e-6 with
// a few per cent of prestrain takes it hundreds of iterations). The stiff chain here starts at
// rest.
Model chain(int links, double compliance, bool damping, double prestrain = 0.02) {
  std::vector<Vec3> pos;
  std::vector<double> inv_mass;
  for (int i = 0; i <= links; ++i) {
    pos.emplace_back(0.2 * i, 1.0 - 0.03 * i * i, 0.01 * i);
    inv_mass.push_back(i == 0 ? 0.0 : 1.0 / (0.1 + 0.05 * i));
  }
  Model m = particles(pos, inv_mass);
  const auto rest = [&](int a, int b, double factor) {
    return factor * (pos[static_cast<size_t>(a)] - pos[static_cast<size_t>(b)]).norm();
  };
  const double more = prestrain > 0.0 ? 0.01 : 0.0;
  for (int i = 0; i < links; ++i)
    m.constraints.push_back(distance(i, i + 1, rest(i, i + 1, 1.0 - prestrain - more * i),
                                     compliance * (1.0 + 0.3 * i),
                                     damping && i % 2 == 0 ? 0.5 : 0.0));
  for (int i = 0; i + 2 <= links; i += 2)
    m.constraints.push_back(
        distance(i, i + 2, rest(i, i + 2, 1.0 - prestrain - more), 10.0 * compliance));
  return m;
}

Points chain_velocities(int n) {
  Points v(n, 3);
  for (int i = 0; i < n; ++i) v.row(i) << 0.4 * std::sin(i), -0.3 * i, 0.2 * std::cos(2.0 * i);
  v.row(0).setZero();
  return v;
}

TEST(GlobalCeres, CompliantChainIsStationary) {
  for (const double compliance : {1e-3, 1e-6}) {
    for (const bool damping : {false, true}) {
      for (const std::string& method : kMethods) {
        SCOPED_TRACE("compliance " + std::to_string(compliance) + (damping ? ", damped, " : ", ") +
                     method);
        const Model m = chain(5, compliance, damping, compliance > 1e-4 ? 0.03 : 0.0);
        GlobalProblem problem(m);
        const Points x_start = m.rest_positions;
        const Points x_pred = predict(m, x_start, chain_velocities(6), kStep);
        problem.begin_step(x_start, x_pred, kStep, kStep, {});

        Points x = x_pred;
        std::vector<double> lambda;
        const GlobalResult r = solve_global_ceres(problem, ceres_options(method), x, lambda);
        EXPECT_TRUE(r.converged);
        EXPECT_LE(r.residual, kTolerance);
        EXPECT_LE(problem.residuals(x, lambda).position, kTolerance);
        // The same from E's gradient directly: |g_i| / m_i.
        Eigen::VectorXd g;
        problem.gradient(x, g);
        EXPECT_LE((g.array() / problem.mass().array()).abs().maxCoeff(), kTolerance);
        // A minimum: E does not decrease along small moves of any dof.
        const double E = problem.objective(x);
        for (const int p : problem.energy().dynamic_particles())
          for (int a = 0; a < 3; ++a)
            for (const double delta : {-1e-5, 1e-5}) {
              Points y = x;
              y(p, a) += delta;
              EXPECT_GT(problem.objective(y), E - 1e-15);
            }
      }
    }
  }
}

// The other compliant terms (volume, bending in its smooth form, a stable neo-Hookean element's
// pair of FEM-kind constraints, damping on some) through their 4-particle stencils, a kinematic
// particle among them.
TEST(GlobalCeres, VolumeBendingAndElementTermsAreStationary) {
  const std::vector<Vec3> pos = {Vec3(0.0, 1.0, 0.0), Vec3(0.3, 1.0, 0.0), Vec3(0.1, 1.25, 0.05),
                                 Vec3(0.12, 0.95, 0.3), Vec3(0.15, 0.7, -0.2)};
  Model m = particles(pos, {0.0, 2.0, 3.0, 2.5, 4.0});
  Motion up;
  up.kind = MotionKind::Linear;
  up.velocity = Vec3(0.0, 0.5, 0.0);
  m.motions.push_back(up);
  m.attachments.push_back({0, pos[0], 0});  // kinematic: on its target at t_end in x_n and x~
  fem::add_fem_elements(m, {{0, 1, 2, 3}}, Material::StableNeoHookean, 200.0, 0.3);
  Constraint volume;
  volume.kind = ConstraintKind::Volume;
  volume.particles = {0, 1, 3, 4};
  volume.rest = 0.97 * tet_signed_volume(pos[0], pos[1], pos[3], pos[4]);
  volume.compliance = 1e-3;
  volume.damping = 0.2;
  m.constraints.push_back(volume);
  Constraint bend;
  bend.kind = ConstraintKind::Bending;
  bend.particles = {0, 1, 2, 4};
  bend.rest = dihedral_angle(pos[0], pos[1], pos[2], pos[4]) + 0.05;
  bend.compliance = 0.05;
  bend.damping = 0.1;
  m.constraints.push_back(bend);
  m.constraints.push_back(distance(2, 4, 0.98 * (pos[2] - pos[4]).norm(), 1e-3));

  GlobalProblem problem(m);
  ASSERT_EQ(problem.compliant().size(), m.constraints.size());
  ASSERT_EQ(problem.damped().size(), 2u);
  const double t_end = kStep;
  Points x_start = m.rest_positions;
  x_start.row(0) = attachment_target(m, m.attachments[0], t_end).transpose();
  Points v = chain_velocities(5);
  const Points x_pred = predict(m, x_start, v, kStep);
  problem.begin_step(x_start, x_pred, kStep, t_end, {});

  for (const std::string& method : kMethods) {
    SCOPED_TRACE(method);
    Points x = x_pred;
    std::vector<double> lambda;
    const GlobalResult r = solve_global_ceres(problem, ceres_options(method), x, lambda);
    EXPECT_TRUE(r.converged);
    EXPECT_LE(problem.residuals(x, lambda).position, kTolerance);
    EXPECT_EQ(x.row(0), x_start.row(0)) << "the kinematic particle stays on its target";
  }
}

// Every kind of term and row at once: a chain with a rigid link and its end predicted through a
// floor.
struct MixedStep {
  Model model;
  Points x_start, x_pred;
  std::vector<Contact> contacts;
};

MixedStep mixed_step() {
  MixedStep s;
  s.model = chain(4, 1e-4, true);
  s.model.constraints[1].compliance = 0.0;  // the second link rigid
  PlaneCollider floor;
  floor.normal = Vec3(0.0, 1.0, 0.0);
  floor.offset = -0.508;  // y >= 0.508 + r: the last particle starts 2 mm above it
  s.model.planes.push_back(floor);
  s.x_start = s.model.rest_positions;
  Points v = chain_velocities(5);
  v.row(4) << 0.0, -2.0, 0.0;  // and is predicted 2 cm through it
  s.x_pred = predict(s.model, s.x_start, v, kStep);
  s.contacts = {Contact{ContactKind::Plane, 4, 0}};
  return s;
}

TEST(GlobalCeres, MixedRowsConvergeWithTheRightSigns) {
  const MixedStep s = mixed_step();
  GlobalProblem problem(s.model);
  problem.begin_step(s.x_start, s.x_pred, kStep, kStep, s.contacts);
  ASSERT_EQ(problem.rows().size(), 2u);  // the rigid link, then the contact
  ASSERT_FALSE(problem.rows()[0].inequality);
  ASSERT_TRUE(problem.rows()[1].inequality);
  ASSERT_LT(s.x_pred(4, 1), 0.508 + 0.01);

  for (const std::string& method : kMethods) {
    SCOPED_TRACE(method);
    Points x = s.x_pred;
    std::vector<double> lambda(2, 0.0);
    const GlobalResult r = solve_global_ceres(problem, ceres_options(method), x, lambda);
    EXPECT_TRUE(r.converged);
    EXPECT_LE(r.residual, kTolerance);
    EXPECT_LE(std::abs((x.row(2) - x.row(1)).norm() - s.model.constraints[1].rest), kTolerance)
        << "the rigid link";
    EXPECT_LT(lambda[0], 0.0) << "the rigid link of a hanging chain is in tension";
    EXPECT_NEAR(x(4, 1), 0.508 + 0.01, kTolerance) << "the contact holds the end on the floor";
    EXPECT_GT(lambda[1], 0.0) << "the contact pushes";
    const GlobalProblem::Residuals res = problem.residuals(x, lambda);
    EXPECT_LE(res.position, kTolerance);
    EXPECT_EQ(res.position, r.residual);
  }
}

// ---------------------------------------------------------------------------------------------
// Bookkeeping.

TEST(GlobalCeres, HistoryAndCountsAreConsistent) {
  const MixedStep s = mixed_step();
  GlobalProblem problem(s.model);
  problem.begin_step(s.x_start, s.x_pred, kStep, kStep, s.contacts);
  for (const std::string& method : kMethods) {
    SCOPED_TRACE(method);
    Points x = s.x_pred;
    std::vector<double> lambda(2, 0.0);
    const double start = problem.residuals(x, lambda).position;
    const GlobalResult r = solve_global_ceres(problem, ceres_options(method), x, lambda);
    ASSERT_TRUE(r.converged);
    ASSERT_GE(r.history.size(), 2u);
    EXPECT_EQ(r.history[0].iteration, 0);
    EXPECT_EQ(r.history[0].inner_iterations, 0);
    EXPECT_EQ(r.history[0].residual, start);
    for (size_t k = 1; k < r.history.size(); ++k) {
      EXPECT_EQ(r.history[k].iteration, static_cast<int>(k));
      EXPECT_EQ(r.history[k].inner_iterations, static_cast<long>(k)) << "one entry per iteration";
      EXPECT_GE(r.history[k].time, r.history[k - 1].time);
    }
    EXPECT_EQ(r.inner_iterations, r.history.back().inner_iterations);
    EXPECT_EQ(r.history.back().residual, r.residual) << "the last entry is the solution";
    EXPECT_GE(r.iterations, 1);
    EXPECT_LE(r.iterations, r.inner_iterations);
    EXPECT_GE(r.linear_solves, 1);
    EXPECT_EQ(r.factorizations, r.linear_solves);
    EXPECT_GE(r.time_linear, 0.0);
    EXPECT_LE(r.time_linear, r.history.back().time + 1.0);
    EXPECT_GE(r.residual_h, 0.0);
    EXPECT_GE(r.residual_g, 0.0);
  }
}

TEST(GlobalCeres, IsDeterministic) {
  const MixedStep s = mixed_step();
  for (const std::string& method : kMethods) {
    SCOPED_TRACE(method);
    std::vector<Points> xs;
    std::vector<std::vector<double>> lambdas;
    std::vector<GlobalResult> results;
    for (int run = 0; run < 2; ++run) {
      GlobalProblem problem(s.model);  // a fresh problem each time
      problem.begin_step(s.x_start, s.x_pred, kStep, kStep, s.contacts);
      Points x = s.x_pred;
      std::vector<double> lambda(2, 0.0);
      results.push_back(solve_global_ceres(problem, ceres_options(method), x, lambda));
      xs.push_back(x);
      lambdas.push_back(lambda);
    }
    for (Eigen::Index i = 0; i < xs[0].size(); ++i)
      EXPECT_TRUE(same_bits(xs[0].data()[i], xs[1].data()[i])) << "x entry " << i;
    for (size_t r = 0; r < lambdas[0].size(); ++r)
      EXPECT_TRUE(same_bits(lambdas[0][r], lambdas[1][r])) << "lambda " << r;
    ASSERT_EQ(results[0].history.size(), results[1].history.size());
    for (size_t k = 0; k < results[0].history.size(); ++k)
      EXPECT_TRUE(same_bits(results[0].history[k].residual, results[1].history[k].residual));
    EXPECT_EQ(results[0].iterations, results[1].iterations);
    EXPECT_EQ(results[0].linear_solves, results[1].linear_solves);
  }
}

TEST(GlobalCeres, WarmStartAtTheSolutionTakesNoIteration) {
  const MixedStep s = mixed_step();
  GlobalProblem problem(s.model);
  problem.begin_step(s.x_start, s.x_pred, kStep, kStep, s.contacts);
  Points x = s.x_pred;
  std::vector<double> lambda(2, 0.0);
  ASSERT_TRUE(solve_global_ceres(problem, ceres_options(), x, lambda).converged);
  const Points x_solution = x;
  const GlobalResult again = solve_global_ceres(problem, ceres_options(), x, lambda);
  EXPECT_TRUE(again.converged);
  EXPECT_EQ(again.iterations, 0);
  EXPECT_EQ(again.inner_iterations, 0);
  EXPECT_EQ(again.history.size(), 1u);
  EXPECT_EQ(x, x_solution);
}

TEST(GlobalCeres, StopsAtTheIterationLimit) {
  // One iteration of one round cannot close a rigid row (after the first round C is about
  // eps lambda).
  const Vec3 pivot(0.0, 0.0, 0.0);
  Model m = particles({pivot, Vec3(0.0, -1.0, 0.0)}, {0.0, 1.0});
  m.constraints.push_back(distance(0, 1, 1.0, 0.0));
  GlobalProblem problem(m);
  Points x_pred = m.rest_positions;
  x_pred.row(1) << 0.3, -1.2, 0.0;
  problem.begin_step(m.rest_positions, x_pred, kStep, kStep, {});
  SolverOptions o = ceres_options();
  o.global_max_iterations = 1;
  Points x = x_pred;
  std::vector<double> lambda(1, 0.0);
  const GlobalResult r = solve_global_ceres(problem, o, x, lambda);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.iterations, 1);
  EXPECT_EQ(r.inner_iterations, 1);
  EXPECT_GT(r.residual, kTolerance);
  EXPECT_EQ(r.history.size(), 2u);
}

TEST(GlobalCeres, RefusesBadArguments) {
  const Model m = chain(2, 1e-3, false);
  GlobalProblem problem(m);
  problem.begin_step(m.rest_positions, m.rest_positions, kStep, kStep, {});
  Points x = m.rest_positions;
  std::vector<double> lambda;
  EXPECT_THROW(solve_global_ceres(problem, ceres_options("gauss_newton"), x, lambda),
               std::invalid_argument);
  std::vector<double> wrong(3, 0.0);
  EXPECT_THROW(solve_global_ceres(problem, ceres_options(), x, wrong), std::invalid_argument);
  Points short_x = x.topRows(2);
  EXPECT_THROW(solve_global_ceres(problem, ceres_options(), short_x, lambda),
               std::invalid_argument);
}

}  // namespace
}  // namespace pbdbench
