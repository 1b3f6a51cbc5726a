// Projections of symmetric blocks onto the positive semi-definite cone, [H]_+ = the same matrix
// with its negative eigenvalues clamped to 0: what the Newton matrices of the global solvers and
// of the reference integrators are made of, one block per term (core/fem.cpp's elements,
// reference/energy.cpp's constraint terms, reference/global_newton.cpp's rows). Pure functions on
// fixed-size matrices: nothing is allocated. Each fast path below is the general projection of the
// same matrix in exact arithmetic (it changes rounding only), and tests/core/
// test_psd_projection.cpp compares it with project_psd on random blocks, inverted ones included.
//
// Translation-free blocks. A term over four particles that depends only on their differences
// (a volume, a bending hinge, a finite element) has a 12 x 12 Hessian H with H (1 (x) I3) = 0:
// it is zero on the three translations. With q the 4 x 3 matrix of the columns of the 4 x 4
// Hadamard matrix after the first, over 2 (orthonormal and orthogonal to (1, 1, 1, 1)), and
// Q = q (x) I3 (12 x 9, Q(3 v + a, 3 c + a) = q(v, c)), H = Q M Q^T with M = Q^T H Q (9 x 9), so
// [H]_+ = Q [M]_+ Q^T: a 9 x 9 eigen-solve instead of a 12 x 12 one, and none at all when M is
// positive definite (its Cholesky factorisation succeeds), where [M]_+ = M.
//
// The volume term. For C = V - rest, V = (1/6) (x1 - x0) . ((x2 - x0) x (x3 - x0)), the
// positions' coordinates Z = X q (3 x 3, X = [x0 x1 x2 x3]) give V = kappa det Z with
// kappa = 1/3 (the edge matrix [x1 - x0, x2 - x0, x3 - x0] is Z r, r = q^T [-1 -1 -1; I3],
// det r = 2), and the term
// C^2 / (2 alpha) has, over vec Z, the Hessian
//   K = (kappa^2 vec(cof Z) vec(cof Z)^T + C kappa d2(det Z)/dZ2) / alpha,
// whose eigensystem is known from the singular value decomposition Z = U diag(s) V^T (U, V
// rotations, s_2 < 0 when det Z < 0; Smith, de Goes and Kim 2019, "Analytic eigensystems for
// isotropic distortion energies", sec. 5, for det): with D the direction dZ = U D V^T,
//   D = (e_i e_j^T + e_j e_i^T) / sqrt2, i < j:  eigenvalue -C kappa s_k / alpha  (k the third index)
//   D = (e_i e_j^T - e_j e_i^T) / sqrt2, i < j:  eigenvalue +C kappa s_k / alpha
//   D = diag(d): the 3 x 3 block (kappa^2 w w^T + C kappa [0 s2 s1; s2 0 s0; s1 s0 0]) / alpha,
//                w = (s1 s2, s0 s2, s0 s1) (cof Z = U diag(w) V^T), solved as a 3 x 3.
// (The second derivative of det(S + t D) at t = 0 is 2 sum_k s_k (D_ii D_jj - D_ij D_ji).) So
// [H]_+ = sum over the nine modes of max(eigenvalue, 0) (Q vec(U D V^T)) (Q vec(U D V^T))^T: a
// 3 x 3 SVD and a 3 x 3 eigen-solve instead of a 12 x 12 one.
#pragma once

#include <Eigen/Core>

#include "core/model.hpp"

