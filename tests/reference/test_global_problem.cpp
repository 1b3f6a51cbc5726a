// Tests of reference/global_problem.cpp: the objective's gradient and Hessian against finite
// differences, the rows' gradients and Hessians against finite differences, and the residuals.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>

#include "reference/global_problem.hpp"
#include "tests/reference/global_fixtures.hpp"

namespace pbdbench {
namespace {

using test::begin_global_step;
using test::catalog_scene;

// A small cloth with damping, bending and pins, moved off its rest state so that every term is
// active, and its step's problem.
struct ClothFixture {
  Scene scene = catalog_scene("hanging_cloth", {"scene.resolution=[5, 4]",
                                                "scene.stretch_damping=0.01",
                                                "scene.bending_compliance=1.0"});
  GlobalProblem problem{scene.model};
  ClothFixture() {
    test::advance(scene.model, scene.initial, "xpbd", 6, 1.0 / 60.0);
    begin_global_step(problem, scene.initial, 1.0 / 60.0);
  }
};

TEST(GlobalProblem, GradientMatchesFiniteDifferencesOfTheObjective) {
  ClothFixture f;
  const GlobalProblem& p = f.problem;
  Points x = f.scene.initial.x;
  Eigen::VectorXd q = p.gather(x);
  q += 0.01 * Eigen::VectorXd::LinSpaced(q.size(), -1.0, 1.0);  // off the start
  p.positions(q, x);
  Eigen::VectorXd g;
  p.gradient(x, g);
  const double step = 1e-6;
  double worst = 0.0;
  for (Eigen::Index k = 0; k < q.size(); ++k) {
    Eigen::VectorXd qp = q, qm = q;
    qp(k) += step;
    qm(k) -= step;
    Points xp, xm;
    p.positions(qp, xp);
    p.positions(qm, xm);
    const double fd = (p.objective(xp) - p.objective(xm)) / (2.0 * step);
    worst = std::max(worst, std::abs(fd - g(k)));
  }
  EXPECT_LT(worst, 1e-7 * g.cwiseAbs().maxCoeff() + 1e-10);
}

TEST(GlobalProblem, HessianProductAndDiagonalAgreeWithTheAssembledHessian) {
  ClothFixture f;
  const GlobalProblem& p = f.problem;
  const Points& x = f.scene.initial.x;
  const Eigen::SparseMatrix<double> H = p.hessian(x);
  const Eigen::VectorXd v = Eigen::VectorXd::LinSpaced(p.dofs(), -0.3, 0.7);
  Eigen::VectorXd Hv;
  p.hessian_product(x, v, Hv);
  EXPECT_LT((Hv - H * v).cwiseAbs().maxCoeff(), 1e-12 * (H * v).cwiseAbs().maxCoeff());
  EXPECT_LT((p.hessian_diagonal(x) - Eigen::VectorXd(H.diagonal())).cwiseAbs().maxCoeff(),
            1e-12 * H.diagonal().cwiseAbs().maxCoeff());
  // Symmetric, with the masses on the diagonal and the projected terms positive semi-definite.
  const Eigen::MatrixXd D(H);
  EXPECT_LT((D - D.transpose()).cwiseAbs().maxCoeff(), 1e-12 * D.cwiseAbs().maxCoeff());
  const Eigen::VectorXd m = p.mass();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(D - Eigen::MatrixXd(m.asDiagonal()));
  EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-9 * eig.eigenvalues().cwiseAbs().maxCoeff());
}

// A chain in tension: every term of E is convex there, so the projected Hessian is the exact one
// and matches finite differences of the gradient.
TEST(GlobalProblem, HessianMatchesFiniteDifferencesOfTheGradientWhereEveryTermIsConvex) {
  Scene s = catalog_scene("hanging_chain", {"scene.links=4", "scene.compliance=1e-4"});
  GlobalProblem p(s.model);
  begin_global_step(p, s.initial, 1.0 / 60.0);
  Points x;
  Eigen::VectorXd q = p.gather(p.x_pred());
  for (Eigen::Index k = 1; k < q.size(); k += 3) q(k) -= 0.002 * static_cast<double>(k);  // stretched
  p.positions(q, x);
  const Eigen::MatrixXd H(p.hessian(x));
  const double step = 1e-6;
  Eigen::MatrixXd fd(q.size(), q.size());
  for (Eigen::Index k = 0; k < q.size(); ++k) {
    Eigen::VectorXd qp = q, qm = q, gp, gm;
    qp(k) += step;
    qm(k) -= step;
    Points xp, xm;
    p.positions(qp, xp);
    p.positions(qm, xm);
    p.gradient(xp, gp);
    p.gradient(xm, gm);
    fd.col(k) = (gp - gm) / (2.0 * step);
  }
  EXPECT_LT((fd - H).cwiseAbs().maxCoeff(), 1e-6 * H.cwiseAbs().maxCoeff());
}

// Rows: a rigid distance and a rigid volume constraint, and contacts against a plane, a sphere
// from outside and inside, and between particles. Their gradients and Hessians against finite
// differences of C.
TEST(GlobalProblem, RowGradientsAndHessiansMatchFiniteDifferences) {
  Model m;
  m.name = "rows";
  m.gravity = Vec3::Zero();
  m.rest_positions.resize(6, 3);
  m.rest_positions << 0.0, 0.0, 0.0, 0.4, 0.1, 0.0, 0.1, 0.5, 0.1, 0.05, 0.1, 0.45, 0.8, -0.02, 0.1,
      0.86, 0.05, 0.12;
  m.inv_mass = {1.0, 2.0, 0.5, 1.0, 1.0, 1.5};
  m.radius.assign(6, 0.05);
  Constraint d;
  d.kind = ConstraintKind::Distance;
  d.particles = {0, 1, -1, -1};
  d.rest = 0.3;
  Constraint v;
  v.kind = ConstraintKind::Volume;
  v.particles = {0, 1, 2, 3};
  v.rest = 0.01;
  m.constraints = {d, v};
  m.group_names = {"rows"};
  m.planes.push_back({Vec3(0.0, 1.0, 0.0), 0.0, 0.0, 0.0});
  SphereCollider out;
  out.center = Vec3(0.8, 0.3, 0.1);
  out.radius = 0.3;
  SphereCollider in = out;
  in.side = SphereSide::Inside;
  in.radius = 0.9;
  m.spheres = {out, in};
  GlobalProblem p(m);
  const Points x = m.rest_positions;
  std::vector<Contact> contacts = {{ContactKind::Plane, 4, 0},
                                   {ContactKind::Sphere, 4, 0},
                                   {ContactKind::Sphere, 5, 1},
                                   {ContactKind::Particle, 4, 5}};
  p.begin_step(x, x, 0.01, 0.0, contacts);
  ASSERT_EQ(p.rows().size(), 6u);
  const double step = 1e-6;
  for (int r = 0; r < 6; ++r) {
    SCOPED_TRACE("row " + std::to_string(r));
    const RowEval e = p.eval_row(r, x);
    const Eigen::Matrix<double, 12, 12> H = p.row_hessian(r, x);
    for (int a = 0; a < e.count; ++a)
      for (int c = 0; c < 3; ++c) {
        Points xp = x, xm = x;
        xp(e.particles[static_cast<size_t>(a)], c) += step;
        xm(e.particles[static_cast<size_t>(a)], c) -= step;
        const RowEval ep = p.eval_row(r, xp), em = p.eval_row(r, xm);
        EXPECT_NEAR((ep.C - em.C) / (2.0 * step), e.grad[static_cast<size_t>(a)](c), 1e-8);
        for (int b = 0; b < e.count; ++b)
          for (int k = 0; k < 3; ++k)
            EXPECT_NEAR((ep.grad[static_cast<size_t>(b)](k) - em.grad[static_cast<size_t>(b)](k)) /
                            (2.0 * step),
                        H(3 * b + k, 3 * a + c), 1e-6);
      }
  }
}

TEST(GlobalProblem, CompliantBendingIsSmoothAtFlat) {
  // A flat cloth's hinges sit exactly at flat, where the acos form has no gradient; the form the
  // global problem uses has one, and its C^2 / 2 has the gradient C grad C = 0 there.
  Scene s = catalog_scene("hanging_cloth", {"scene.resolution=[3, 3]"});
  GlobalProblem p(s.model);
  begin_global_step(p, s.initial, 1.0 / 60.0);
  int hinges = 0;
  for (int j : p.compliant()) {
    if (s.model.constraints[static_cast<size_t>(j)].kind != ConstraintKind::Bending) continue;
    const RowEval e = p.eval_compliant(j, s.initial.x);
    EXPECT_TRUE(e.valid);
    EXPECT_NEAR(e.C, 0.0, 1e-12);
    ++hinges;
  }
  EXPECT_GT(hinges, 0);
}

TEST(GlobalProblem, RefusesRigidBendingAndElementsWithoutAConstraintForm) {
  Scene s = catalog_scene("hanging_cloth", {"scene.resolution=[3, 3]", "scene.bending_compliance=0"});
  EXPECT_THROW(
      {
        try {
          GlobalProblem p(s.model);
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("bending"), std::string::npos) << e.what();
          throw;
        }
      },
      std::invalid_argument);
}

