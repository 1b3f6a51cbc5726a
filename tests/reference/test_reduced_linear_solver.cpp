// ReducedLinearSolver (reference/reduced_linear_solver.hpp): the Newton matrix A = I - gamma J of
// the first-order system solved through S = M + gamma D + gamma^2 K equals a dense solve of A;
// matrices it cannot read are refused; and the integrators give the same trajectories with it as
// with KLU on the whole matrix.
#include "catalog/solver_catalog.hpp"
#include "reference/reduced_linear_solver.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include <Eigen/Dense>
#include <sunmatrix/sunmatrix_sparse.h>

#include "reference/first_order_system.hpp"
#include "solver_api/solver.hpp"
#include "tests/reference/integrator_fixtures.hpp"

namespace pbdbench {
namespace {

Eigen::MatrixXd dense_of(SUNMatrix A) {
  const auto rows = SUNSparseMatrix_Rows(A), cols = SUNSparseMatrix_Columns(A);
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(rows, cols);
  const sunindextype* start = SUNSparseMatrix_IndexPointers(A);
  const sunindextype* row = SUNSparseMatrix_IndexValues(A);
  const double* v = SUNSparseMatrix_Data(A);
  for (sunindextype j = 0; j < cols; ++j)
    for (sunindextype k = start[j]; k < start[j + 1]; ++k) D(row[k], j) += v[k];
  return D;
}

// A = I - gamma J(t, y) as the packages form it: J evaluated, then SUNMatScaleAddI(-gamma, .).
void newton_matrix(FirstOrderSystem& fos, const Eigen::VectorXd& y, double gamma, SUNMatrix A) {
  sun::write_pattern(A, fos.jacobian_pattern());
  fos.jacobian(0.3, y.data(), SUNSparseMatrix_Data(A));
  ASSERT_EQ(SUNMatScaleAddI(-gamma, A), 0);
}

TEST(ReducedLinearSolver, SolvesTheNewtonMatrixLikeADenseSolve) {
  // Random nonlinear systems, damped and undamped, at random states and gammas from 1e-4 to 1:
  // the solution of A x = b through S agrees with a dense LU of A to round-off of A's condition.
  double worst = 0.0;
  for (bool damped : {false, true}) {
    for (unsigned seed = 1; seed <= 4; ++seed) {
      test::RandomSystem sys(15, seed, damped);
      FirstOrderSystem fos(sys);
      sun::Context ctx;
      sun::SparseMatrix A(fos.jacobian_pattern(), ctx);
      ReducedLinearSolver ls(fos, ctx);
      ASSERT_EQ(SUNLinSolInitialize(ls), 0);
      sun::Vector x(fos.size(), ctx), b(fos.size(), ctx);
      for (double gamma : {1e-4, 1e-2, 1.0}) {
        const Eigen::VectorXd y = Eigen::VectorXd::LinSpaced(fos.size(), -0.7, 0.9) * (0.5 + seed * 0.1);
        newton_matrix(fos, y, gamma, A.get());
        ASSERT_EQ(SUNLinSolSetup(ls, A.get()), SUNLS_SUCCESS) << "seed " << seed << " gamma " << gamma;
        EXPECT_EQ(ls.gamma(), gamma);
        b.map() = Eigen::VectorXd::LinSpaced(fos.size(), 1.0, -2.0);
        b.map()(3) += 5.0;
        const Eigen::VectorXd rhs = b.map();
        ASSERT_EQ(SUNLinSolSolve(ls, A.get(), x.get(), b.get(), 0.0), SUNLS_SUCCESS);
        const Eigen::MatrixXd Ad = dense_of(A.get());
        const Eigen::VectorXd exact = Ad.partialPivLu().solve(rhs);
        const double cond = Ad.norm() * Ad.inverse().norm();
        const double err = (x.map() - exact).norm() / exact.norm() / cond;
        worst = std::max(worst, err);
        // Relative error over the condition number: round-off times a small factor.
        EXPECT_LE(err, 1e-13) << "seed " << seed << " gamma " << gamma << (damped ? " damped" : "");
      }
      EXPECT_EQ(ls.stats().setups, 3);
      EXPECT_EQ(ls.stats().solves, 3);
    }
  }
  std::printf("[ measured ] largest |x - x_dense| / |x_dense| / cond(A): %.3g\n", worst);
}

TEST(ReducedLinearSolver, SolvesInPlace) {
  test::RandomSystem sys(9, 2, true);
  FirstOrderSystem fos(sys);
  sun::Context ctx;
  sun::SparseMatrix A(fos.jacobian_pattern(), ctx);
  ReducedLinearSolver ls(fos, ctx);
  const Eigen::VectorXd y = Eigen::VectorXd::Constant(fos.size(), 0.2);
  newton_matrix(fos, y, 0.05, A.get());
  ASSERT_EQ(SUNLinSolSetup(ls, A.get()), SUNLS_SUCCESS);
  sun::Vector x(fos.size(), ctx), xb(fos.size(), ctx);
  xb.map() = Eigen::VectorXd::LinSpaced(fos.size(), -1.0, 1.0);
  const Eigen::VectorXd b = xb.map();
  ASSERT_EQ(SUNLinSolSolve(ls, A.get(), x.get(), xb.get(), 0.0), SUNLS_SUCCESS);
  ASSERT_EQ(SUNLinSolSolve(ls, A.get(), xb.get(), xb.get(), 0.0), SUNLS_SUCCESS);
  EXPECT_EQ((x.map() - xb.map()).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_LE((dense_of(A.get()) * x.map() - b).norm(), 1e-12 * b.norm());
}

TEST(ReducedLinearSolver, RefusesAMatrixThatIsNotINewtonForm) {
  test::RandomSystem sys(6, 1, false);
  FirstOrderSystem fos(sys);
  sun::Context ctx;
  sun::SparseMatrix A(fos.jacobian_pattern(), ctx);
  ReducedLinearSolver ls(fos, ctx);
  const Eigen::VectorXd y = Eigen::VectorXd::Zero(fos.size());
  // J itself (no identity in the position block, no -gamma I): refused.
  sun::write_pattern(A.get(), fos.jacobian_pattern());
  fos.jacobian(0.0, y.data(), SUNSparseMatrix_Data(A.get()));
  EXPECT_EQ(SUNLinSolSetup(ls, A.get()), SUNLS_ILL_INPUT);
  sun::Vector x(fos.size(), ctx), b(fos.size(), ctx);
  b.map().setOnes();
  EXPECT_NE(SUNLinSolSolve(ls, A.get(), x.get(), b.get(), 0.0), SUNLS_SUCCESS);
  // A -gamma I block whose entries differ: refused.
  newton_matrix(fos, y, 0.1, A.get());
  SUNSparseMatrix_Data(A.get())[fos.identity_slots()[2]] *= 1.5;
  EXPECT_EQ(SUNLinSolSetup(ls, A.get()), SUNLS_ILL_INPUT);
  // Back to a proper one: accepted.
  newton_matrix(fos, y, 0.1, A.get());
  EXPECT_EQ(SUNLinSolSetup(ls, A.get()), SUNLS_SUCCESS);
}

TEST(ReducedLinearSolver, IntegratorsAgreeWithTheFullSystemSolve) {
  // The same scene by each integrator with either linear solver: the Newton iterations stop at
  // the same tolerance from slightly different round-off, so the trajectories agree to far
  // below the tolerance-controlled error, not bitwise. Hanging chain with compliant links
  // (swinging, K indefinite where links are compressed) and the FEM cantilever.
  struct Case {
    const char* scene;
    const char* solver;
    std::vector<std::pair<std::string, std::string>> overrides;
  };
  const std::vector<Case> cases = {
      {"hanging_chain", "ref-bdf", {{"time.duration", "0.2"}, {"scene.compliance", "1e-6"}}},
      {"hanging_chain", "ref-be", {{"time.duration", "0.2"}, {"scene.compliance", "1e-6"}}},
      {"cantilever_fem", "ref-sdirk2", {{"time.duration", "0.05"}, {"scene.cells", "[6, 2, 2]"}}},
  };
  for (const Case& c : cases) {
    Points x[2];
    long cholesky = 0;
    for (int k = 0; k < 2; ++k) {
      auto o = c.overrides;
      o.emplace_back("solver.name", c.solver);
      o.emplace_back("solver.ref.linear_solver", k == 0 ? "reduced" : "full");
      test::CatalogScene s = test::catalog(c.scene, o);
      const Model& m = s.scene.model;
      State st = s.scene.initial;
      auto solver = make_solver(s.options, m);
      const config::RunOptions run = config::run_options(s.config);
      for (long i = 0; i < run.steps(); ++i) {
        const StepReport r = solver->step(m, st, run.dt);
        if (k == 0) cholesky += r.cholesky_factorizations;
      }
      x[k] = st.x;
    }
    const double scale = x[1].cwiseAbs().maxCoeff();
    const double gap = (x[0] - x[1]).cwiseAbs().maxCoeff() / scale;
    std::printf("[ measured ] %s %s: reduced vs full, largest position gap / extent %.3g, %ld Cholesky\n",
                c.scene, c.solver, gap, cholesky);
    // Measured: 4e-15 and below. The Newton iterations of both stop at rtol 1e-8, but each
    // converges quadratically, so their last iterates differ by round-off of the linear solves,
    // not by the stopping tolerance; 1e-10 still catches a wrong gamma or mass scaling (which
    // would show at the tolerance level or above).
    EXPECT_LE(gap, 1e-10) << c.scene << " " << c.solver;
    EXPECT_GT(cholesky, 0) << c.scene << " " << c.solver;
  }
}

}  // namespace
}  // namespace pbdbench
