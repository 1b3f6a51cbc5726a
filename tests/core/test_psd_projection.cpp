// Tests of core/psd_projection: the general projection clamps the negative eigenvalues and only
// them; the translation-free path and the volume term's analytic eigensystem give the general
// projection of the same matrix (to rounding) on random blocks: indefinite and definite ones,
// tets regular, flattened, degenerate and inverted, constraints stretched and compressed, soft and
// nearly incompressible compliances.
#include "core/psd_projection.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "core/constraint_functions.hpp"
#include "tests/core/test_support.hpp"

namespace pbdbench {
namespace {

using psd::Mat12;
using psd::Mat9;
using test::Random;

template <int N>
Eigen::Matrix<double, N, N> random_symmetric(Random& rng) {
  Eigen::Matrix<double, N, N> A;
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) A(i, j) = rng.uniform(-1.0, 1.0);
  return 0.5 * (A + A.transpose());
}

// C (x) I3 with C = I4 - 1 1^T / 4: the projector that removes the translations.
Mat12 centering() {
  Mat12 P = Mat12::Identity();
  for (int v = 0; v < 4; ++v)
    for (int w = 0; w < 4; ++w) P.block<3, 3>(3 * v, 3 * w) -= Eigen::Matrix3d::Identity() / 4.0;
  return P;
}

double max_abs(const Mat12& m) { return m.cwiseAbs().maxCoeff(); }

TEST(PsdProjection, ClampsTheNegativeEigenvaluesAndKeepsTheRest) {
  Random rng(11);
  for (int trial = 0; trial < 50; ++trial) {
    const Mat12 H = random_symmetric<12>(rng);
    Mat12 P = H;
    psd::project_psd<12>(P);
    const Eigen::SelfAdjointEigenSolver<Mat12> before(H), after(P);
    // Eigenvalues in increasing order on both sides: the clamped ones become 0, the others stay.
    for (int i = 0; i < 12; ++i)
      EXPECT_NEAR(after.eigenvalues()(i),
                  std::max(before.eigenvalues()(i), 0.0), 1e-13) << "trial " << trial << ", " << i;
    // P - H is positive semi-definite (it adds back the negative part only).
    const Eigen::SelfAdjointEigenSolver<Mat12> diff(P - H);
    EXPECT_GE(diff.eigenvalues().minCoeff(), -1e-13) << "trial " << trial;
    // A projected matrix is its own projection.
    Mat12 again = P;
    psd::project_psd<12>(again);
    EXPECT_LE(max_abs(again - P), 1e-13) << "trial " << trial;
  }
}

// The tridiagonal-QL projection against Eigen's on blocks of every size the solvers project:
// random (scaled from 1e-9 to 1e12), positive definite, rank-deficient, with repeated eigenvalues
// (negative, zero and positive clusters), diagonal, already tridiagonal, zero.
template <int N>
void expect_tridiagonal_ql_equals_the_general_projection(Random& rng) {
  using MatN = Eigen::Matrix<double, N, N>;
  const auto check = [&](const MatN& H, const std::string& what) {
    MatN general = H, fast = H;
    psd::project_psd<N>(general);
    psd::project_psd_tridiagonal_ql<N>(fast);
    const double scale = std::max(H.cwiseAbs().maxCoeff(), 1e-300);
    EXPECT_LE((fast - general).cwiseAbs().maxCoeff(), 2e-14 * scale) << N << " x " << N << ", " << what;
    EXPECT_EQ(fast, fast.transpose()) << N << " x " << N << ", " << what;
  };
  for (int trial = 0; trial < 100; ++trial) {
    const double scale = std::pow(10.0, rng.uniform(-9.0, 12.0));
    const MatN A = random_symmetric<N>(rng);
    check(scale * A, "random " + std::to_string(trial));
    check(scale * (A * A.transpose() + 0.01 * MatN::Identity()), "definite " + std::to_string(trial));
    // Rank 2: two outer products of either sign.
    Eigen::Matrix<double, N, 1> u, v;
    for (int i = 0; i < N; ++i) {
      u(i) = rng.uniform(-1.0, 1.0);
      v(i) = rng.uniform(-1.0, 1.0);
    }
    check(scale * (u * u.transpose() - v * v.transpose()), "rank 2 " + std::to_string(trial));
    // Repeated eigenvalues: Q diag(lambda) Q^T with lambda in {-1, 0, 2} (Q orthogonal).
    const Eigen::SelfAdjointEigenSolver<MatN> eig(A);
    Eigen::Matrix<double, N, 1> lambda;
    for (int i = 0; i < N; ++i) lambda(i) = static_cast<double>(rng.integer(0, 2)) * 1.5 - 1.0;
    const MatN R = eig.eigenvectors() * lambda.asDiagonal() * eig.eigenvectors().transpose();
    check(scale * MatN(0.5 * (R + R.transpose())), "clusters " + std::to_string(trial));
    MatN D = MatN::Zero(), T = MatN::Zero();
    for (int i = 0; i < N; ++i) {
      D(i, i) = A(i, 0);
      T(i, i) = A(i, i);
      if (i + 1 < N) T(i, i + 1) = T(i + 1, i) = A(i, i + 1);
    }
    check(D, "diagonal " + std::to_string(trial));
    check(T, "tridiagonal " + std::to_string(trial));
  }
  check(MatN::Zero(), "zero");
  check(-MatN::Identity(), "minus identity");
}

TEST(PsdProjection, TridiagonalQlEqualsTheGeneralProjection) {
  Random rng(17);
  expect_tridiagonal_ql_equals_the_general_projection<3>(rng);
  expect_tridiagonal_ql_equals_the_general_projection<6>(rng);
  expect_tridiagonal_ql_equals_the_general_projection<9>(rng);
  expect_tridiagonal_ql_equals_the_general_projection<12>(rng);
}

TEST(PsdProjection, TranslationFreeBasisIsOrthonormalAndBlindToTranslations) {
  Random rng(12);
  const Mat9 M = random_symmetric<9>(rng);
  EXPECT_LE((psd::restrict_translation_free(psd::expand_translation_free(M)) - M).cwiseAbs().maxCoeff(), 1e-15);
  // A block that is nothing but translations restricts to zero.
  Mat12 T = Mat12::Zero();
  for (int v = 0; v < 4; ++v)
    for (int w = 0; w < 4; ++w) T.block<3, 3>(3 * v, 3 * w) = Eigen::Matrix3d::Identity();
  EXPECT_LE(psd::restrict_translation_free(T).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(PsdProjection, TranslationFreePathEqualsTheGeneralOne) {
  Random rng(13);
  const Mat12 P = centering();
  int definite = 0;
  for (int trial = 0; trial < 200; ++trial) {
    Mat12 G = random_symmetric<12>(rng);
    // Every third block positive definite on the complement of the translations.
    if (trial % 3 == 0) G = G * G.transpose() + 0.1 * Mat12::Identity();
    const Mat12 H = P * G * P;
    Mat12 general = H, fast = H;
    psd::project_psd<12>(general);
    const bool skipped = psd::project_psd_translation_free(fast);
    EXPECT_LE(max_abs(fast - general), 1e-13 * max_abs(H)) << "trial " << trial;
    EXPECT_EQ(skipped, trial % 3 == 0) << "trial " << trial;
    definite += skipped ? 1 : 0;
    if (skipped) {
      EXPECT_LE(max_abs(fast - H), 1e-14 * max_abs(H)) << "trial " << trial;
    }
  }
  EXPECT_EQ(definite, 67);
}

// The hinge path (project_psd_hinge) against the general 12 x 12 projection, on blocks with the
// null space of a hinge's Hessian: N S N with S symmetric and N the projector onto the complement
// of the translations and of v = (0, u, t1 u, t2 u) (core/psd_projection.hpp). Hinges random, with
// the wings' tips projecting outside the edge (t < 0, t > 1), short and long edges, the tips on
// the edge's line (degenerate wings: v is still the null vector asked for); blocks random
// (indefinite), positive semi-definite, rank one, clustered eigenvalues (-1, 0, 2 repeated), zero.
TEST(PsdProjection, HingePathEqualsTheGeneralOne) {
  Random rng(19);
  const std::string kinds[] = {"random", "semidefinite", "rank one", "clustered", "zero"};
  for (int trial = 0; trial < 400; ++trial) {
    std::array<Vec3, 4> x;
    for (Vec3& p : x) p = rng.vec(-1.0, 1.0);
    const int shape = trial % 4;
    if (shape == 1) x[1] = x[0] + 1e-3 * rng.vec(-1.0, 1.0);  // a short edge
    if (shape == 2) {  // tips far outside the edge's span
      x[2] += 5.0 * (x[1] - x[0]);
      x[3] -= 4.0 * (x[1] - x[0]);
    }
    if (shape == 3) x[2] = x[0] + rng.uniform(-2.0, 3.0) * (x[1] - x[0]);  // a degenerate wing
    const Vec3 e = x[1] - x[0];
    const Vec3 u = e.normalized();
    const double t1 = (x[2] - x[0]).dot(e) / e.squaredNorm(), t2 = (x[3] - x[0]).dot(e) / e.squaredNorm();
    Eigen::Matrix<double, 12, 4> B = Eigen::Matrix<double, 12, 4>::Zero();  // translations and v
    for (int k = 0; k < 4; ++k) B.block<3, 3>(3 * k, 0) = Eigen::Matrix3d::Identity();
    B.block<3, 1>(3, 3) = u;
    B.block<3, 1>(6, 3) = t1 * u;
    B.block<3, 1>(9, 3) = t2 * u;
    const Eigen::HouseholderQR<Eigen::Matrix<double, 12, 4>> qr(B);
    const Eigen::Matrix<double, 12, 4> Y = qr.householderQ() * Eigen::Matrix<double, 12, 4>::Identity();
    const Mat12 N = Mat12::Identity() - Y * Y.transpose();

    const std::string& kind = kinds[(trial / 4) % 5];
    Mat12 S = random_symmetric<12>(rng);
    if (kind == "semidefinite") S = S * S.transpose();
    if (kind == "rank one") {
      Eigen::Matrix<double, 12, 1> g;
      for (int i = 0; i < 12; ++i) g(i) = rng.uniform(-1.0, 1.0);
      S = g * g.transpose();
    }
    if (kind == "clustered") {
      Eigen::Matrix<double, 12, 1> d;
      d << -1, -1, -1, 0, 0, 2, 2, 2, 2, -1, 0, 2;
      const Eigen::HouseholderQR<Mat12> r(random_symmetric<12>(rng));
      const Mat12 R = r.householderQ();
      S = R * d.asDiagonal() * R.transpose();
    }
    if (kind == "zero") S.setZero();
    const double scale = std::pow(10.0, rng.uniform(-6.0, 9.0));
    Mat12 H = scale * (N * S * N);
    H = 0.5 * (H + H.transpose());
    Mat12 general = H, fast = H;
    psd::project_psd<12>(general);
    psd::project_psd_hinge(fast, x[0], x[1], x[2], x[3]);
    const double tol = 1e-13 * std::max(max_abs(H), 1e-300);
    EXPECT_LE(max_abs(fast - general), tol) << "trial " << trial << ", " << kind << ", shape " << shape;
    EXPECT_LE(max_abs(fast - fast.transpose()), tol) << "trial " << trial;  // as symmetric as the general one
  }
}

// (g g^T + C hess V) / alpha over the four points, hess V by central differences of grad V
// (quadratic in the positions, so the differences are exact up to rounding).
Mat12 volume_term_hessian(const std::array<Vec3, 4>& x, double rest, double alpha, double& C) {
  const ConstraintEval e = eval_volume(x[0], x[1], x[2], x[3], rest);
  C = e.C;
  Eigen::Matrix<double, 12, 1> g;
  for (int i = 0; i < 4; ++i) g.segment<3>(3 * i) = e.grad[static_cast<size_t>(i)];
  Mat12 hv;
  const double h = 1e-3;
  for (int k = 0; k < 12; ++k) {
    std::array<Vec3, 4> xp = x, xm = x;
    xp[static_cast<size_t>(k / 3)](k % 3) += h;
    xm[static_cast<size_t>(k / 3)](k % 3) -= h;
    const ConstraintEval ep = eval_volume(xp[0], xp[1], xp[2], xp[3], rest);
    const ConstraintEval em = eval_volume(xm[0], xm[1], xm[2], xm[3], rest);
    for (int i = 0; i < 4; ++i)
      hv.block<3, 1>(3 * i, k) = (ep.grad[static_cast<size_t>(i)] - em.grad[static_cast<size_t>(i)]) / (2.0 * h);
  }
  hv = 0.5 * (hv + hv.transpose());
  return (g * g.transpose() + C * hv) / alpha;
}

TEST(PsdProjection, VolumeTermAnalyticEigensystemEqualsTheGeneralProjection) {
  Random rng(14);
  const std::string shapes[] = {"regular", "flattened", "degenerate", "inverted", "random"};
  int compressed = 0, stretched = 0;
  for (int trial = 0; trial < 250; ++trial) {
    const std::string& shape = shapes[trial % 5];
    std::array<Vec3, 4> x = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
    for (Vec3& p : x) p += 0.2 * rng.vec(-1.0, 1.0);
    if (shape == "flattened") x[3].z() = x[0].z() + 1e-3 * rng.uniform(-1.0, 1.0);
    if (shape == "degenerate") x[3] = 0.5 * (x[1] + x[2]);  // coplanar: V = 0, Z singular
    if (shape == "inverted") std::swap(x[1], x[2]);
    if (shape == "random") for (Vec3& p : x) p = rng.vec(-1.0, 1.0);
    // A far-off origin and a rotation change nothing the term sees.
    const Vec3 shift = rng.vec(-5.0, 5.0);
    for (Vec3& p : x) p += shift;
    const double V = (x[1] - x[0]).dot((x[2] - x[0]).cross(x[3] - x[0])) / 6.0;
    // Rest volumes on both sides of V: the constraint compressed (C < 0) and stretched (C > 0).
    const double rest = V + (trial % 2 == 0 ? 1.0 : -1.0) * rng.uniform(0.0, 0.2);
    const double alpha = trial % 4 < 2 ? 1.0 : 4e-11;
    double C = 0.0;
    Mat12 general = volume_term_hessian(x, rest, alpha, C);
    const double scale = max_abs(general);
    psd::project_psd<12>(general);
    const Mat12 fast = psd::volume_term_hessian_psd(x[0], x[1], x[2], x[3], rest, alpha);
    EXPECT_LE(max_abs(fast - general), 1e-10 * scale)
        << shape << ", trial " << trial << ", C " << C << ", alpha " << alpha;
    (C < 0.0 ? compressed : stretched) += 1;
  }
  EXPECT_GT(compressed, 50);
  EXPECT_GT(stretched, 50);
}

TEST(PsdProjection, VolumeTermAtItsRestVolumeIsTheGradientsOuterProduct) {
  // C = 0: the term's Hessian is g g^T / alpha, already positive semi-definite.
  const std::array<Vec3, 4> x = {Vec3(0.1, 0, 0), Vec3(1, 0.2, 0), Vec3(0, 1, 0.1), Vec3(0.3, 0, 1)};
  const double V = (x[1] - x[0]).dot((x[2] - x[0]).cross(x[3] - x[0])) / 6.0;
  double C = 1.0;
  const Mat12 H = volume_term_hessian(x, V, 2.0, C);
  EXPECT_EQ(C, 0.0);
  EXPECT_LE(max_abs(psd::volume_term_hessian_psd(x[0], x[1], x[2], x[3], V, 2.0) - H), 1e-14 * max_abs(H));
}

}  // namespace
}  // namespace pbdbench