TEST(GlobalProblem, ResidualIsZeroAtTheClosedFormOfARigidPendulum) {
  // One rigid link from a pinned pivot: x* is x~ projected onto the circle, lambda from the
  // radial balance m (x* - x~) = grad C lambda, grad C = n (the unit radial vector).
  Scene s = catalog_scene("pendulum");
  GlobalProblem p(s.model);
  const Points x_pred = begin_global_step(p, s.initial, 0.01);
  ASSERT_EQ(p.rows().size(), 1u);
  const int bob = s.model.observables.bob;
  const Vec3 pivot = s.model.observables.pivot;
  const Vec3 d = x_pred.row(bob).transpose() - pivot;
  const double L = s.model.constraints[0].rest;
  Points x = x_pred;
  x.row(bob) = (pivot + L * d.normalized()).transpose();
  const double m = 1.0 / s.model.inv_mass[static_cast<size_t>(bob)];
  const double lambda = m * (L - d.norm());  // m (x* - x~) . n
  // The constraint's particle order decides the sign of grad C = +-n.
  const RowEval e = p.eval_row(0, x);
  const double sign = e.grad[e.particles[0] == bob ? 0 : 1].dot(d.normalized());
  const GlobalProblem::Residuals r = p.residuals(x, {sign * lambda});
  EXPECT_LT(r.position, 1e-14);
  EXPECT_GT(p.residuals(x, {-sign * lambda}).position, 1e6 * r.position + 1e-9);
}

}  // namespace
}  // namespace pbdbench
