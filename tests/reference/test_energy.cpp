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
#include <functional>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/constraint_functions.hpp"
#include "core/fem.hpp"
#include "core/generators.hpp"
#include "core/psd_projection.hpp"
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

// A random hinge whose dihedral angle (acos(n1 . n2), pi when flat) is exactly theta up to the
// rounding of its construction (~1e-16 rad): with b = x3 - x0 = s R (x2 - x0) + t e, R the rotation
// by `sign` theta about the hinge e = x1 - x0 and s > 0, n2 = R n1. The signed angle phi of
// reference/energy.cpp (from n1 to -n2 about e) is then -sign (pi - theta).
Points hinge_at(Random& rng, double theta, double sign) {
  Points x(4, 3);
  x.row(0) = rng.vec(-1, 1).transpose();
  Vec3 e = rng.vec(-1, 1);
  while (e.norm() < 0.3) e = rng.vec(-1, 1);
  x.row(1) = x.row(0) + e.transpose();
  Vec3 a = rng.vec(-1, 1);
  while (e.normalized().cross(a).norm() < 0.3) a = rng.vec(-1, 1);
  x.row(2) = x.row(0) + a.transpose();
  const Eigen::AngleAxisd R(sign * theta, e.normalized());
  const Vec3 b = rng.uniform(0.5, 1.5) * (R * a) + rng.uniform(-0.5, 0.5) * e;
  x.row(3) = x.row(0) + b.transpose();
  return x;
}

