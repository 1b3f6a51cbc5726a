// Tests of solvers/kernels.hpp: the projection kernels in isolation.
#include <gtest/gtest.h>

#include <cmath>

#include "core/constraint_functions.hpp"
#include "solver_test_util.hpp"
#include "solvers/kernels.hpp"

namespace pbdbench::test {
namespace {

// A random configuration of a constraint of each kind, with random inverse masses.
struct Config {
  std::array<Vec3, 4> x;
  Weights w{};
  int count = 0;
  ConstraintEval e;
};

Config random_config(Random& rng, ConstraintKind kind) {
  Config c;
  c.count = arity(kind);
  for (int i = 0; i < 4; ++i) {
    c.x[static_cast<size_t>(i)] = rng.vec(-1.0, 1.0);
    c.w[static_cast<size_t>(i)] = rng.uniform(0.2, 5.0);
  }
  switch (kind) {
    case ConstraintKind::Distance:
      c.e = eval_distance(c.x[0], c.x[1], rng.uniform(0.1, 2.0));
      break;
    case ConstraintKind::Volume:
      c.e = eval_volume(c.x[0], c.x[1], c.x[2], c.x[3], rng.uniform(-0.2, 0.2));
      break;
    case ConstraintKind::Bending:
    case ConstraintKind::FemDeviatoric:  // the kernels see FEM constraints only through their
    case ConstraintKind::FemHydrostatic:  // ConstraintEval: a bending one stands for them here
    case ConstraintKind::FemStrainTriangle:  // (the strain kinds are block updates of their own,
    case ConstraintKind::FemStrainTet:       // tested in tests/core/test_fem_constraints.cpp)
      c.e = eval_bending(c.x[0], c.x[1], c.x[2], c.x[3], rng.uniform(0.5, 3.0));
      break;
  }
  return c;
}

TEST(Kernels, PbdProjectionSatisfiesALinearConstraintExactly) {
  // A distance constraint between two particles is linear along the line joining them: one
  // projection with k = 1 gives |x1 - x0| = rest.
  const Vec3 x0(0.1, 0.2, -0.3), x1(1.4, -0.5, 0.7);
  const ConstraintEval e = eval_distance(x0, x1, 0.8);
  Correction c;
  ASSERT_EQ(pbd_project(e, {1.0, 3.0, 0, 0}, 2, 1.0, c), Projection::Applied);
  EXPECT_NEAR(((x1 + c.dx[1]) - (x0 + c.dx[0])).norm(), 0.8, kRoundoff);
  // Mass weighting: particle 1 (w = 3) moves three times as far as particle 0.
  EXPECT_NEAR(c.dx[1].norm(), 3.0 * c.dx[0].norm(), kRoundoff);
  // With stiffness k the correction scales by k.
  Correction half;
  pbd_project(e, {1.0, 3.0, 0, 0}, 2, 0.5, half);
  EXPECT_NEAR((half.dx[1] - 0.5 * c.dx[1]).norm(), 0.0, kRoundoff);
}

TEST(Kernels, ProjectionsConserveLinearAndAngularMomentum) {
  // Mueller et al. 2007, sec. 3.3: the corrections of a constraint that is invariant under
  // translation and rotation change neither sum m_i dx_i nor sum m_i x_i x dx_i (about the
  // positions at which the constraint was evaluated). 200 random configurations per kind.
  Random rng(7);
  for (ConstraintKind kind :
       {ConstraintKind::Distance, ConstraintKind::Volume, ConstraintKind::Bending}) {
    for (int trial = 0; trial < 200; ++trial) {
      const Config c = random_config(rng, kind);
      if (!c.e.valid) continue;
      std::array<Vec3, 4> disp;
      for (auto& d : disp) d = rng.vec(-0.1, 0.1);
      Correction pbd, xpbd;
      ASSERT_EQ(pbd_project(c.e, c.w, c.count, 0.7, pbd), Projection::Applied);
      ASSERT_EQ(
          xpbd_project(c.e, c.w, c.count, xpbd_coefficients(1e-4, 0.5, 0.01), 0.3, disp, xpbd),
          Projection::Applied);
      for (const Correction* corr : {&pbd, &xpbd}) {
        Vec3 lin = Vec3::Zero(), ang = Vec3::Zero();
        double scale = 0.0;
        for (int i = 0; i < c.count; ++i) {
          const size_t j = static_cast<size_t>(i);
          lin += corr->dx[j] / c.w[j];
          ang += c.x[j].cross(corr->dx[j] / c.w[j]);
          scale += corr->dx[j].norm() / c.w[j];
        }
        EXPECT_LE(lin.norm(), kRoundoff * scale) << to_string(kind) << " trial " << trial;
        EXPECT_LE(ang.norm(), 10 * kRoundoff * scale) << to_string(kind) << " trial " << trial;
      }
    }
  }
}

TEST(Kernels, CorrectedStiffnessGivesTheSameErrorAfterNSweeps) {
  // Mueller et al. 2007, sec. 3.3: (1 - k')^n = 1 - k.
  for (double k : {0.01, 0.3, 0.9, 1.0})
    for (int n : {1, 2, 7, 100})
      EXPECT_NEAR(std::pow(1.0 - pbd_corrected_stiffness(k, n), n), 1.0 - k, kRoundoff);
}

TEST(Kernels, XpbdCoefficients) {
  // alpha~ = alpha / h^2, gamma = alpha~ (h^2 beta) / h = alpha beta / h.
  const XpbdCoefficients c = xpbd_coefficients(2e-4, 3.0, 0.01);
  EXPECT_NEAR(c.alpha_tilde, 2.0, kRoundoff);
  EXPECT_NEAR(c.gamma, 2e-4 * 3.0 / 0.01, kRoundoff);
}

TEST(Kernels, XpbdUpdateMatchesEquation18) {
  // One distance constraint, particle 0 fixed (w = 0): dlambda = (-C - alpha~ lambda) / (w + alpha~).
  const Vec3 x0(0, 0, 0), x1(1.5, 0, 0);
  const ConstraintEval e = eval_distance(x0, x1, 1.0);
  const XpbdCoefficients k = xpbd_coefficients(1e-3, 0.0, 0.1);  // alpha~ = 0.1
  Correction c;
  ASSERT_EQ(xpbd_project(e, {0.0, 2.0, 0, 0}, 2, k, 0.25, {}, c), Projection::Applied);
  const double expected = (-0.5 - 0.1 * 0.25) / (2.0 + 0.1);
  EXPECT_NEAR(c.dlambda, expected, kRoundoff);
  EXPECT_NEAR(c.dx[1].x(), 2.0 * expected, kRoundoff);
  EXPECT_EQ(c.dx[0].norm(), 0.0);
}

TEST(Kernels, XpbdWithZeroComplianceIsPbdWithUnitStiffness) {
  // Macklin et al. 2016: with alpha = 0 the XPBD update is PBD's with k = 1, bit for bit here.
  Random rng(11);
  for (ConstraintKind kind :
       {ConstraintKind::Distance, ConstraintKind::Volume, ConstraintKind::Bending}) {
    for (int trial = 0; trial < 50; ++trial) {
      const Config c = random_config(rng, kind);
      if (!c.e.valid) continue;
      Correction pbd, xpbd;
      pbd_project(c.e, c.w, c.count, 1.0, pbd);
      xpbd_project(c.e, c.w, c.count, xpbd_coefficients(0.0, 0.0, 0.01), 0.0, {}, xpbd);
      for (int i = 0; i < c.count; ++i)
        EXPECT_EQ(pbd.dx[static_cast<size_t>(i)], xpbd.dx[static_cast<size_t>(i)]);
    }
  }
}

TEST(Kernels, SkippedAndInactive) {
  Correction c;
  // Coincident particles: gradient undefined.
  const ConstraintEval coincident = eval_distance(Vec3::Zero(), Vec3::Zero(), 1.0);
  EXPECT_EQ(pbd_project(coincident, {1, 1, 0, 0}, 2, 1.0, c), Projection::Skipped);
  EXPECT_EQ(xpbd_project(coincident, {1, 1, 0, 0}, 2, {}, 0.0, {}, c), Projection::Skipped);
  // Both particles pinned: zero generalised inverse mass.
  const ConstraintEval e = eval_distance(Vec3::Zero(), Vec3::UnitX(), 0.5);
  EXPECT_EQ(pbd_project(e, {0, 0, 0, 0}, 2, 1.0, c), Projection::Skipped);
  EXPECT_EQ(xpbd_project(e, {0, 0, 0, 0}, 2, {}, 0.0, {}, c), Projection::Skipped);
  // A contact that is not violated.
  ConstraintEval contact;
  contact.C = 0.01;
  contact.grad[0] = Vec3::UnitY();
  EXPECT_EQ(pbd_project_contact(contact, {1, 0, 0, 0}, 1, c), Projection::Inactive);
  EXPECT_EQ(xpbd_project_contact(contact, {1, 0, 0, 0}, 1, 0.0, c), Projection::Inactive);
  // A violated one pushes out along the normal by the penetration.
  contact.C = -0.02;
  ASSERT_EQ(pbd_project_contact(contact, {2, 0, 0, 0}, 1, c), Projection::Applied);
  EXPECT_NEAR(c.dx[0].y(), 0.02, kRoundoff);
  EXPECT_NEAR(c.dlambda, 0.01, kRoundoff);  // W lambda = 0.02 m: the push
  ASSERT_EQ(xpbd_project_contact(contact, {2, 0, 0, 0}, 1, 0.5, c), Projection::Applied);
  EXPECT_NEAR(c.dx[0].y(), 0.02, kRoundoff);
  EXPECT_GE(0.5 + c.dlambda, 0.0);
}

}  // namespace
}  // namespace pbdbench::test
