// core/psd_projection.hpp: projections onto the positive semi-definite cone, the general
// eigen-solve and the fast paths for translation-free blocks and the volume term.
#include "core/psd_projection.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

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

// Householder reduction of the symmetric N x N matrix held in V (row-major, V[i][j] = A(i, j)) to
// tridiagonal form, accumulating the orthogonal transform in V: on return A = V T V^T with T's
// diagonal in d and its off-diagonal in e[1..N-1] (e[0] = 0). The textbook algorithm (Wilkinson
// and Reinsch's tred2), every loop bound a compile-time bound.
template <int N>
void householder_tridiagonal(double (&V)[N][N], double (&d)[N], double (&e)[N]) {
  for (int j = 0; j < N; ++j) d[j] = V[N - 1][j];
  for (int i = N - 1; i > 0; --i) {
    double scale = 0.0, h = 0.0;
    for (int k = 0; k < i; ++k) scale += std::abs(d[k]);
    if (scale == 0.0) {
      e[i] = d[i - 1];
      for (int j = 0; j < i; ++j) {
        d[j] = V[i - 1][j];
        V[i][j] = 0.0;
        V[j][i] = 0.0;
      }
    } else {
      for (int k = 0; k < i; ++k) {
        d[k] /= scale;
        h += d[k] * d[k];
      }
      double f = d[i - 1];
      double g = std::sqrt(h);
      if (f > 0.0) g = -g;
      e[i] = scale * g;
      h -= f * g;
      d[i - 1] = f - g;
      for (int j = 0; j < i; ++j) e[j] = 0.0;
      for (int j = 0; j < i; ++j) {
        f = d[j];
        V[j][i] = f;
        g = e[j] + V[j][j] * f;
        for (int k = j + 1; k <= i - 1; ++k) {
          g += V[k][j] * d[k];
          e[k] += V[k][j] * f;
        }
        e[j] = g;
      }
      f = 0.0;
      for (int j = 0; j < i; ++j) {
        e[j] /= h;
        f += e[j] * d[j];
      }
      const double hh = f / (h + h);
      for (int j = 0; j < i; ++j) e[j] -= hh * d[j];
      for (int j = 0; j < i; ++j) {
        f = d[j];
        g = e[j];
        for (int k = j; k <= i - 1; ++k) V[k][j] -= (f * e[k] + g * d[k]);
        d[j] = V[i - 1][j];
        V[i][j] = 0.0;
      }
    }
    d[i] = h;
  }
  for (int i = 0; i < N - 1; ++i) {  // accumulate the transformations
    V[N - 1][i] = V[i][i];
    V[i][i] = 1.0;
    const double h = d[i + 1];
    if (h != 0.0) {
      for (int k = 0; k <= i; ++k) d[k] = V[k][i + 1] / h;
      for (int j = 0; j <= i; ++j) {
        double g = 0.0;
        for (int k = 0; k <= i; ++k) g += V[k][i + 1] * V[k][j];
        for (int k = 0; k <= i; ++k) V[k][j] -= g * d[k];
      }
    }
    for (int k = 0; k <= i; ++k) V[k][i + 1] = 0.0;
  }
  for (int j = 0; j < N; ++j) {
    d[j] = V[N - 1][j];
    V[N - 1][j] = 0.0;
  }
  V[N - 1][N - 1] = 1.0;
  e[0] = 0.0;
}

// The implicit QL iteration with Wilkinson's shift on the tridiagonal (d, e) of
// householder_tridiagonal (Bowdler, Martin, Reinsch and Wilkinson's tql2), the rotations applied
// to W = V^T (row j of W: the j-th eigenvector, contiguous, so that a rotation of two rows
// vectorises). On return d holds the eigenvalues (unsorted). Returns false when an eigenvalue took
// more than 60 iterations (the caller falls back to Eigen's solver).
template <int N>
bool implicit_ql(double (&W)[N][N], double (&d)[N], double (&e)[N]) {
  for (int i = 1; i < N; ++i) e[i - 1] = e[i];
  e[N - 1] = 0.0;
  double f = 0.0, tst1 = 0.0;
  constexpr double eps = std::numeric_limits<double>::epsilon();
  for (int l = 0; l < N; ++l) {
    tst1 = std::max(tst1, std::abs(d[l]) + std::abs(e[l]));
    int m = l;
    while (m < N - 1 && !(std::abs(e[m]) <= eps * tst1)) ++m;
    if (m > l) {
      int iterations = 0;
      do {
        if (++iterations > 60) return false;
        double g = d[l];
        double p = (d[l + 1] - g) / (2.0 * e[l]);
        double r = std::sqrt(p * p + 1.0);
        if (p < 0.0) r = -r;
        d[l] = e[l] / (p + r);
        d[l + 1] = e[l] * (p + r);
        const double dl1 = d[l + 1];
        double h = g - d[l];
        for (int i = l + 2; i < N; ++i) d[i] -= h;
        f += h;
        p = d[m];
        double c = 1.0, c2 = 1.0, c3 = 1.0, s = 0.0, s2 = 0.0;
        const double el1 = e[l + 1];
        for (int i = m - 1; i >= l; --i) {
          c3 = c2;
          c2 = c;
          s2 = s;
          g = c * e[i];
          h = c * p;
          r = std::sqrt(p * p + e[i] * e[i]);
          e[i + 1] = s * r;
          s = e[i] / r;
          c = p / r;
          p = c * d[i] - s * g;
          d[i + 1] = h + s * (c * g + s * d[i]);
          for (int k = 0; k < N; ++k) {
            const double w1 = W[i + 1][k], w0 = W[i][k];
            W[i + 1][k] = s * w0 + c * w1;
            W[i][k] = c * w0 - s * w1;
          }
        }
        p = -s * s2 * c3 * el1 * e[l] / dl1;
        e[l] = s * p;
        d[l] = c * p;
      } while (std::abs(e[l]) > eps * tst1);
    }
    d[l] += f;
    e[l] = 0.0;
  }
  return true;
}

