// Tests of reference/energy: the dof maps, the energy against its terms computed independently,
// the assembled gradient and Hessian against finite differences on random models mixing every
// term (and each kind of term alone, over many configurations), the fixed symmetric pattern, the
// PSD projection, damping against its definition, constraint forces, and the model checks.
#include "reference/energy.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/constraint_functions.hpp"
#include "core/fem.hpp"
#include "core/generators.hpp"
#include "tests/reference/energy_fixtures.hpp"

namespace pbdbench {
namespace {

using test::Random;

constexpr int kRandomModels = 20;  // random mixed models per test
constexpr double kTime = 0.37;     // s, a time at which the kinematic particles have moved

// Computations that differ only by rounding and summation order, relative to the sum of the
// magnitudes of the terms.
constexpr double kRoundoff = 1e-12;

TEST(EnergyModel, DofMapsMassesAndRigidConstraints) {
  Random rng(1);
  const Model m = test::random_model(rng);
  const EnergyModel E(m);
  ASSERT_EQ(E.dofs(), 3 * (test::kRandomParticles + 1 - 4));
  ASSERT_EQ(E.mass().size(), E.dofs());
  for (size_t k = 0; k < E.dynamic_particles().size(); ++k) {
    const int p = E.dynamic_particles()[k];
    EXPECT_GT(m.inv_mass[static_cast<size_t>(p)], 0.0);
    for (int a = 0; a < 3; ++a)
      EXPECT_DOUBLE_EQ(E.mass()(3 * static_cast<Eigen::Index>(k) + a), 1.0 / m.inv_mass[static_cast<size_t>(p)]);
    if (k > 0) {
      EXPECT_LT(E.dynamic_particles()[k - 1], p) << "dofs in particle order";
    }
  }
  // The one rigid constraint (the last before the FEM-kind ones) and nothing else.
  ASSERT_EQ(E.rigid_constraints().size(), 1u);
  EXPECT_EQ(m.constraints[static_cast<size_t>(E.rigid_constraints()[0])].compliance, 0.0);

  // positions / velocities / gather.
  const Eigen::VectorXd q = test::random_q(rng, E, m);
  Eigen::VectorXd u(E.dofs());
  for (Eigen::Index i = 0; i < u.size(); ++i) u(i) = rng.uniform(-1, 1);
  Points x, v;
  E.positions(q, kTime, x);
  E.velocities(u, kTime, v);
  EXPECT_EQ(E.gather(x), q);
  EXPECT_EQ(E.gather(v), u);
  EXPECT_EQ(Vec3(x.row(test::kPinned)), Vec3(m.rest_positions.row(test::kPinned)));
  EXPECT_EQ(Vec3(v.row(test::kPinned)), Vec3::Zero());
  for (const Attachment& a : m.attachments) {
    EXPECT_EQ(Vec3(x.row(a.particle)), attachment_target(m, a, kTime)) << "particle " << a.particle;
    const Vec3 va = a.motion < 0 ? Vec3::Zero() : motion_velocity(m.motions[static_cast<size_t>(a.motion)], kTime);
    EXPECT_EQ(Vec3(v.row(a.particle)), va) << "particle " << a.particle;
  }
  EXPECT_NE(Vec3(x.row(test::kLinearTarget)), Vec3(m.rest_positions.row(test::kLinearTarget)))
      << "the linear target has moved by t = " << kTime;
}

TEST(EnergyModel, EnergyIsTheSumOfItsTermsComputedIndependently) {
  Random rng(2);
  for (int n = 0; n < kRandomModels; ++n) {
    const Model m = test::random_model(rng);
    const EnergyModel E(m);
    Points x;
    E.positions(test::random_q(rng, E, m), kTime, x);
    double sum = 0.0, magnitude = 0.0;
    for (const Constraint& c : m.constraints) {
      if (is_fem_kind(c.kind) || c.compliance == 0.0) continue;
      const auto& p = c.particles;
      double C = 0.0;
      if (c.kind == ConstraintKind::Distance) C = (x.row(p[1]) - x.row(p[0])).norm() - c.rest;
      if (c.kind == ConstraintKind::Volume)
        C = tet_signed_volume(x.row(p[0]), x.row(p[1]), x.row(p[2]), x.row(p[3])) - c.rest;
      if (c.kind == ConstraintKind::Bending)
        C = dihedral_angle(x.row(p[0]), x.row(p[1]), x.row(p[2]), x.row(p[3])) - c.rest;
      sum += C * C / (2.0 * c.compliance);
      magnitude += C * C / (2.0 * c.compliance);
    }
    for (const FemElement& e : m.elements) {
      const Mat3 F = fem::deformation_gradient(e, x);
      const double term = e.rest_volume * (fem::energy_density(e.material, e.mu, e.lambda, F) -
                                           fem::energy_density(e.material, e.mu, e.lambda, Mat3::Identity()));
      sum += term;
      magnitude += std::abs(term);
    }
    for (int p = 0; p < m.particle_count(); ++p) {
      const double w = m.inv_mass[static_cast<size_t>(p)];
      if (w == 0.0) continue;
      const double term = -(1.0 / w) * m.gravity.dot(Vec3(x.row(p)));
      sum += term;
      magnitude += std::abs(term);
    }
    EXPECT_NEAR(E.energy(x), sum, kRoundoff * magnitude) << "model " << n;
  }
}

TEST(EnergyModel, GradientMatchesFiniteDifferences) {
  Random rng(3);
  double worst = 0.0;
  for (int n = 0; n < kRandomModels; ++n) {
    const Model m = test::random_model(rng);
    const EnergyModel E(m);
    const Eigen::VectorXd q = test::random_q(rng, E, m);
    Points x;
    E.positions(q, kTime, x);
    Eigen::VectorXd g;
    E.gradient(x, g);
    const Eigen::VectorXd fd = test::fd_gradient(
        [&](const Eigen::VectorXd& y) {
          Points xy;
          E.positions(y, kTime, xy);
          return E.energy(xy);
        },
        q);
    const std::string what = test::compare(g, fd, test::kDofTol, &worst);
    EXPECT_TRUE(what.empty()) << "model " << n << ": " << what << "; " << test::str(q);
  }
  std::printf("[ measured ] largest |analytic - central difference| / tolerance: %.3g\n", worst);
}

// The assembled Hessian against central differences of the assembled gradient: every entry,
// those outside the pattern included (they must be zero), so this also checks that the pattern
// holds every coupling.
std::string check_hessian(const EnergyModel& E, const Eigen::VectorXd& q, double& worst,
                          double h = test::kDofStep) {
  Points x;
  E.positions(q, kTime, x);
  std::vector<double> values;
  E.hessian(x, values);
  const Eigen::MatrixXd H = test::dense(E.hessian_pattern(), values);
  const Eigen::MatrixXd fd = test::fd_jacobian(
      [&](const Eigen::VectorXd& y) {
        Points xy;
        E.positions(y, kTime, xy);
        Eigen::VectorXd g;
        E.gradient(xy, g);
        return g;
      },
      q, h);
  return test::compare(H, fd, test::kDofTol, &worst);
}

TEST(EnergyModel, HessianMatchesFiniteDifferences) {
  Random rng(4);
  double worst = 0.0;
  for (int n = 0; n < kRandomModels; ++n) {
    const Model m = test::random_model(rng);
    const EnergyModel E(m);
    const Eigen::VectorXd q = test::random_q(rng, E, m);
    const std::string what = check_hessian(E, q, worst);
    EXPECT_TRUE(what.empty()) << "model " << n << ": " << what << "; " << test::str(q);
  }
  std::printf("[ measured ] largest |analytic - central difference| / tolerance: %.3g\n", worst);
}

// One term alone on four dynamic particles, and a configuration q for it.
struct SingleTerm {
  Model model;
  Points x;  // (4 x 3) m, where to check
};

// Hinges with a dihedral angle drawn from: anywhere in [0.3, pi - 0.3], within [0.02, 0.3] rad of
// flat (pi) or of closed (0), where the angle's curvature grows like 1/sin(theta).
// With b = x3 - x0 = s R(phi) (x2 - x0) + t e (R a rotation about the hinge e = x1 - x0, s > 0),
// n2 = R(phi) n1 and the angle is exactly |phi|.
Points random_hinge(Random& rng, int n) {
  Points x(4, 3);
  x.row(0) = rng.vec(-1, 1).transpose();
  Vec3 e = rng.vec(-1, 1);
  while (e.norm() < 0.3) e = rng.vec(-1, 1);
  x.row(1) = x.row(0) + e.transpose();
  Vec3 a = rng.vec(-1, 1);
  while (e.normalized().cross(a).norm() < 0.3) a = rng.vec(-1, 1);
  x.row(2) = x.row(0) + a.transpose();
  const double pi = std::numbers::pi;
  const double phi = n % 3 == 0 ? rng.uniform(0.3, pi - 0.3)
                     : n % 3 == 1 ? pi - rng.uniform(0.02, 0.3)
                                  : rng.uniform(0.02, 0.3);
  const Eigen::AngleAxisd R((rng.uniform() < 0.5 ? -1.0 : 1.0) * phi, e.normalized());
  const Vec3 b = rng.uniform(0.5, 1.5) * (R * a) + rng.uniform(-0.5, 0.5) * e;
  x.row(3) = x.row(0) + b.transpose();
  return x;
}

SingleTerm single_term(Random& rng, const std::string& kind, int n) {
  SingleTerm t;
  Model& m = t.model;
  m.gravity = Vec3::Zero();
  m.inv_mass.assign(4, 1.0);
  m.radius.assign(4, 0.01);
  m.rest_positions.resize(4, 3);
  for (;;) {
    for (int p = 0; p < 4; ++p) m.rest_positions.row(p) = rng.vec(-1, 1).transpose();
    const double v = tet_signed_volume(m.rest_positions.row(0), m.rest_positions.row(1),
                                       m.rest_positions.row(2), m.rest_positions.row(3));
    if (std::abs(v) < 0.02) continue;  // a thin tet: F would be large for small motions
    if (v < 0.0) m.rest_positions.row(1).swap(m.rest_positions.row(2));
    break;
  }
  t.x = m.rest_positions;
  for (int p = 0; p < 4; ++p) t.x.row(p) += 0.3 * rng.vec(-1, 1).transpose();
  if (kind == "snh" || kind == "corotated") {
    fem::add_fem_elements(m, {{0, 1, 2, 3}}, kind == "snh" ? Material::StableNeoHookean : Material::Corotated,
                          10.0, 0.35);
    return t;
  }
  Constraint c;
  c.particles = {0, 1, 2, 3};
  c.compliance = 0.05;
  if (kind == "distance") {
    c.kind = ConstraintKind::Distance;
    c.rest = rng.uniform(0.2, 2.0);
  } else if (kind == "volume") {
    c.kind = ConstraintKind::Volume;
    c.rest = rng.uniform(-0.2, 0.2);
  } else {
    c.kind = ConstraintKind::Bending;
    c.rest = rng.uniform(0.0, std::numbers::pi);
    t.x = random_hinge(rng, n);
  }
  m.constraints.push_back(c);
  return t;
}

TEST(EnergyModel, HessianOfEachKindMatchesFiniteDifferences) {
  // Each kind of term alone: the bending Hessian (written analytically in reference/energy.cpp)
  // against central differences of the analytic gradient, and the others, over many
  // configurations.
  Random rng(5);
  for (const char* kind : {"distance", "volume", "bending", "snh", "corotated"}) {
    double worst = 0.0;
    for (int n = 0; n < 300; ++n) {
      const SingleTerm t = single_term(rng, kind, n);
      const EnergyModel E(t.model);
      const Eigen::VectorXd q = E.gather(t.x);
      // Hinges within 0.3 rad of flat or closed: the analytic gradient of acos(n1 . n2) carries
      // rounding of relative size ~eps / sin^2(theta) (up to ~3e-13 at 0.02 rad), which central
      // differences with h = 1e-6 amplify to ~2e-7 of the largest entry (measured), above
      // kDofTol. A step of 1e-5 divides that by 10, while the truncation error h^2 |g'''| stays
      // below 1e-8 of the largest entry there (measured: 4e-9 at 0.02 rad).
      const bool near_singular = std::string(kind) == "bending" && n % 3 != 0;
      const std::string what = check_hessian(E, q, worst, near_singular ? 1e-5 : test::kDofStep);
      EXPECT_TRUE(what.empty()) << kind << ", configuration " << n << ": " << what << "; "
                                << test::str(q) << ", rest "
                                << (t.model.constraints.empty() ? 0.0 : t.model.constraints[0].rest);
      // One term: the projected assembly is the eigenvalue-clamped exact one.
      std::vector<double> exact, projected;
      E.hessian(t.x, exact);
      E.hessian(t.x, projected, true);
      const Eigen::MatrixXd H = test::dense(E.hessian_pattern(), exact);
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(H);
      const Eigen::MatrixXd clamped = eig.eigenvectors() *
                                      eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
                                      eig.eigenvectors().transpose();
      // Two eigen-decompositions of the same 12 x 12: ~1e-14 of its largest entry apart.
      EXPECT_LE((test::dense(E.hessian_pattern(), projected) - clamped).cwiseAbs().maxCoeff(),
                1e-11 * H.cwiseAbs().maxCoeff())
          << kind << ", configuration " << n << ": projection";
    }
    std::printf("[ measured ] %s: largest |analytic - central difference| / tolerance: %.3g\n", kind, worst);
  }
}

TEST(EnergyModel, BendingTermWithUndefinedGradientContributesOnlyItsEnergy) {
  // An exactly flat hinge (theta = pi, where acos has no derivative) with rest angle 2: the term
  // C^2 / (2 alpha) is in U, but its gradient and Hessian are left out (valid = false).
  Model m;
  m.gravity = Vec3::Zero();
  m.rest_positions.resize(4, 3);
  m.rest_positions << 0, 0, 0, 1, 0, 0, 0.5, 1, 0, 0.5, -1, 0;
  m.inv_mass.assign(4, 1.0);
  m.radius.assign(4, 0.01);
  Constraint c;
  c.kind = ConstraintKind::Bending;
  c.particles = {0, 1, 2, 3};
  c.rest = 2.0;
  c.compliance = 0.1;
  m.constraints.push_back(c);
  ASSERT_FALSE(eval_constraint(c, m.rest_positions).valid);
  const EnergyModel E(m);
  const double C = std::numbers::pi - 2.0;
  EXPECT_NEAR(E.energy(m.rest_positions), C * C / (2.0 * c.compliance), kRoundoff);
  Eigen::VectorXd g;
  E.gradient(m.rest_positions, g);
  EXPECT_EQ(g.cwiseAbs().maxCoeff(), 0.0);
  std::vector<double> values;
  E.hessian(m.rest_positions, values);
  EXPECT_EQ(*std::max_element(values.begin(), values.end()), 0.0);
  EXPECT_EQ(*std::min_element(values.begin(), values.end()), 0.0);
}

TEST(EnergyModel, PatternIsFixedSymmetricAndHasTheDiagonal) {
  Random rng(6);
  const Model m = test::random_model(rng);
  const EnergyModel E(m);
  const SparsityPattern p = E.hessian_pattern();  // a copy
  ASSERT_EQ(p.n, E.dofs());
  ASSERT_EQ(static_cast<int>(p.column_start.size()), p.n + 1);
  EXPECT_EQ(p.column_start.front(), 0);
  EXPECT_EQ(p.column_start.back(), p.nnz());
  for (int c = 0; c < p.n; ++c) {
    EXPECT_GE(p.find(c, c), 0) << "diagonal " << c;
    for (std::int64_t k = p.column_start[static_cast<size_t>(c)]; k < p.column_start[static_cast<size_t>(c) + 1]; ++k) {
      const int r = static_cast<int>(p.row[static_cast<size_t>(k)]);
      if (k > p.column_start[static_cast<size_t>(c)]) {
        EXPECT_LT(p.row[static_cast<size_t>(k) - 1], r) << "sorted, column " << c;
      }
      EXPECT_EQ(p.find(r, c), k);
      EXPECT_GE(p.find(c, r), 0) << "(" << r << ", " << c << ") without its transpose";
    }
  }
  EXPECT_EQ(p.find(-1, 0), -1);
  EXPECT_EQ(p.find(0, p.n), -1);

  for (int n = 0; n < 5; ++n) {
    Points x;
    E.positions(test::random_q(rng, E, m, 1.0), rng.uniform(0, 2), x);
    std::vector<double> values, damping;
    E.hessian(x, values);
    E.damping_matrix(x, damping);
    ASSERT_EQ(static_cast<std::int64_t>(values.size()), p.nnz());
    ASSERT_EQ(static_cast<std::int64_t>(damping.size()), p.nnz());
    const Eigen::MatrixXd H = test::dense(E.hessian_pattern(), values);
    EXPECT_LE((H - H.transpose()).cwiseAbs().maxCoeff(), kRoundoff * H.cwiseAbs().maxCoeff());
    // Same pattern for any x.
    EXPECT_EQ(E.hessian_pattern().column_start, p.column_start);
    EXPECT_EQ(E.hessian_pattern().row, p.row);
  }
}

TEST(EnergyModel, ProjectedHessianIsPsdAndExactAtRest) {
  Random rng(7);
  int indefinite = 0;
  for (int n = 0; n < kRandomModels; ++n) {
    const Model m = test::random_model(rng);
    const EnergyModel E(m);
    Points x;
    E.positions(test::random_q(rng, E, m, 0.5), kTime, x);
    std::vector<double> exact, projected;
    E.hessian(x, exact);
    E.hessian(x, projected, true);
    const Eigen::MatrixXd H = test::dense(E.hessian_pattern(), exact);
    const Eigen::MatrixXd Hp = test::dense(E.hessian_pattern(), projected);
    const double tiny = 1e-12 * Hp.cwiseAbs().maxCoeff() * Hp.rows();
    const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Hp).eigenvalues();
    EXPECT_GE(eig(0), -tiny) << "model " << n;
    const double exact_min = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues()(0);
    if (exact_min < -tiny) ++indefinite;
  }
  EXPECT_GE(indefinite, kRandomModels / 2) << "the projection was not exercised";
  // At the rest state every term is at its minimum and its Hessian PSD: the projection is the
  // identity there.
  for (int n = 0; n < kRandomModels; ++n) {
    test::RandomModelOptions o;
    o.at_rest = true;
    const Model m = test::random_model(rng, o);
    const EnergyModel E(m);
    std::vector<double> exact, projected;
    E.hessian(m.rest_positions, exact);
    E.hessian(m.rest_positions, projected, true);
    const Eigen::MatrixXd H = test::dense(E.hessian_pattern(), exact);
    const Eigen::MatrixXd Hp = test::dense(E.hessian_pattern(), projected);
    // Eigen-decompositions of 12 x 12 blocks reproduce them to ~1e-14 of their largest entry.
    EXPECT_LE((Hp - H).cwiseAbs().maxCoeff(), 1e-11 * H.cwiseAbs().maxCoeff()) << "model " << n;
  }
}

TEST(EnergyModel, DampingForceAndMatrixMatchTheirDefinitions) {
  Random rng(8);
  int damped_models = 0;
  for (int n = 0; n < kRandomModels; ++n) {
    test::RandomModelOptions o;
    o.damping = true;
    const Model m = test::random_model(rng, o);
    const EnergyModel E(m);
    const Eigen::VectorXd q = test::random_q(rng, E, m);
    Eigen::VectorXd u(E.dofs());
    for (Eigen::Index i = 0; i < u.size(); ++i) u(i) = rng.uniform(-1, 1);
    Points x, v;
    E.positions(q, kTime, x);
    E.velocities(u, kTime, v);
    if (E.has_damping()) ++damped_models;

    // Definition: f_d = -sum over constraints (compliant or FEM-kind) of beta grad C (grad C . v),
    // D = sum beta grad C grad C^T over the dofs.
    const int n_dofs = E.dofs();
    Eigen::VectorXd f_def = Eigen::VectorXd::Zero(n_dofs);
    Eigen::MatrixXd D_def = Eigen::MatrixXd::Zero(n_dofs, n_dofs);
    double scale = 0.0;
    for (const Constraint& c : m.constraints) {
      if (c.damping == 0.0 || c.compliance == 0.0) continue;
      const ConstraintEval ev = eval_constraint(m, c, x);
      ASSERT_TRUE(ev.valid);
      Eigen::VectorXd g = Eigen::VectorXd::Zero(n_dofs);
      double rate = 0.0;
      for (int i = 0; i < arity(c.kind); ++i) {
        const int p = c.particles[static_cast<size_t>(i)];
        rate += ev.grad[static_cast<size_t>(i)].dot(Vec3(v.row(p)));
        const auto it = std::find(E.dynamic_particles().begin(), E.dynamic_particles().end(), p);
        if (it != E.dynamic_particles().end())
          g.segment<3>(3 * (it - E.dynamic_particles().begin())) += ev.grad[static_cast<size_t>(i)];
      }
      f_def -= c.damping * rate * g;
      D_def += c.damping * g * g.transpose();
      scale += c.damping * g.squaredNorm() * (1.0 + std::abs(rate));
    }
    Eigen::VectorXd f;
    E.damping_force(x, v, f);
    std::vector<double> values;
    E.damping_matrix(x, values);
    const Eigen::MatrixXd D = test::dense(E.hessian_pattern(), values);
    EXPECT_LE((f - f_def).cwiseAbs().maxCoeff(), kRoundoff * scale) << "model " << n;
    EXPECT_LE((D - D_def).cwiseAbs().maxCoeff(), kRoundoff * scale) << "model " << n;
    // f_d = -D u plus the drag of the moving targets, which does not depend on u.
    Points v0;
    E.velocities(Eigen::VectorXd::Zero(n_dofs), kTime, v0);
    Eigen::VectorXd f0;
    E.damping_force(x, v0, f0);
    EXPECT_LE((f - f0 + D * u).cwiseAbs().maxCoeff(), kRoundoff * scale) << "model " << n;
    EXPECT_EQ(E.has_damping(), D_def.cwiseAbs().maxCoeff() > 0.0);
  }
  EXPECT_GT(damped_models, kRandomModels / 2);
  // Without damped constraints: nothing.
  Random rng2(9);
  const Model m = test::random_model(rng2);
  const EnergyModel E(m);
  EXPECT_FALSE(E.has_damping());
  Points x, v;
  E.positions(test::random_q(rng2, E, m), kTime, x);
  E.velocities(Eigen::VectorXd::Ones(E.dofs()), kTime, v);
  Eigen::VectorXd f;
  E.damping_force(x, v, f);
  EXPECT_EQ(f.size(), E.dofs());
  EXPECT_EQ(f.cwiseAbs().maxCoeff(), 0.0);
}

TEST(EnergyModel, ConstraintForcesAreMinusCOverAlphaForCompliantConstraintsOnly) {
  Random rng(10);
  const Model m = test::random_model(rng);
  const EnergyModel E(m);
  Points x;
  E.positions(test::random_q(rng, E, m), kTime, x);
  const double sentinel = 12345.0;
  std::vector<double> lambda(static_cast<size_t>(m.constraint_count()), sentinel);
  E.constraint_forces(x, lambda);
  for (int j = 0; j < m.constraint_count(); ++j) {
    const Constraint& c = m.constraints[static_cast<size_t>(j)];
    if (is_fem_kind(c.kind) || c.compliance == 0.0)
      EXPECT_EQ(lambda[static_cast<size_t>(j)], sentinel) << "constraint " << j << " was touched";
    else
      EXPECT_NEAR(lambda[static_cast<size_t>(j)], -eval_constraint(c, x).C / c.compliance,
                  kRoundoff * std::abs(lambda[static_cast<size_t>(j)]))
          << "constraint " << j;
  }
  // The compliant constraints' forces are those of U: sum_j grad C_j lambda_j = -dU_c/dq.
}

TEST(EnergyModel, RefusesWhatTheEnergyCannotExpressByName) {
  Random rng(11);
  const Model base = test::random_model(rng);
  const auto expect_refused = [](const Model& m, const std::string& fragment) {
    try {
      const EnergyModel E(m);
      ADD_FAILURE() << "accepted; expected a refusal naming '" << fragment << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  {
    Model m = base;
    m.constraints[3].compliance = -1.0;
    expect_refused(m, "constraint 3 (distance): compliance -1");
  }
  {
    Model m = base;
    m.constraints[2].damping = -0.5;
    expect_refused(m, "constraint 2 (distance): damping -0.5");
  }
  {
    Model m = base;
    m.inv_mass[static_cast<size_t>(test::kStaticTarget)] = 1.0;
    expect_refused(m, "attachment 0: particle 1");
  }
  {
    Model m = base;
    for (Constraint& c : m.constraints)
      if (is_fem_kind(c.kind)) {
        c.element = 99;
        break;
      }
    expect_refused(m, "element 99 is out of range");
  }
  {
    Model m = base;
    m.elements[1].rest_volume = 0.0;
    expect_refused(m, "element 1: rest volume 0");
  }
  {
    Model m = base;
    m.constraints[0].particles[1] = 1000;
    expect_refused(m, "constraint 0 (distance): particle 1000");
  }
}

// The cost of one Hessian assembly on a block of ~100k tets (not a check: run with
// --gtest_also_run_disabled_tests to measure). 40 x 20 x 21 cells, 6 tets each = 100,800 tets.
TEST(EnergyModel, DISABLED_HessianAssemblyTimeOn100kTets) {
  for (Material material : {Material::StableNeoHookean, Material::Corotated}) {
    Model m;
    TetBlockSpec spec;
    spec.cells = {40, 20, 21};
    spec.size = Vec3(4.0, 2.0, 2.1);
    spec.edges = false;
    spec.volumes = false;
    add_tet_block(m, spec);
    fem::add_fem_elements(m, m.tets, material, 1e6, 0.3);
    for (int p = 0; p < m.particle_count(); ++p)
      if (m.rest_positions(p, 0) == 0.0) m.inv_mass[static_cast<size_t>(p)] = 0.0;  // clamp x = 0
    const auto t0 = std::chrono::steady_clock::now();
    const EnergyModel E(m);
    const auto t1 = std::chrono::steady_clock::now();
    Random rng(12);
    Points x = m.rest_positions;
    for (int p = 0; p < x.rows(); ++p) x.row(p) += 0.01 * rng.vec(-1, 1).transpose();
    std::vector<double> values;
    E.hessian(x, values);  // first call allocates values
    double best = 1e300, best_psd = 1e300, best_grad = 1e300;
    Eigen::VectorXd g;
    for (int r = 0; r < 5; ++r) {
      auto a = std::chrono::steady_clock::now();
      E.hessian(x, values);
      auto b = std::chrono::steady_clock::now();
      best = std::min(best, std::chrono::duration<double>(b - a).count());
      a = std::chrono::steady_clock::now();
      E.hessian(x, values, true);
      b = std::chrono::steady_clock::now();
      best_psd = std::min(best_psd, std::chrono::duration<double>(b - a).count());
      a = std::chrono::steady_clock::now();
      E.gradient(x, g);
      b = std::chrono::steady_clock::now();
      best_grad = std::min(best_grad, std::chrono::duration<double>(b - a).count());
    }
    std::printf("[ measured ] %s, %zu tets, %d dofs, nnz %lld: setup %.3f s; Hessian %.4f s, "
                "projected %.4f s, gradient %.4f s (best of 5)\n",
                to_string(material), m.elements.size(), E.dofs(),
                static_cast<long long>(E.hessian_pattern().nnz()),
                std::chrono::duration<double>(t1 - t0).count(), best, best_psd, best_grad);
  }
}

}  // namespace
}  // namespace pbdbench