namespace pbdbench::psd {

using Mat12 = Eigen::Matrix<double, 12, 12>;
using Mat9 = Eigen::Matrix<double, 9, 9>;

// The general projection: a fixed-size self-adjoint eigen-solve of H (symmetric), N x N.
template <int N>
void project_psd(Eigen::Matrix<double, N, N>& H);
extern template void project_psd<3>(Eigen::Matrix<double, 3, 3>&);
extern template void project_psd<6>(Eigen::Matrix<double, 6, 6>&);
extern template void project_psd<8>(Eigen::Matrix<double, 8, 8>&);
extern template void project_psd<9>(Eigen::Matrix<double, 9, 9>&);
extern template void project_psd<12>(Eigen::Matrix<double, 12, 12>&);

// The same projection by a fixed-size Householder tridiagonalisation and implicit QL iteration
// with Wilkinson's shift (the eigenvectors' rotations applied to contiguous rows), every loop
// bound a compile-time constant: the general projection to rounding, 1.2x Eigen's solver at 9 x 9
// and 1.6x at 12 x 12 (psd/9/*, psd/12/* of bench_reference). Uses Eigen's
// solver when an eigenvalue does not converge in 60 iterations (never seen).
template <int N>
void project_psd_tridiagonal_ql(Eigen::Matrix<double, N, N>& H);
extern template void project_psd_tridiagonal_ql<3>(Eigen::Matrix<double, 3, 3>&);
extern template void project_psd_tridiagonal_ql<6>(Eigen::Matrix<double, 6, 6>&);
extern template void project_psd_tridiagonal_ql<8>(Eigen::Matrix<double, 8, 8>&);
extern template void project_psd_tridiagonal_ql<9>(Eigen::Matrix<double, 9, 9>&);
extern template void project_psd_tridiagonal_ql<12>(Eigen::Matrix<double, 12, 12>&);

// M = Q^T H Q and H = Q M Q^T (Q of the header).
Mat9 restrict_translation_free(const Mat12& H);
Mat12 expand_translation_free(const Mat9& M);

// [H]_+ of a symmetric translation-free block (H (1 (x) I3) = 0 up to rounding; what H holds on
// the translations is dropped), through the 9 x 9 restriction (project_psd_tridiagonal_ql<9>).
// Returns true when M was positive definite and no eigen-solve ran.
bool project_psd_translation_free(Mat12& H);

// [H]_+ of a symmetric block of a bending hinge over (x0, x1, x2, x3), the hinge the edge
// x0-x1 and the wings' tips x2 and x3: a Hessian of any function of the dihedral angle phi
// (reference/energy.cpp's (grad phi grad phi^T - C s hess phi) / alpha). Besides the
// translations, such a block has the null vector
//   v = (0, u, t1 u, t2 u),  u = (x1 - x0) / |x1 - x0|,  t_k = (x_{k+1} - x0) . u / |x1 - x0|
// (each vertex slid along the hinge in proportion to where it projects on it): sliding x_k by
// s_k u keeps u and both wings' planes, so phi(x + sum_k s_k e_k (x) u) = phi(x) for every s,
// whence H v = -(du/dx)^T sum_k s_k grad_k phi, and sum_k s_k grad_k phi = 0 for this s
// (grad_2 phi = -n1 / h1, grad_3 phi = n2 / h2, grad_1 phi = t1 n1 / h1 - t2 n2 / h2); and
// grad phi . v = 0. On the 9 x 9 restriction M (header above) v is z = sigma (x) u,
// sigma_c = sum_k q(k, c) s_k; with the Householder reflection P that maps z onto the last axis,
// P M P is zero on its last row and column in exact arithmetic, so [M]_+ = P ([M']_+ (+) 0) P
// with M' its leading 8 x 8: an 8 x 8 eigen-solve (project_psd_tridiagonal_ql<8>) instead of a
// 9 x 9 one, and no Cholesky attempt (such a block, C != 0, has 3 or 4 negative eigenvalues: the
// rank-one grad phi grad phi^T cannot make the 4 negative ones of hess phi positive; at C = 0 it is
// singular). The general projection of H to rounding (tests/core/test_psd_projection.cpp).
// A zero-length hinge (u undefined) goes through project_psd_translation_free.
void project_psd_hinge(Mat12& H, const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3);

// [(g g^T + C hess V) / alpha]_+ over (x0, x1, x2, x3), g = grad V, for the volume term
// C^2 / (2 alpha) with C = V(x) - rest (alpha > 0), by the analytic eigensystem of the header.
Mat12 volume_term_hessian_psd(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                              double rest, double alpha);

}  // namespace pbdbench::psd
