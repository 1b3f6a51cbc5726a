// SparseFactor (reference/sparse_factor.hpp): Cholesky on symmetric positive definite matrices,
// LU where Cholesky meets a pivot <= 0 or the matrix is not symmetric, refusals of singular and
// non-finite matrices, and what each counts.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <Eigen/Dense>

#include "integrator_fixtures.hpp"
#include "reference/sparse_factor.hpp"

namespace pbdbench {
namespace {

using Method = SparseFactor::Method;

// A banded symmetric pattern (|i - j| <= w, plus a few far pairs) on n dofs.
SparsityPattern banded(int n, int w) {
  SparsityPattern p;
  p.n = n;
  p.column_start.push_back(0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i)
      if (std::abs(i - j) <= w || (i + j) % 11 == 0) p.row.push_back(i);
    p.column_start.push_back(p.nnz());
  }
  return p;
}

std::vector<double> values_of(const SparsityPattern& p, const Eigen::MatrixXd& A) {
  std::vector<double> v(static_cast<size_t>(p.nnz()));
  for (int j = 0; j < p.n; ++j)
    for (auto k = p.column_start[static_cast<size_t>(j)]; k < p.column_start[static_cast<size_t>(j) + 1]; ++k)
      v[static_cast<size_t>(k)] = A(p.row[static_cast<size_t>(k)], j);
  return v;
}

// A random matrix on the pattern: symmetric when `symmetric`, with `shift` added to its diagonal.
Eigen::MatrixXd random_on(const SparsityPattern& p, unsigned seed, bool symmetric, double shift) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(p.n, p.n);
  for (int j = 0; j < p.n; ++j)
    for (auto k = p.column_start[static_cast<size_t>(j)]; k < p.column_start[static_cast<size_t>(j) + 1]; ++k)
      A(p.row[static_cast<size_t>(k)], j) = U(rng);
  if (symmetric) A = (0.5 * (A + A.transpose())).eval();
  A.diagonal().array() += shift;
  return A;
}

// |A x - b| / (|A| |x| + |b|): a backward error, round-off for a stable solve.
double backward_error(const Eigen::MatrixXd& A, const Eigen::VectorXd& x, const Eigen::VectorXd& b) {
  return (A * x - b).norm() / (A.norm() * x.norm() + b.norm());
}

TEST(SparseFactor, CholeskySolvesAPositiveDefiniteMatrix) {
  const SparsityPattern p = banded(60, 3);
  SparseFactor f(p);
  EXPECT_EQ(f.size(), 60);
  for (unsigned seed = 1; seed <= 5; ++seed) {
    const Eigen::MatrixXd A = random_on(p, seed, true, 12.0);  // diagonally dominant: SPD
    ASSERT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(A).eigenvalues().minCoeff(), 0.0);
    const std::vector<double> v = values_of(p, A);
    ASSERT_EQ(f.factorize(v.data()), Method::Cholesky);
    const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(60, -1.0, 2.0);
    Eigen::VectorXd x(60);
    ASSERT_TRUE(f.solve(b.data(), x.data()));
    EXPECT_LE(backward_error(A, x, b), 1e-15) << "seed " << seed;
  }
  EXPECT_EQ(f.stats().cholesky, 5);
  EXPECT_EQ(f.stats().lu, 0);
  EXPECT_EQ(f.stats().solves, 5);
}

TEST(SparseFactor, IndefiniteFallsBackToLuAndReturnsToCholesky) {
  const SparsityPattern p = banded(40, 2);
  SparseFactor f(p);
  // Symmetric with a negative eigenvalue: Cholesky meets a pivot <= 0, LU solves it.
  Eigen::MatrixXd A = random_on(p, 7, true, 6.0);
  A(10, 10) = -3.0;
  ASSERT_LT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(A).eigenvalues().minCoeff(), 0.0);
  std::vector<double> v = values_of(p, A);
  EXPECT_EQ(f.factorize(v.data(), /*allow_lu=*/false), Method::None);
  EXPECT_EQ(f.method(), Method::None);
  Eigen::VectorXd x(40);
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(40);
  EXPECT_FALSE(f.solve(b.data(), x.data()));
  ASSERT_EQ(f.factorize(v.data()), Method::Lu);
  ASSERT_TRUE(f.solve(b.data(), x.data()));
  EXPECT_LE(backward_error(A, x, b), 1e-14);
  EXPECT_EQ(f.stats().not_positive_definite, 2);
  EXPECT_EQ(f.stats().lu, 1);
  // Definite again: Cholesky once more.
  A(10, 10) = 8.0;
  v = values_of(p, A);
  EXPECT_EQ(f.factorize(v.data()), Method::Cholesky);
  ASSERT_TRUE(f.solve(b.data(), x.data()));
  EXPECT_LE(backward_error(A, x, b), 1e-15);
}