// Hinges with a dihedral angle drawn from: anywhere in [0.3, pi - 0.3], within [0.02, 0.3] rad of
// flat (pi) or of closed (0) (where the derivatives of acos(n1 . n2) grow like 1 / sin(theta);
// those of the signed angle that U uses do not).
Points random_hinge(Random& rng, int n) {
  const double pi = std::numbers::pi;
  const double theta = n % 3 == 0 ? rng.uniform(0.3, pi - 0.3)
                       : n % 3 == 1 ? pi - rng.uniform(0.02, 0.3)
                                    : rng.uniform(0.02, 0.3);
  const double sign = rng.uniform() < 0.5 ? -1.0 : 1.0;
  return hinge_at(rng, theta, sign);
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
      // Hinges within 0.3 rad of flat or closed included: U's bending term is written through a
      // signed angle whose derivatives stay bounded there (no 1 / sin(theta)), so the default
      // step serves every kind (measured below). Within 0.02 rad of flat see
      // BendingGradientAndHessianMatchFiniteDifferencesNearFlat.
      const std::string what = check_hessian(E, q, worst);
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

// One bending term on four dynamic particles at x, with rest angle `rest` and compliance 0.05.
Model bending_model(const Points& x, double rest) {
  Model m;
  m.gravity = Vec3::Zero();
  m.rest_positions = x;
  m.inv_mass.assign(4, 1.0);
  m.radius.assign(4, 0.01);
  Constraint c;
  c.kind = ConstraintKind::Bending;
  c.particles = {0, 1, 2, 3};
  c.rest = rest;
  c.compliance = 0.05;
  m.constraints.push_back(c);
  return m;
}

// Fourth-order central differences, f' ~ (8 (f(q+h) - f(q-h)) - (f(q+2h) - f(q-2h))) / (12 h):
// truncation ~h^4 |f^(5)| / 30. Near flat with rest pi the gradient phi grad phi / alpha is as
// small as the distance from flat while the third derivative of U is not, so second-order
// differences (truncation h^2 |U'''| / 6) cannot check it there; fourth-order ones can.
Eigen::MatrixXd fd4_jacobian(const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f,
                             const Eigen::VectorXd& q, double h) {
  Eigen::MatrixXd J(f(q).size(), q.size());
  Eigen::VectorXd y = q;
  for (Eigen::Index j = 0; j < q.size(); ++j) {
    Eigen::VectorXd v[4];
    const double step[4] = {h, -h, 2 * h, -2 * h};
    for (int k = 0; k < 4; ++k) {
      y(j) = q(j) + step[k];
      v[k] = f(y);
    }
    y(j) = q(j);
    J.col(j) = (8.0 * (v[0] - v[1]) - (v[2] - v[3])) / (12.0 * h);
  }
  return J;
}

// sign(phi) = -sign(e . (a x b)) away from flat (reference/energy.cpp, signed_dihedral).
double phi_sign(const Points& x) {
  return tet_signed_volume(x.row(0), x.row(1), x.row(2), x.row(3)) > 0.0 ? -1.0 : 1.0;
}

TEST(EnergyModel, BendingGradientAndHessianMatchFiniteDifferencesNearFlat) {
  // Hinges 1e-8 ... 0.3 rad from flat, on both sides (phi > 0 and < 0), with rest angles pi (the
  // term is smooth through flat) and 2.5, 1.0 (C^2 has a kink at flat: the analytic values are
  // one-sided). Differences with h = 1e-5 cross flat for the hinges within ~1e-4 rad of it, so
  // they are taken of the term's smooth continuation from the side of q, s0 = sign(phi(q)):
  //   U~ = (c0 - s0 phi)^2 / (2 alpha),  c0 = pi - rest,
  // built from the model's own values: with U_pi, g_pi those of the same hinge with rest pi
  // (phi^2 / (2 alpha), phi grad phi / alpha) and s = sign(phi) at the displaced point,
  //   U~ = U + c0 (|phi| - s0 s |phi|) / alpha,  |phi| = sqrt(2 alpha U_pi),
  //   g~ = g_pi + s0 s (g - g_pi)
  // (both exactly U and g wherever s = s0, and for rest pi). Tolerance kDofTol, as for the other
  // terms. Measured, 40 hinges per line: at most 3e-4 of it, except the gradient 1e-8 rad from
  // flat with rest pi at 0.08: that gradient, phi grad phi / alpha, is proportional to phi,
  // which carries an absolute rounding of ~eps (e . (a x b) cancels near flat), a relative one
  // of ~eps / 1e-8 = 2e-8.
  const double pi = std::numbers::pi;
  Random rng(13);
  for (double distance : {1e-8, 1e-6, 1e-4, 1e-2, 0.3}) {
    for (double rest : {pi, 2.5, 1.0}) {
      double worst_g = 0.0, worst_h = 0.0;
      for (int n = 0; n < 40; ++n) {
        const Points x = hinge_at(rng, pi - distance, n % 2 == 0 ? 1.0 : -1.0);
        const Model m = bending_model(x, rest), m_pi = bending_model(x, pi);
        const EnergyModel E(m), E_pi(m_pi);
        const double alpha = m.constraints[0].compliance, c0 = pi - rest;
        const Eigen::VectorXd q = E.gather(x);
        const double s0 = phi_sign(x);
        const auto at = [&](const Eigen::VectorXd& y) {
          Points xy;
          E.positions(y, kTime, xy);
          return xy;
        };
        const auto U_smooth = [&](const Eigen::VectorXd& y) {
          const Points xy = at(y);
          const double abs_phi = std::sqrt(2.0 * alpha * E_pi.energy(xy));
          const double s = phi_sign(xy);
          Eigen::VectorXd r(1);
          r(0) = E.energy(xy) + c0 * (abs_phi - s0 * s * abs_phi) / alpha;
          return r;
        };
        const auto g_smooth = [&](const Eigen::VectorXd& y) {
          const Points xy = at(y);
          Eigen::VectorXd g, g_pi;
          E.gradient(xy, g);
          E_pi.gradient(xy, g_pi);
          return Eigen::VectorXd(g_pi + s0 * phi_sign(xy) * (g - g_pi));
        };
        Eigen::VectorXd g;
        E.gradient(x, g);
        std::vector<double> values;
        E.hessian(x, values);
        const Eigen::MatrixXd H = test::dense(E.hessian_pattern(), values);
        const Eigen::VectorXd fd_g = fd4_jacobian(U_smooth, q, 1e-5).row(0).transpose();
        const Eigen::MatrixXd fd_H = fd4_jacobian(g_smooth, q, 1e-5);
        const std::string what_g = test::compare(g, fd_g, test::kDofTol, &worst_g);
        const std::string what_h = test::compare(H, fd_H, test::kDofTol, &worst_h);
        EXPECT_TRUE(what_g.empty()) << distance << " rad from flat, rest " << rest << ", hinge " << n
                                    << ": gradient " << what_g << "; " << test::str(q);
        EXPECT_TRUE(what_h.empty()) << distance << " rad from flat, rest " << rest << ", hinge " << n
                                    << ": Hessian " << what_h << "; " << test::str(q);
      }
      std::printf("[ measured ] %g rad from flat, rest %.4g: largest |analytic - central difference| "
                  "/ tolerance: gradient %.3g, Hessian %.3g\n",
                  distance, rest, worst_g, worst_h);
    }
  }
}

TEST(EnergyModel, BendingProjectedHessianEqualsTheGeneralProjection) {
  // The bending term's projected block (psd::project_psd_hinge: an 8 x 8 eigen-solve past the
  // translations and the slide along the edge) against the general 12 x 12 eigen-clamp of its exact
  // block, on hinges 1e-8 ... 2.8 rad from flat on both sides, exactly flat (the block rank one,
  // semi-definite), nearly closed, with thin wings and with the tips projecting outside the edge;
  // rest angles pi, 2.5 and 1.0. And the null vector the hinge path relies on:
  // |H v| <= 1e-13 |H| |v|, v = (0, u, t1 u, t2 u).
  const double pi = std::numbers::pi;
  Random rng(29);
  double worst = 0.0, worst_null = 0.0;
  int indefinite = 0, hinges = 0;
  for (double distance : {0.0, 1e-8, 1e-4, 1e-2, 0.3, 1.5, 2.8, pi - 1e-3}) {
    for (double rest : {pi, 2.5, 1.0}) {
      for (int n = 0; n < 20; ++n) {
        Points x = hinge_at(rng, pi - distance, n % 2 == 0 ? 1.0 : -1.0);
        if (distance == 0.0) x.col(2).setZero();  // exactly flat: phi = 0
        const Vec3 e = x.row(1) - x.row(0);
        if (n % 5 == 3) x.row(2) = x.row(0) + 0.5 * e.transpose() + 1e-3 * (x.row(2) - x.row(0));  // a thin wing
        if (n % 5 == 4) x.row(3) += 3.0 * e.transpose();  // a tip beyond the edge
        const Model m = bending_model(x, rest);
        const EnergyModel E(m);
        std::vector<double> exact, projected;
        E.hessian(x, exact);
        E.hessian(x, projected, true);
        const Eigen::MatrixXd H = test::dense(E.hessian_pattern(), exact);
        const Eigen::MatrixXd Hp = test::dense(E.hessian_pattern(), projected);
        Eigen::Matrix<double, 12, 12> general = H;
        general = 0.5 * (general + general.transpose()).eval();
        psd::project_psd<12>(general);
        const double scale = H.cwiseAbs().maxCoeff();
        const double err = (Hp - general).cwiseAbs().maxCoeff() / scale;
        worst = std::max(worst, err);
        EXPECT_LE(err, 1e-13) << distance << " rad from flat, rest " << rest << ", hinge " << n;
        Eigen::Matrix<double, 12, 1> v = Eigen::Matrix<double, 12, 1>::Zero();
        const double t1 = (x.row(2) - x.row(0)).dot(e.transpose()) / e.squaredNorm();
        const double t2 = (x.row(3) - x.row(0)).dot(e.transpose()) / e.squaredNorm();
        v.segment<3>(3) = e.normalized();
        v.segment<3>(6) = t1 * e.normalized();
        v.segment<3>(9) = t2 * e.normalized();
        const double null = (H * v).norm() / (scale * v.norm());
        worst_null = std::max(worst_null, null);
        EXPECT_LE(null, 1e-13) << distance << " rad from flat, rest " << rest << ", hinge " << n;
        if (Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues()(0) < -1e-12 * scale) ++indefinite;
        ++hinges;
      }
    }
  }
  EXPECT_GE(indefinite, hinges / 2) << "the projection was not exercised";
  std::printf("[ measured ] %d hinges (%d indefinite): largest |hinge path - general| / |H| %.3g, "
              "|H v| / (|H| |v|) %.3g\n", hinges, indefinite, worst, worst_null);
}

TEST(EnergyModel, FlatBendingTermWithRestPiHasZeroGradientAndARankOneHessian) {
  // Exactly flat hinges (all four particles in the plane z = 0, so phi = 0 exactly) with rest
  // angle pi: C = 0, the gradient is exactly zero and the Hessian is grad phi grad phi^T / alpha,
  // finite, nonzero and PSD (rank 1), with grad phi written here from the geometry of the hinge:
  // moving a wing vertex at distance h_k from the hinge line along the wing's normal n_k turns
  // that wing about u = e / |e| by 1 / h_k per unit length,
  //   d phi/dx2 = -n1 / h1,  d phi/dx3 = n2 / h2,
  // and the hinge vertices take the rest in proportion to where the wing vertices project on the
  // hinge (t_k = 0 at x0, 1 at x1): d phi/dx1 = -t1 d phi/dx2 - t2 d phi/dx3, d phi/dx0 = -(sum).
  Random rng(14);
  double worst_diff = 0.0, worst_eig = 0.0;
  for (int n = 0; n < 20; ++n) {
    Points x(4, 3);
    for (int p = 0; p < 4; ++p) x.row(p) << rng.uniform(-1, 1), rng.uniform(-1, 1), 0.0;
    const Vec3 e = x.row(1) - x.row(0), a = x.row(2) - x.row(0), b = x.row(3) - x.row(0);
    const Vec3 eh = e.normalized();
    const Vec3 r1 = a - a.dot(eh) * eh, r2 = b - b.dot(eh) * eh;  // wing vertices off the hinge
    if (e.norm() < 0.3 || r1.norm() < 0.2 || r2.norm() < 0.2 || r1.dot(r2) > 0.0) {
      --n;  // thin wings, or both on one side of the hinge (closed, not flat)
      continue;
    }
    const Model m = bending_model(x, std::numbers::pi);
    const EnergyModel E(m);
    const double alpha = m.constraints[0].compliance;
    Eigen::VectorXd g;
    E.gradient(x, g);
    EXPECT_EQ(g.cwiseAbs().maxCoeff(), 0.0) << "hinge " << n;
    EXPECT_EQ(E.energy(x), 0.0) << "hinge " << n;
    const Vec3 n1 = e.cross(a).normalized(), n2 = e.cross(b).normalized();
    const Vec3 g2 = -n1 / r1.norm(), g3 = n2 / r2.norm();
    const double t1 = a.dot(e) / e.squaredNorm(), t2 = b.dot(e) / e.squaredNorm();
    const Vec3 g1 = -t1 * g2 - t2 * g3;
    fem::Vec12 gphi;
    gphi << -(g1 + g2 + g3), g1, g2, g3;
    const Eigen::MatrixXd expected = gphi * gphi.transpose() / alpha;
    std::vector<double> values;
    E.hessian(x, values);
    const Eigen::MatrixXd H = test::dense(E.hessian_pattern(), values);
    ASSERT_TRUE(H.allFinite());
    // The same products formed in two ways (kRoundoff of the largest entry); the eigenvalues of
    // a 12 x 12 to ~1e-15 of the largest (1e-12 allowed).
    const double diff = (H - expected).cwiseAbs().maxCoeff() / expected.cwiseAbs().maxCoeff();
    EXPECT_LE(diff, kRoundoff) << "hinge " << n;
    EXPECT_GT(H.cwiseAbs().maxCoeff(), 1.0) << "hinge " << n;
    const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues();
    const double others = std::max(-eig(0), std::abs(eig(10))) / eig(11);
    EXPECT_GE(eig(0), -1e-12 * eig(11)) << "hinge " << n << ": PSD";
    EXPECT_LE(std::abs(eig(10)), 1e-12 * eig(11)) << "hinge " << n << ": rank 1";
    EXPECT_NEAR(eig(11), gphi.squaredNorm() / alpha, 1e-12 * eig(11)) << "hinge " << n;
    worst_diff = std::max(worst_diff, diff);
    worst_eig = std::max(worst_eig, others);
  }
  std::printf("[ measured ] |H - grad phi grad phi^T / alpha| <= %.3g of its largest entry; other "
              "eigenvalues within %.3g of the largest\n",
              worst_diff, worst_eig);
}

TEST(EnergyModel, FlatBendingTermWithRestBelowPiTakesOneSidedValues) {
  // The flat hinge where the acos form has no gradient, with rest angle 2: the term is in U with
  // its gradient and Hessian from the side phi <= 0 (phi = -0 here, e . (a x b) = +0):
  // C = pi - 2, grad C = -s grad phi = grad phi, Hessian (grad phi grad phi^T + C hess phi) / alpha.
  // grad phi: d/dx2 = -n1 / 1 = (0, 0, -1), d/dx3 = n2 / 1 = (0, 0, -1) (n1 = z, n2 = -z, both
  // wings 1 from the hinge), d/dx0 = d/dx1 = (0, 0, 1) (t1 = t2 = 1/2).
  Points x(4, 3);
  x << 0, 0, 0, 1, 0, 0, 0.5, 1, 0, 0.5, -1, 0;
  const Model m = bending_model(x, 2.0);
  ASSERT_FALSE(eval_constraint(m.constraints[0], x).valid) << "the acos form's gradient is undefined here";
  const EnergyModel E(m);
  const double C = std::numbers::pi - 2.0, alpha = m.constraints[0].compliance;
  EXPECT_NEAR(E.energy(x), C * C / (2.0 * alpha), kRoundoff);
  Eigen::VectorXd g;
  E.gradient(x, g);
  Eigen::VectorXd expected(12);
  expected << 0, 0, 1, 0, 0, 1, 0, 0, -1, 0, 0, -1;
  EXPECT_LE((g - C / alpha * expected).cwiseAbs().maxCoeff(), kRoundoff * C / alpha) << g.transpose();
  std::vector<double> values;
  E.hessian(x, values);
  const Eigen::MatrixXd H = test::dense(E.hessian_pattern(), values);
  EXPECT_TRUE(H.allFinite());
  EXPECT_GT(H.cwiseAbs().maxCoeff(), 1.0);
}

TEST(EnergyModel, BendingTermWithADegenerateWingContributesOnlyItsEnergy) {
  // x2 on the hinge line: wing 1 has no normal and the angle no gradient (valid = false, as in
  // eval_bending); the term is in U with the angle taken as 0 (C = -rest) and contributes no
  // gradient or Hessian.
  Points x(4, 3);
  x << 0, 0, 0, 1, 0, 0, 0.5, 0, 0, 0.5, -1, 0;
  const Model m = bending_model(x, 2.0);
  ASSERT_FALSE(eval_constraint(m.constraints[0], x).valid);
  const EnergyModel E(m);
  EXPECT_NEAR(E.energy(x), 2.0 * 2.0 / (2.0 * m.constraints[0].compliance), kRoundoff);
  Eigen::VectorXd g;
  E.gradient(x, g);
  EXPECT_EQ(g.cwiseAbs().maxCoeff(), 0.0);
  std::vector<double> values;
  E.hessian(x, values);
  EXPECT_EQ(*std::max_element(values.begin(), values.end()), 0.0);
  EXPECT_EQ(*std::min_element(values.begin(), values.end()), 0.0);
}

TEST(EnergyModel, BendingAngleAgreesWithTheAcosFormUpToItsRounding) {
  // The angle in U (pi - |phi|, atan2) against acos(n1 . n2) (dihedral_angle, eval_bending) and
  // against the angle the hinge was built with, at distances from flat. Near flat acos loses
  // digits: n1 . n2 = -cos(delta) carries rounding ~eps, and acos turns it into ~eps / delta of
  // angle; the atan2 form keeps ~eps. |phi| is read from U with rest pi: U = phi^2 / (2 alpha).
  const double pi = std::numbers::pi;
  Random rng(15);
  for (double distance : {1e-8, 1e-6, 1e-4, 1e-2, 0.3}) {
    double worst_atan2 = 0.0, worst_acos = 0.0;
    for (int n = 0; n < 200; ++n) {
      const Points x = hinge_at(rng, pi - distance, n % 2 == 0 ? 1.0 : -1.0);
      const Model m = bending_model(x, pi);
      const EnergyModel E(m);
      const double abs_phi = std::sqrt(2.0 * m.constraints[0].compliance * E.energy(x));
      const double acos_distance = pi - dihedral_angle(x.row(0), x.row(1), x.row(2), x.row(3));
      worst_atan2 = std::max(worst_atan2, std::abs(abs_phi - distance));
      worst_acos = std::max(worst_acos, std::abs(acos_distance - abs_phi));
    }
    const double eps = std::numeric_limits<double>::epsilon();
    std::printf("[ measured ] %g rad from flat: |angle in U - built angle| <= %.3g rad, "
                "|acos form - angle in U| <= %.3g rad = %.3g eps / distance\n",
                distance, worst_atan2, worst_acos, worst_acos * distance / eps);
    // Measured: the angle in U within 1.1e-15 rad (5 eps, the hinge's construction rounds too) of
    // the built one at every distance; acos within 1.3 eps / distance of it (1.6e-8 at 1e-8 rad,
    // where acos can only return pi or pi - 1.5e-8, the acos of the doubles nearest -1).
    EXPECT_LE(worst_atan2, 20 * eps) << distance << " rad from flat";
    EXPECT_LE(worst_acos, 4 * eps / distance + 20 * eps) << distance << " rad from flat";
  }
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
