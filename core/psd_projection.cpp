// core/psd_projection.hpp: projections onto the positive semi-definite cone, the general
// eigen-solve and the fast paths for translation-free blocks and the volume term.
#include "core/psd_projection.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>

namespace pbdbench::psd {

namespace {

using Mat3 = Eigen::Matrix3d;
using Vec9 = Eigen::Matrix<double, 9, 1>;

// Q = q (x) I3 of the header: q(v, c) = H4(v, c + 1) / 2, H4 the 4 x 4 Hadamard matrix
// [1 1 1 1; 1 -1 1 -1; 1 1 -1 -1; 1 -1 -1 1] (its columns after the first: orthonormal once
// halved, and each sums to 0).
constexpr double kQ[4][3] = {{0.5, 0.5, 0.5}, {-0.5, 0.5, -0.5}, {0.5, -0.5, -0.5}, {-0.5, -0.5, 0.5}};

// Z = X q: the positions' coordinates on the translation-free basis, column c = sum_v q(v, c) x_v.
Mat3 translation_free_coordinates(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  const Vec3* x[4] = {&x0, &x1, &x2, &x3};
  Mat3 Z = Mat3::Zero();
  for (int c = 0; c < 3; ++c)
    for (int v = 0; v < 4; ++v) Z.col(c) += kQ[v][c] * *x[v];
  return Z;
}

Eigen::Map<const Vec9> vec(const Mat3& m) { return Eigen::Map<const Vec9>(m.data()); }

}  // namespace

template <int N>
void project_psd(Eigen::Matrix<double, N, N>& H) {
  // Products of small fixed sizes coefficient by coefficient (lazyProduct): Eigen's blocked
  // kernel, which it picks above 20 for the sum of the sizes, is slower at these.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(H);
  const Eigen::Matrix<double, N, N> scaled = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal();
  H = scaled.lazyProduct(eig.eigenvectors().transpose());
}
template void project_psd<3>(Eigen::Matrix<double, 3, 3>&);
template void project_psd<6>(Eigen::Matrix<double, 6, 6>&);
template void project_psd<9>(Eigen::Matrix<double, 9, 9>&);
template void project_psd<12>(Eigen::Matrix<double, 12, 12>&);

// Both products block by block (3 x 3 blocks, q's entries +-1/2): a quarter of the arithmetic of
// the dense 12 x 9 products.
Mat9 restrict_translation_free(const Mat12& H) {
  Eigen::Matrix<double, 9, 12> G;  // q^T H by blocks: G_cw = sum_v q(v, c) H_vw
  for (int c = 0; c < 3; ++c)
    for (int w = 0; w < 4; ++w)
      G.block<3, 3>(3 * c, 3 * w) = kQ[0][c] * H.block<3, 3>(0, 3 * w) + kQ[1][c] * H.block<3, 3>(3, 3 * w) +
                                    kQ[2][c] * H.block<3, 3>(6, 3 * w) + kQ[3][c] * H.block<3, 3>(9, 3 * w);
  Mat9 M;  // M_cd = sum_w G_cw q(w, d)
  for (int c = 0; c < 3; ++c)
    for (int d = 0; d < 3; ++d)
      M.block<3, 3>(3 * c, 3 * d) = kQ[0][d] * G.block<3, 3>(3 * c, 0) + kQ[1][d] * G.block<3, 3>(3 * c, 3) +
                                    kQ[2][d] * G.block<3, 3>(3 * c, 6) + kQ[3][d] * G.block<3, 3>(3 * c, 9);
  return M;
}

Mat12 expand_translation_free(const Mat9& M) {
  Eigen::Matrix<double, 12, 9> G;  // q M by blocks: G_vd = sum_c q(v, c) M_cd
  for (int v = 0; v < 4; ++v)
    for (int d = 0; d < 3; ++d)
      G.block<3, 3>(3 * v, 3 * d) = kQ[v][0] * M.block<3, 3>(0, 3 * d) + kQ[v][1] * M.block<3, 3>(3, 3 * d) +
                                    kQ[v][2] * M.block<3, 3>(6, 3 * d);
  Mat12 H;  // H_vw = sum_d G_vd q(w, d)
  for (int v = 0; v < 4; ++v)
    for (int w = 0; w < 4; ++w)
      H.block<3, 3>(3 * v, 3 * w) = kQ[w][0] * G.block<3, 3>(3 * v, 0) + kQ[w][1] * G.block<3, 3>(3 * v, 3) +
                                    kQ[w][2] * G.block<3, 3>(3 * v, 6);
  return H;
}

bool project_psd_translation_free(Mat12& H) {
  Mat9 M = restrict_translation_free(H);
  M = 0.5 * (M + M.transpose());
  const Eigen::LLT<Mat9> llt(M);
  const bool definite = llt.info() == Eigen::Success;
  if (!definite) project_psd<9>(M);
  H = expand_translation_free(M);
  return definite;
}

Mat12 volume_term_hessian_psd(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                              double rest, double alpha) {
  constexpr double kappa = 1.0 / 3.0;  // V = kappa det Z
  const Vec3 e1 = x1 - x0, e2 = x2 - x0, e3 = x3 - x0;
  const double C = e1.dot(e2.cross(e3)) / 6.0 - rest;
  const Mat3 Z = translation_free_coordinates(x0, x1, x2, x3);

  // Z = U diag(s) V^T with U and V rotations: a reflection moves to the smallest singular value.
  const Eigen::JacobiSVD<Mat3> svd(Z, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 U = svd.matrixU(), V = svd.matrixV();
  Vec3 s = svd.singularValues();
  if (U.determinant() < 0.0) {
    U.col(2) = -U.col(2);
    s(2) = -s(2);
  }
  if (V.determinant() < 0.0) {
    V.col(2) = -V.col(2);
    s(2) = -s(2);
  }

  const double inv_alpha = 1.0 / alpha;
  const double ck = C * kappa * inv_alpha;
  Mat9 K = Mat9::Zero();  // [K]_+ over vec Z
  auto add_mode = [&](double eigenvalue, const Mat3& D) {
    if (eigenvalue > 0.0) K.noalias() += eigenvalue * (vec(D) * vec(D).transpose());
  };
  constexpr int pairs[3][3] = {{0, 1, 2}, {0, 2, 1}, {1, 2, 0}};
  const double r2 = std::sqrt(0.5);
  for (const auto& p : pairs) {
    const int i = p[0], j = p[1], k = p[2];
    const Mat3 a = U.col(i) * V.col(j).transpose(), b = U.col(j) * V.col(i).transpose();
    add_mode(-ck * s(k), r2 * (a + b));
    add_mode(ck * s(k), r2 * (a - b));
  }
  const Vec3 w(s(1) * s(2), s(0) * s(2), s(0) * s(1));
  Mat3 S = (kappa * kappa * inv_alpha) * (w * w.transpose());
  S(0, 1) += ck * s(2);
  S(1, 0) += ck * s(2);
  S(0, 2) += ck * s(1);
  S(2, 0) += ck * s(1);
  S(1, 2) += ck * s(0);
  S(2, 1) += ck * s(0);
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(S);
  for (int m = 0; m < 3; ++m) {
    if (!(eig.eigenvalues()(m) > 0.0)) continue;
    const Vec3 d = eig.eigenvectors().col(m);
    add_mode(eig.eigenvalues()(m), U * d.asDiagonal() * V.transpose());
  }
  return expand_translation_free(K);
}

}  // namespace pbdbench::psd