TEST(SparseFactor, UnsymmetricGoesToLu) {
  const SparsityPattern p = banded(30, 2);
  SparseFactor f(p);
  const Eigen::MatrixXd A = random_on(p, 3, false, 6.0);
  const std::vector<double> v = values_of(p, A);
  EXPECT_EQ(f.factorize(v.data(), false), Method::None);
  ASSERT_EQ(f.factorize(v.data()), Method::Lu);
  EXPECT_EQ(f.stats().unsymmetric, 2);
  EXPECT_EQ(f.stats().cholesky, 0);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(30, 1.0, 3.0);
  Eigen::VectorXd x = b;
  ASSERT_TRUE(f.solve(x.data(), x.data()));  // in place
  EXPECT_LE(backward_error(A, x, b), 1e-14);
}

TEST(SparseFactor, RoundOffAsymmetryStillCholesky) {
  // A symmetric matrix whose mirrored entries differ in the last bits (rows scaled by masses
  // do that) is symmetric for the factorisation.
  const SparsityPattern p = banded(20, 2);
  SparseFactor f(p);
  Eigen::MatrixXd A = random_on(p, 11, true, 8.0);
  for (int j = 0; j < 20; ++j)
    for (int i = j + 1; i < 20; ++i)
      if (A(i, j) != 0.0) A(i, j) = std::nextafter(A(i, j), 10.0);
  const std::vector<double> v = values_of(p, A);
  EXPECT_EQ(f.factorize(v.data()), Method::Cholesky);
  EXPECT_EQ(f.stats().unsymmetric, 0);
}

TEST(SparseFactor, RefusesSingularAndNonFinite) {
  const SparsityPattern p = banded(12, 1);
  SparseFactor f(p);
  Eigen::MatrixXd A = random_on(p, 5, false, 4.0);
  A.row(4).setZero();  // structurally present, numerically zero row
  std::vector<double> v = values_of(p, A);
  EXPECT_EQ(f.factorize(v.data()), Method::None);
  EXPECT_EQ(f.stats().singular, 1);
  Eigen::VectorXd x(12), b = Eigen::VectorXd::Ones(12);
  EXPECT_FALSE(f.solve(b.data(), x.data()));
  A = random_on(p, 5, true, 4.0);
  v = values_of(p, A);
  v[3] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(f.factorize(v.data()), Method::None);
  EXPECT_FALSE(f.solve(b.data(), x.data()));
}

TEST(SparseFactor, RefusesAPatternWithoutDiagonalOrUnsymmetric) {
  SparsityPattern p = test::full_pattern(3, false);  // the diagonal only: fine
  EXPECT_NO_THROW(SparseFactor f(p));
  SparsityPattern no_diag;
  no_diag.n = 2;
  no_diag.column_start = {0, 1, 2};
  no_diag.row = {1, 0};  // (1, 0) and (0, 1): symmetric, no diagonal
  EXPECT_THROW(SparseFactor f(no_diag), std::invalid_argument);
  SparsityPattern one_sided;
  one_sided.n = 2;
  one_sided.column_start = {0, 2, 3};
  one_sided.row = {0, 1, 1};  // (1, 0) without (0, 1)
  EXPECT_THROW(SparseFactor f(one_sided), std::invalid_argument);
}

TEST(SparseFactor, Deterministic) {
  const SparsityPattern p = banded(50, 4);
  const Eigen::MatrixXd A = random_on(p, 2, true, 10.0);
  const std::vector<double> v = values_of(p, A);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(50, -2.0, 1.0);
  Eigen::VectorXd x1(50), x2(50);
  SparseFactor f1(p), f2(p);
  ASSERT_EQ(f1.factorize(v.data()), Method::Cholesky);
  ASSERT_EQ(f2.factorize(v.data()), Method::Cholesky);
  ASSERT_TRUE(f1.solve(b.data(), x1.data()));
  ASSERT_TRUE(f2.solve(b.data(), x2.data()));
  EXPECT_EQ(std::memcmp(x1.data(), x2.data(), 50 * sizeof(double)), 0);
}

}  // namespace
}  // namespace pbdbench