// The eigensystem of the symmetric N x N matrix H: H = sum_j d_j w_j w_j^T, w_j = row j of W
// (orthonormal), d unsorted. Should the QL iteration not converge, Eigen's solver gives it.
template <int N, class Matrix>
void symmetric_eigensystem(const Matrix& H, double (&d)[N], double (&W)[N][N]) {
  double V[N][N], e[N];
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) V[i][j] = H(i, j);
  householder_tridiagonal<N>(V, d, e);
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) W[i][j] = V[j][i];
  if (implicit_ql<N>(W, d, e)) return;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(H);
  for (int j = 0; j < N; ++j) {
    d[j] = eig.eigenvalues()(j);
    for (int k = 0; k < N; ++k) W[j][k] = eig.eigenvectors()(k, j);
  }
}

// Z = U diag(s) V^T with U and V rotations, s_0 >= s_1 >= |s_2| and s_2 < 0 when det Z < 0 (the
// convention of volume_term_hessian_psd). V from the eigensystem of Z^T Z, then U and s from the
// Gram-Schmidt factorisation of B = Z V = U R (R diagonal in exact arithmetic; its off-diagonal,
// of the order of rounding times |Z|, is dropped): the singular values come from B's columns, not
// from the squares, so a small one keeps its accuracy relative to |Z|.
void rotation_svd(const Mat3& Z, Mat3& U, Vec3& s, Mat3& V) {
  const Mat3 A = Z.transpose() * Z;
  double d[3], W[3][3];
  symmetric_eigensystem<3>(A, d, W);
  int order[3] = {0, 1, 2};  // eigenvalues in decreasing order
  if (d[order[0]] < d[order[1]]) std::swap(order[0], order[1]);
  if (d[order[1]] < d[order[2]]) std::swap(order[1], order[2]);
  if (d[order[0]] < d[order[1]]) std::swap(order[0], order[1]);
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) V(r, c) = W[order[c]][r];
  if (V.determinant() < 0.0) V.col(2) = -V.col(2);
  const Mat3 B = Z * V;
  const double scale = Z.cwiseAbs().maxCoeff();
  // The first column: B's largest; a zero matrix takes any rotation (U = V).
  s(0) = B.col(0).norm();
  if (!(s(0) > 0.0)) {
    U = V;
    s.setZero();
    return;
  }
  const Vec3 u0 = B.col(0) / s(0);
  Vec3 b1 = B.col(1) - u0.dot(B.col(1)) * u0;
  s(1) = b1.norm();
  Vec3 u1;
  if (s(1) > 1e-300 * scale && s(1) > 0.0) {
    u1 = b1 / s(1);
  } else {  // rank one: any unit vector orthogonal to u0
    const int k = std::abs(u0(0)) < 0.6 ? 0 : (std::abs(u0(1)) < 0.6 ? 1 : 2);
    u1 = u0.cross(Vec3::Unit(k)).normalized();
    s(1) = 0.0;
  }
  const Vec3 u2 = u0.cross(u1);
  s(2) = u2.dot(B.col(2));
  U.col(0) = u0;
  U.col(1) = u1;
  U.col(2) = u2;
}

}  // namespace

