// Tests of reference/first_order_system: the 2n x 2n Jacobian pattern holds every diagonal entry
// and exactly the blocks it should, and its values equal central differences of y' on random
// nonlinear systems, with and without damping.
#include "reference/first_order_system.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <stdexcept>
#include <vector>

#include "tests/reference/integrator_fixtures.hpp"

namespace pbdbench {
namespace {

Eigen::MatrixXd dense(const sun::CscPattern& p, const std::vector<double>& values) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(p.rows, p.cols);
  for (sunindextype j = 0; j < p.cols; ++j)
    for (auto k = p.column_start[static_cast<size_t>(j)]; k < p.column_start[static_cast<size_t>(j) + 1]; ++k)
      A(p.row[static_cast<size_t>(k)], j) = values[static_cast<size_t>(k)];
  return A;
}

TEST(FirstOrderSystem, PatternHasEveryDiagonalEntrySortedRows) {
  for (bool damped : {false, true}) {
    test::RandomSystem sys(7, 3, damped);
    FirstOrderSystem fos(sys);
    const sun::CscPattern& p = fos.jacobian_pattern();
    ASSERT_EQ(p.rows, 14);
    ASSERT_EQ(p.cols, 14);
    EXPECT_TRUE(p.has_full_diagonal());
    for (sunindextype j = 0; j < p.cols; ++j) {
      EXPECT_GE(p.find(j, j), 0) << "missing (" << j << ", " << j << ")";
      for (auto k = p.column_start[static_cast<size_t>(j)] + 1; k < p.column_start[static_cast<size_t>(j) + 1]; ++k)
        EXPECT_LT(p.row[static_cast<size_t>(k) - 1], p.row[static_cast<size_t>(k)]) << "column " << j;
    }
    // Blocks: [[diag, I], [K pattern, D pattern or diag]].
    const SparsityPattern& sp = sys.pattern();
    const auto expected = 7 + sp.nnz() + 7 + (damped ? sp.nnz() : 7);
    EXPECT_EQ(p.nnz(), expected) << (damped ? "damped" : "undamped");
    for (int i = 0; i < 7; ++i)
      for (int j = 0; j < 7; ++j) {
        EXPECT_EQ(p.find(i, j) >= 0, i == j) << "top-left (" << i << ", " << j << ")";
        EXPECT_EQ(p.find(i, 7 + j) >= 0, i == j) << "top-right (" << i << ", " << j << ")";
        EXPECT_EQ(p.find(7 + i, j) >= 0, sp.find(i, j) >= 0) << "bottom-left (" << i << ", " << j << ")";
        EXPECT_EQ(p.find(7 + i, 7 + j) >= 0, damped ? sp.find(i, j) >= 0 : i == j)
            << "bottom-right (" << i << ", " << j << ")";
      }
  }
}

// J against central differences of y', column by column; entries outside the pattern must be
// zero in the differences too.
TEST(FirstOrderSystem, JacobianEqualsFiniteDifferencesOfRhs) {
  double worst = 0.0;
  for (unsigned seed = 1; seed <= 6; ++seed) {
    for (bool damped : {false, true}) {
      test::RandomSystem sys(9, seed, damped);
      FirstOrderSystem fos(sys);
      const int N = fos.size();
      std::mt19937 rng(seed + 100);
      std::uniform_real_distribution<double> U(-1.0, 1.0);
      Eigen::VectorXd y(N);
      for (int i = 0; i < N; ++i) y[i] = U(rng);
      const double t = 0.37;
      std::vector<double> values(static_cast<size_t>(fos.jacobian_pattern().nnz()), -99.0);
      fos.jacobian(t, y.data(), values.data());
      const Eigen::MatrixXd J = dense(fos.jacobian_pattern(), values);

      const double eps = 1e-6;
      Eigen::MatrixXd fd(N, N);
      Eigen::VectorXd yp(N), ym(N), fp(N), fm(N);
      for (int c = 0; c < N; ++c) {
        yp = y;
        ym = y;
        yp[c] += eps;
        ym[c] -= eps;
        fos.rhs(t, yp.data(), fp.data());
        fos.rhs(t, ym.data(), fm.data());
        fd.col(c) = (fp - fm) / (2.0 * eps);
      }
      // Central differences of O(1) smooth functions at eps = 1e-6: truncation ~1e-12 and
      // round-off ~1e-10; 1e-7 leaves room and still catches any wrong entry (they are O(0.1+)).
      const double tol = 1e-7;
      for (int r = 0; r < N; ++r)
        for (int c = 0; c < N; ++c) {
          const double err = std::abs(J(r, c) - fd(r, c)) / (1.0 + std::abs(fd(r, c)));
          worst = std::max(worst, err);
          EXPECT_LE(err, tol) << "seed " << seed << (damped ? " damped" : "") << " entry (" << r
                              << ", " << c << "): analytic " << J(r, c) << ", differences "
                              << fd(r, c);
          if (fos.jacobian_pattern().find(r, c) < 0) {
            EXPECT_EQ(J(r, c), 0.0);
          }
        }
    }
  }
  std::printf("[ measured ] largest |J - central difference| / (1 + |fd|): %.3g\n", worst);
}

TEST(FirstOrderSystem, RhsIsVelocityAndAcceleration) {
  test::RandomSystem sys(5, 11, true);
  FirstOrderSystem fos(sys);
  Eigen::VectorXd q(5), u(5), y(10), ydot(10), f;
  for (int i = 0; i < 5; ++i) {
    q[i] = 0.1 * i - 0.2;
    u[i] = 0.3 - 0.05 * i;
  }
  fos.pack(q, u, y.data());
  fos.rhs(1.5, y.data(), ydot.data());
  sys.force(1.5, q, u, f);
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(ydot[i], u[i]);
    EXPECT_DOUBLE_EQ(ydot[5 + i], f[i] / sys.mass()[i]);
  }
  Eigen::VectorXd q2, u2;
  fos.unpack(y.data(), q2, u2);
  EXPECT_EQ(q2, q);
  EXPECT_EQ(u2, u);
}

// A pattern without a diagonal entry would let I - gamma J change the pattern: refused.
TEST(FirstOrderSystem, RefusesPatternWithoutDiagonal) {
  class NoDiagonal final : public MechanicalSystem {
   public:
    NoDiagonal() : m_(Eigen::VectorXd::Ones(2)) {
      p_.n = 2;
      p_.column_start = {0, 1, 2};
      p_.row = {1, 0};  // off-diagonal only
    }
    int dofs() const override { return 2; }
    const Eigen::VectorXd& mass() const override { return m_; }
    void force(double, const Eigen::VectorXd& q, const Eigen::VectorXd&, Eigen::VectorXd& f) const override { f = -q; }
    const SparsityPattern& pattern() const override { return p_; }
    void stiffness(double, const Eigen::VectorXd&, const Eigen::VectorXd&, std::vector<double>& v) const override { v = {0, 0}; }
    void damping(double, const Eigen::VectorXd&, const Eigen::VectorXd&, std::vector<double>& v) const override { v = {1, 1}; }
    bool has_damping() const override { return true; }
    double potential(double, const Eigen::VectorXd& q) const override { return 0.5 * q.squaredNorm(); }

   private:
    Eigen::VectorXd m_;
    SparsityPattern p_;
  };
  NoDiagonal sys;
  EXPECT_THROW(FirstOrderSystem fos(sys), std::invalid_argument);
}

}  // namespace
}  // namespace pbdbench
