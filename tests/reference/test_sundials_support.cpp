// Tests of reference/sundials_support: check() names the call and the flag of each package's
// table, the sparse matrix carries the pattern, the vectors wrap Eigen memory, and KLU through
// the timed wrapper solves a small system and counts its calls.
#include "reference/sundials_support.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include <sunmatrix/sunmatrix_sparse.h>

namespace pbdbench {
namespace {

std::string message(int flag, const char* call, sun::Flags table, const sun::ErrorLog* log = nullptr) {
  try {
    sun::check(flag, call, table, log);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "no exception";
}

TEST(SundialsSupport, CheckNamesCallAndFlag) {
  EXPECT_EQ(sun::check(0, "CVode", sun::Flags::Cvode), 0);
  EXPECT_EQ(sun::check(2, "KINSol", sun::Flags::Kinsol), 2);  // positive: returned, not thrown
  EXPECT_EQ(message(-1, "CVode", sun::Flags::Cvode), "CVode failed: CV_TOO_MUCH_WORK (-1)");
  EXPECT_EQ(message(-1, "CVodeSetJacFn", sun::Flags::CvodeLs), "CVodeSetJacFn failed: CVLS_MEM_NULL (-1)");
  EXPECT_EQ(message(-4, "ARKStepEvolve", sun::Flags::Arkode), "ARKStepEvolve failed: ARK_CONV_FAILURE (-4)");
  EXPECT_EQ(message(-5, "KINSol", sun::Flags::Kinsol), "KINSol failed: KIN_LINESEARCH_NONCONV (-5)");
  EXPECT_EQ(message(-4, "IDASolve", sun::Flags::Ida), "IDASolve failed: IDA_CONV_FAIL (-4)");
  EXPECT_EQ(message(-809, "SUNLinSolSetup", sun::Flags::LinearSolver),
            "SUNLinSolSetup failed: SUNLS_PACKAGE_FAIL_UNREC (-809)");
  EXPECT_EQ(message(-7, "something", sun::Flags::Plain), "something failed: flag -7 (-7)");
  sun::ErrorLog log;
  log.last = "CVODE CVode: At t = 0.5, mxstep steps taken before reaching tout.";
  EXPECT_EQ(message(-1, "CVode", sun::Flags::Cvode, &log),
            "CVode failed: CV_TOO_MUCH_WORK (-1): CVODE CVode: At t = 0.5, mxstep steps taken "
            "before reaching tout.");
}

TEST(SundialsSupport, VectorsWrapAndOwn) {
  sun::Context ctx;
  Eigen::VectorXd data = Eigen::VectorXd::LinSpaced(4, 1.0, 4.0);
  sun::Vector wrapped(data, ctx);
  EXPECT_EQ(N_VGetArrayPointer(wrapped), data.data());
  wrapped.map()[2] = -7.0;
  EXPECT_EQ(data[2], -7.0);
  sun::Vector owned(3, ctx);
  EXPECT_EQ(owned.size(), 3);
  EXPECT_EQ(owned.map(), Eigen::Vector3d::Zero());
  sun::Vector moved(std::move(owned));
  EXPECT_EQ(owned.get(), nullptr);
  EXPECT_EQ(moved.size(), 3);
}

TEST(SundialsSupport, SparseMatrixAndTimedKluSolve) {
  sun::Context ctx;
  // [[4, 1, 0], [1, 3, 0], [0, 0, 2]], CSC with the zero (2, 0) absent.
  sun::CscPattern p;
  p.rows = p.cols = 3;
  p.column_start = {0, 2, 4, 5};
  p.row = {0, 1, 0, 1, 2};
  EXPECT_TRUE(p.has_full_diagonal());
  EXPECT_EQ(p.find(1, 0), 1);
  EXPECT_EQ(p.find(2, 0), -1);
  sun::SparseMatrix A(p, ctx);
  const double v[5] = {4, 1, 1, 3, 2};
  std::copy(v, v + 5, A.values());
  sun::Vector x(3, ctx), b(3, ctx);
  b.map() << 1.0, 2.0, 4.0;
  sun::TimedKlu klu(x, A, ctx);
  ASSERT_EQ(SUNLinSolInitialize(klu), 0);
  ASSERT_EQ(SUNLinSolSetup(klu, A), 0);
  ASSERT_EQ(SUNLinSolSolve(klu, A, x, b, 0.0), 0);
  EXPECT_NEAR(x.map()[0], 1.0 / 11.0, 1e-15);
  EXPECT_NEAR(x.map()[1], 7.0 / 11.0, 1e-15);
  EXPECT_NEAR(x.map()[2], 2.0, 1e-15);
  EXPECT_EQ(klu.stats().setups, 1);
  EXPECT_EQ(klu.stats().solves, 1);
  // SUNMatZero clears the index arrays too; write_pattern restores them.
  SUNMatZero(A);
  EXPECT_EQ(SUNSparseMatrix_IndexPointers(A)[3], 0);
  sun::write_pattern(A, p);
  EXPECT_EQ(SUNSparseMatrix_IndexPointers(A)[3], 5);
  EXPECT_EQ(SUNSparseMatrix_IndexValues(A)[4], 2);
  sun::CscPattern wrong = p;
  wrong.rows = 4;
  EXPECT_THROW(sun::write_pattern(A, wrong), std::invalid_argument);
}

TEST(SundialsSupport, CountersDifference) {
  sun::Counters a, b;
  a.steps = 10;
  a.newton_iterations = 20;
  a.time_linear = 0.5;
  b.steps = 4;
  b.newton_iterations = 5;
  b.time_linear = 0.25;
  const sun::Counters d = a - b;
  EXPECT_EQ(d.steps, 6);
  EXPECT_EQ(d.newton_iterations, 15);
  EXPECT_EQ(d.time_linear, 0.25);
  b += d;
  EXPECT_EQ(b.steps, a.steps);
}

}  // namespace
}  // namespace pbdbench