template <int N>
void project_psd_tridiagonal_ql(Eigen::Matrix<double, N, N>& H) {
  double d[N], W[N][N];
  symmetric_eigensystem<N>(H, d, W);
  // [H]_+ = sum over the positive eigenvalues of d_j w_j w_j^T, its upper triangle mirrored (the
  // result symmetric bit for bit).
  double P[N][N] = {};
  for (int j = 0; j < N; ++j) {
    if (!(d[j] > 0.0)) continue;
    for (int r = 0; r < N; ++r) {
      const double a = d[j] * W[j][r];
      for (int c = r; c < N; ++c) P[r][c] += a * W[j][c];
    }
  }
  for (int r = 0; r < N; ++r)
    for (int c = r; c < N; ++c) H(r, c) = H(c, r) = P[r][c];
}
template void project_psd_tridiagonal_ql<3>(Eigen::Matrix<double, 3, 3>&);
template void project_psd_tridiagonal_ql<6>(Eigen::Matrix<double, 6, 6>&);
template void project_psd_tridiagonal_ql<8>(Eigen::Matrix<double, 8, 8>&);
template void project_psd_tridiagonal_ql<9>(Eigen::Matrix<double, 9, 9>&);
template void project_psd_tridiagonal_ql<12>(Eigen::Matrix<double, 12, 12>&);

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
template void project_psd<8>(Eigen::Matrix<double, 8, 8>&);
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
  if (!definite) project_psd_tridiagonal_ql<9>(M);
  H = expand_translation_free(M);
  return definite;
}

namespace {

// M <- P M P with P = I - beta w w^T, beta = 2 / (w^T w) (a Householder reflection): with
// p = beta M w and r = p - (beta w^T p / 2) w, P M P = M - w r^T - r w^T. Each entry is
// M_ij - (w_i r_j + r_i w_j), the same products summed in the same order on both sides: the result
// is symmetric bit for bit when M is.
void reflect_both_sides(Mat9& M, const Vec9& w, double beta) {
  const Vec9 p = beta * (M * w);
  const Vec9 r = p - (0.5 * beta * w.dot(p)) * w;
  for (int j = 0; j < 9; ++j)
    for (int i = 0; i < 9; ++i) M(i, j) -= w(i) * r(j) + r(i) * w(j);
}

}  // namespace

void project_psd_hinge(Mat12& H, const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  const Vec3 e = x1 - x0;
  const double le2 = e.squaredNorm();
  if (!(le2 > 0.0)) {
    project_psd_translation_free(H);
    return;
  }
  // v = (0, e, t1 e, t2 e) / |e| over the vertices; its restriction z = sigma (x) e (the length of
  // z is irrelevant: only its direction enters the reflection).
  const double s[4] = {0.0, 1.0, (x2 - x0).dot(e) / le2, (x3 - x0).dot(e) / le2};
  Vec9 w;
  for (int c = 0; c < 3; ++c) {
    const double sigma = kQ[0][c] * s[0] + kQ[1][c] * s[1] + kQ[2][c] * s[2] + kQ[3][c] * s[3];
    w.segment<3>(3 * c) = sigma * e;
  }
  // The reflection that maps z onto -sign(z_8) |z| e_8: w = z + sign(z_8) |z| e_8 (the sign that
  // avoids cancellation, so |w| >= |z| > 0: sigma != 0 since s is not constant).
  const double znorm = w.norm();
  w(8) += std::signbit(w(8)) ? -znorm : znorm;
  const double beta = 2.0 / w.squaredNorm();

  Mat9 M = restrict_translation_free(H);
  M = 0.5 * (M + M.transpose());
  reflect_both_sides(M, w, beta);
  Eigen::Matrix<double, 8, 8> lead = M.topLeftCorner<8, 8>();
  project_psd_tridiagonal_ql<8>(lead);
  M.setZero();
  M.topLeftCorner<8, 8>() = lead;
  reflect_both_sides(M, w, beta);
  H = expand_translation_free(M);
}

Mat12 volume_term_hessian_psd(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                              double rest, double alpha) {
  constexpr double kappa = 1.0 / 3.0;  // V = kappa det Z
  const Vec3 e1 = x1 - x0, e2 = x2 - x0, e3 = x3 - x0;
  const double C = e1.dot(e2.cross(e3)) / 6.0 - rest;
  const Mat3 Z = translation_free_coordinates(x0, x1, x2, x3);

  // Z = U diag(s) V^T with U and V rotations: a reflection moves to the smallest singular value.
  Mat3 U, V;
  Vec3 s;
  rotation_svd(Z, U, s, V);

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
  double lambda[3], W[3][3];
  symmetric_eigensystem<3>(S, lambda, W);
  for (int m = 0; m < 3; ++m)
    if (lambda[m] > 0.0) add_mode(lambda[m], U * Vec3(W[m][0], W[m][1], W[m][2]).asDiagonal() * V.transpose());
  return expand_translation_free(K);
}

}  // namespace pbdbench::psd
