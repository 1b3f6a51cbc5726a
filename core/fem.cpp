// The material part of core/fem.hpp: energy densities, first Piola-Kirchhoff stresses and their
// derivatives for the materials, and the element energy, gradient and Hessian.
// (lame, snh_lambda, deformation_gradient, the XPBD constraints and add_fem_elements are in
// core/fem_constraints.cpp.)
//
// Notation: F = [f0 f1 f2] by columns, J = det F, cof F = dJ/dF = [f1 x f2, f2 x f0, f0 x f1]
// (= J F^-T when F is invertible), [v]x the cross-product matrix of v. Derivatives with respect
// to F act on vec(dF), column-major, so entry (a, b) of F is component a + 3 b.
#include "core/fem.hpp"
#include "core/psd_projection.hpp"

#include <Eigen/SVD>
#include <cmath>
#include <stdexcept>
#include <string>

namespace pbdbench::fem {

namespace {

Mat3 cross_matrix(const Vec3& v) {
  Mat3 m;
  m << 0.0, -v.z(), v.y(),  //
      v.z(), 0.0, -v.x(),   //
      -v.y(), v.x(), 0.0;
  return m;
}

// cof F = dJ/dF.
Mat3 cofactor(const Mat3& F) {
  Mat3 c;
  c.col(0) = F.col(1).cross(F.col(2));
  c.col(1) = F.col(2).cross(F.col(0));
  c.col(2) = F.col(0).cross(F.col(1));
  return c;
}

// d vec(cof F) / d vec(F) = d^2 J / dF^2, linear in F (Smith et al. 2018, eq. 27 and sec. 4.2):
//   [    0     -[f2]x   [f1]x ]
//   [  [f2]x     0     -[f0]x ]
//   [ -[f1]x   [f0]x     0    ]
// Block (i, j) maps column j of dF to column i of d cof F: d(f1 x f2) = -[f2]x df1 + [f1]x df2,
// and cyclically.
Mat9 cofactor_derivative(const Mat3& F) {
  const Mat3 x0 = cross_matrix(F.col(0)), x1 = cross_matrix(F.col(1)), x2 = cross_matrix(F.col(2));
  Mat9 h = Mat9::Zero();
  h.block<3, 3>(0, 3) = -x2;
  h.block<3, 3>(0, 6) = x1;
  h.block<3, 3>(3, 0) = x2;
  h.block<3, 3>(3, 6) = -x0;
  h.block<3, 3>(6, 0) = -x1;
  h.block<3, 3>(6, 3) = x0;
  return h;
}

Eigen::Map<const Eigen::Matrix<double, 9, 1>> vec(const Mat3& m) {
  return Eigen::Map<const Eigen::Matrix<double, 9, 1>>(m.data());
}

// F = U diag(sigma) V^T with U and V rotations (det = +1): when the SVD's U or V is a reflection,
// the column of the smallest singular value (the last: they come sorted in decreasing order) and
// that singular value change sign, so sigma(2) < 0 exactly when det F < 0. The polar rotation is
// then R = U V^T, a proper rotation for every F (Irving et al. 2004, Stomakhin et al. 2012).
struct RotationSvd {
  Mat3 U, V;
  Vec3 sigma;
};

RotationSvd rotation_svd(const Mat3& F) {
  const Eigen::JacobiSVD<Mat3> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  RotationSvd s{svd.matrixU(), svd.matrixV(), svd.singularValues()};
  if (s.U.determinant() < 0.0) {
    s.U.col(2) = -s.U.col(2);
    s.sigma(2) = -s.sigma(2);
  }
  if (s.V.determinant() < 0.0) {
    s.V.col(2) = -s.V.col(2);
    s.sigma(2) = -s.sigma(2);
  }
  return s;
}

// |sigma_i + sigma_j| below this is replaced by it (with its sign) in dR/dF. F is dimensionless
// and of order 1, so the floor is absolute. Only an element crushed to a line (two singular
// values near 0) or an inverted one with sigma_i ~ -sigma_j gets there: at such F the polar
// rotation is not differentiable (it jumps) and the exact derivative is unbounded; the guard keeps
// the Hessian finite there and changes nothing elsewhere.
constexpr double kSigmaSumFloor = 1e-8;

// d vec(R) / d vec(F) of the polar rotation R = U V^T. With F = R S, dF = dR S + R dS and
// dR = R W (W skew), the skew part of R^T dF gives W S + S W = R^T dF - dF^T R, that is
// (tr(S) I - S) w = 2 axial(skew(R^T dF)). In the singular basis, with dF^ = U^T dF V,
//   dR = sum over pairs i < j of (dF^_ij - dF^_ji) / (sigma_i + sigma_j) T_ij,
//   T_ij = U (e_i e_j^T - e_j e_i^T) V^T,   T_ij : dF = dF^_ij - dF^_ji,
// so dR/dF = sum_{i<j} vec(T_ij) vec(T_ij)^T / (sigma_i + sigma_j) (the twist modes of
// Smith et al. 2019, with eigenvalues 2 / (sigma_i + sigma_j) on the unit twists).
// Nothing divides by sigma_i - sigma_j: equal singular values, where U and V are not unique, give
// the same matrix whichever singular vectors the SVD returns.
Mat9 rotation_derivative(const RotationSvd& s) {
  Mat9 d = Mat9::Zero();
  constexpr int pairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (const auto& p : pairs) {
    const int i = p[0], j = p[1];
    double denom = s.sigma(i) + s.sigma(j);
    if (std::abs(denom) < kSigmaSumFloor) denom = denom < 0.0 ? -kSigmaSumFloor : kSigmaSumFloor;
    const Mat3 T = s.U.col(i) * s.V.col(j).transpose() - s.U.col(j) * s.V.col(i).transpose();
    const auto t = vec(T);
    d.noalias() += (t * t.transpose()) / denom;
  }
  return d;
}

// StVK for a 3 x D deformation gradient (D = 3: a tet, D = 2: a triangle), E = (F^T F - I) / 2:
//   Psi = mu E : E + lambda/2 tr(E)^2,   P = F S,   S = 2 mu E + lambda tr(E) I
//   dP = dF S + F dS,   dS = 2 mu dE + lambda tr(dE) I,   dE = (F^T dF + dF^T F) / 2
// dP/dF is built column by column: column (a + 3 c) is vec(dP) for dF = e_a e_c^T.
template <int D>
double stvk_density(double mu, double lambda, const Eigen::Matrix<double, 3, D>& F) {
  const Eigen::Matrix<double, D, D> E =
      0.5 * (F.transpose() * F - Eigen::Matrix<double, D, D>::Identity());
  const double tr = E.trace();
  return mu * E.squaredNorm() + 0.5 * lambda * tr * tr;
}

template <int D>
Eigen::Matrix<double, 3, D> stvk_piola(double mu, double lambda, const Eigen::Matrix<double, 3, D>& F) {
  using MatD = Eigen::Matrix<double, D, D>;
  const MatD E = 0.5 * (F.transpose() * F - MatD::Identity());
  const MatD S = 2.0 * mu * E + lambda * E.trace() * MatD::Identity();
  return F * S;
}

template <int D>
Eigen::Matrix<double, 3 * D, 3 * D> stvk_derivative(double mu, double lambda,
                                                    const Eigen::Matrix<double, 3, D>& F) {
  using MatD = Eigen::Matrix<double, D, D>;
  using Mat3D = Eigen::Matrix<double, 3, D>;
  const MatD E = 0.5 * (F.transpose() * F - MatD::Identity());
  const MatD S = 2.0 * mu * E + lambda * E.trace() * MatD::Identity();
  Eigen::Matrix<double, 3 * D, 3 * D> d;
  for (int c = 0; c < D; ++c)
    for (int a = 0; a < 3; ++a) {
      Mat3D dF = Mat3D::Zero();
      dF(a, c) = 1.0;
      const MatD dE = 0.5 * (F.transpose() * dF + dF.transpose() * F);
      const MatD dS = 2.0 * mu * dE + lambda * dE.trace() * MatD::Identity();
      const Mat3D dP = dF * S + F * dS;
      d.col(a + 3 * c) = Eigen::Map<const Eigen::Matrix<double, 3 * D, 1>>(dP.data());
    }
  return d;
}

// Linear elasticity, e = (F + F^T) / 2 - I:
//   Psi = mu e : e + lambda/2 tr(e)^2,   P = 2 mu e + lambda tr(e) I,
//   dP = mu (dF + dF^T) + lambda tr(dF) I   (constant).
Mat3 small_strain(const Mat3& F) { return 0.5 * (F + F.transpose()) - Mat3::Identity(); }

}  // namespace

// ---------------------------------------------------------------------------------------------
// Materials.
//
// Stable neo-Hookean without the log term (Smith et al. 2018; Macklin and Mueller 2021), with
// ls = snh_lambda(mu, lambda) = lambda + mu and a = 1 + mu / ls:
//   Psi   = mu/2 (|F|^2 - 3) + ls/2 (J - a)^2
//   P     = mu F + ls (J - a) cof F
//   dP/dF = mu I9 + ls vec(cof F) vec(cof F)^T + ls (J - a) d(cof F)/dF
// Small strains, F = I + H: P = mu (H + H^T) + lambda tr(H) I + O(|H|^2) (linear elasticity).
//
// Fixed corotated (Stomakhin et al. 2012), F = R S:
//   Psi   = mu |F - R|^2 + lambda/2 (J - 1)^2
//   P     = 2 mu (F - R) + lambda (J - 1) cof F
//   dP/dF = 2 mu (I9 - dR/dF) + lambda vec(cof F) vec(cof F)^T + lambda (J - 1) d(cof F)/dF

double energy_density(Material material, double mu, double lambda, const Mat3& F) {
  const double J = F.determinant();
  switch (material) {
    case Material::StableNeoHookean: {
      const double ls = snh_lambda(mu, lambda);
      const double a = 1.0 + mu / ls;
      return 0.5 * mu * (F.squaredNorm() - 3.0) + 0.5 * ls * (J - a) * (J - a);
    }
    case Material::Corotated: {
      const RotationSvd s = rotation_svd(F);
      const Mat3 R = s.U * s.V.transpose();
      return mu * (F - R).squaredNorm() + 0.5 * lambda * (J - 1.0) * (J - 1.0);
    }
    case Material::StVK:
      return stvk_density<3>(mu, lambda, F);
    case Material::Linear: {
      const Mat3 e = small_strain(F);
      return mu * e.squaredNorm() + 0.5 * lambda * e.trace() * e.trace();
    }
  }
  return 0.0;
}

Mat3 first_piola(Material material, double mu, double lambda, const Mat3& F) {
  const double J = F.determinant();
  const Mat3 cof = cofactor(F);
  switch (material) {
    case Material::StableNeoHookean: {
      const double ls = snh_lambda(mu, lambda);
      const double a = 1.0 + mu / ls;
      return mu * F + ls * (J - a) * cof;
    }
    case Material::Corotated: {
      const RotationSvd s = rotation_svd(F);
      const Mat3 R = s.U * s.V.transpose();
      return 2.0 * mu * (F - R) + lambda * (J - 1.0) * cof;
    }
    case Material::StVK:
      return stvk_piola<3>(mu, lambda, F);
    case Material::Linear: {
      const Mat3 e = small_strain(F);
      return 2.0 * mu * e + lambda * e.trace() * Mat3::Identity();
    }
  }
  return Mat3::Zero();
}

Mat9 stress_derivative(Material material, double mu, double lambda, const Mat3& F) {
  const double J = F.determinant();
  const Mat3 cof = cofactor(F);
  const auto g = vec(cof);
  switch (material) {
    case Material::StableNeoHookean: {
      const double ls = snh_lambda(mu, lambda);
      const double a = 1.0 + mu / ls;
      Mat9 d = (ls * (J - a)) * cofactor_derivative(F);
      d.noalias() += ls * (g * g.transpose());
      d.diagonal().array() += mu;
      return d;
    }
    case Material::Corotated: {
      const RotationSvd s = rotation_svd(F);
      Mat9 d = (lambda * (J - 1.0)) * cofactor_derivative(F);
      d.noalias() += lambda * (g * g.transpose());
      d.noalias() -= (2.0 * mu) * rotation_derivative(s);
      d.diagonal().array() += 2.0 * mu;
      return d;
    }
    case Material::StVK:
      return stvk_derivative<3>(mu, lambda, F);
    case Material::Linear: {
      Mat9 d = Mat9::Zero();
      for (int c = 0; c < 3; ++c)
        for (int a = 0; a < 3; ++a) {
          d(a + 3 * c, a + 3 * c) += mu;  // mu dF
          d(c + 3 * a, a + 3 * c) += mu;  // mu dF^T
        }
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) d(a + 3 * a, b + 3 * b) += lambda;  // lambda tr(dF) I
      return d;
    }
  }
  return Mat9::Zero();
}

namespace {

void require_triangle_material(Material material) {
  if (material != Material::StVK)
    throw std::invalid_argument(std::string("a triangle element of material ") + to_string(material) +
                                ": only stvk has triangles");
}

}  // namespace

double energy_density_2d(Material material, double mu, double lambda, const Mat32& F) {
  require_triangle_material(material);
  return stvk_density<2>(mu, lambda, F);
}

Mat32 first_piola_2d(Material material, double mu, double lambda, const Mat32& F) {
  require_triangle_material(material);
  return stvk_piola<2>(mu, lambda, F);
}

Mat6 stress_derivative_2d(Material material, double mu, double lambda, const Mat32& F) {
  require_triangle_material(material);
  return stvk_derivative<2>(mu, lambda, F);
}

// ---------------------------------------------------------------------------------------------
// Elements. F = Ds Dm^-1 is linear in the vertices: dF = sum_v dx_v b_v^T with b_{k+1} = row k of
// Dm^-1 (k = 0, 1, 2) and b_0 = -(b_1 + b_2 + b_3). In vec form dF = B dx with
// B(a + 3 c, 3 v + a) = b_v(c) (9 x 12), so the gradient is V0 B^T vec(P) (vertex v: V0 P b_v)
// and the Hessian V0 B^T dP/dF B.

namespace {

// b_v as the columns of a D x (D + 1) matrix (D = 3: a tet, D = 2: a triangle, whose Dm^-1 is the
// top-left 2 x 2 block of rest_inverse).
template <int D>
Eigen::Matrix<double, D, D + 1> shape_gradients(const FemElement& e) {
  Eigen::Matrix<double, D, D + 1> b;
  b.template rightCols<D>() = e.rest_inverse.template topLeftCorner<D, D>().transpose();
  b.col(0) = -b.template rightCols<D>().rowwise().sum();
  return b;
}

// V0 P b_v for each vertex, the rest of the 12 entries 0.
template <int D>
Vec12 gradient_from_stress(const FemElement& e, const Eigen::Matrix<double, 3, D>& P) {
  const Eigen::Matrix<double, D, D + 1> b = shape_gradients<D>(e);
  Vec12 g = Vec12::Zero();
  for (int v = 0; v <= D; ++v) g.segment<3>(3 * v) = e.rest_volume * (P * b.col(v));
  return g;
}

// V0 B^T A B without forming B: entry (3 v + a, 3 w + a') is
// V0 sum_{c, c'} b_v(c) A(a + 3 c, a' + 3 c') b_w(c'), i.e. for each pair (a, a') the
// (D + 1) x (D + 1) matrix V0 b^T A_aa' b with A_aa'(c, c') = A(a + 3 c, a' + 3 c').
template <int D>
Mat12 hessian_from_stress_derivative(const FemElement& e, const Eigen::Matrix<double, 3 * D, 3 * D>& A,
                                     bool project_psd) {
  const Eigen::Matrix<double, D, D + 1> b = shape_gradients<D>(e);
  // A triangle is a 2D element of the xy plane: z moves do not change its F (its third row is
  // 0), so its rows and columns of z stay 0.
  constexpr int kMoving = D == 3 ? 3 : 2;
  Mat12 H = Mat12::Zero();
  for (int a2 = 0; a2 < kMoving; ++a2)
    for (int a = 0; a < kMoving; ++a) {
      Eigen::Matrix<double, D, D> Aaa;
      for (int c2 = 0; c2 < D; ++c2)
        for (int c = 0; c < D; ++c) Aaa(c, c2) = A(a + 3 * c, a2 + 3 * c2);
      const Eigen::Matrix<double, D + 1, D + 1> block = e.rest_volume * (b.transpose() * (Aaa * b));
      for (int w = 0; w <= D; ++w)
        for (int v = 0; v <= D; ++v) H(3 * v + a, 3 * w + a2) = block(v, w);
    }
  H = 0.5 * (H + H.transpose());  // exact symmetry, whatever the rounding of the products
  // V0 B^T A B does not see translations (the shape gradients b_v sum to 0): its projection is
  // that of its 9 x 9 restriction (core/psd_projection.hpp).
  if (project_psd) psd::project_psd_translation_free(H);
  return H;
}

}  // namespace

double element_energy(const FemElement& e, const Points& x) {
  if (e.vertices == 3) {
    const Mat32 F = deformation_gradient_2d(e, x);
    return e.rest_volume * energy_density_2d(e.material, e.mu, e.lambda, F);  // Psi(I) = 0
  }
  const Mat3 F = deformation_gradient(e, x);
  return e.rest_volume * (energy_density(e.material, e.mu, e.lambda, F) -
                          energy_density(e.material, e.mu, e.lambda, Mat3::Identity()));
}

Vec12 element_gradient(const FemElement& e, const Points& x) {
  if (e.vertices == 3)
    return gradient_from_stress<2>(
        e, first_piola_2d(e.material, e.mu, e.lambda, deformation_gradient_2d(e, x)));
  return gradient_from_stress<3>(e,
                                 first_piola(e.material, e.mu, e.lambda, deformation_gradient(e, x)));
}

Mat12 element_hessian(const FemElement& e, const Points& x, bool project_psd) {
  if (e.vertices == 3)
    return hessian_from_stress_derivative<2>(
        e, stress_derivative_2d(e.material, e.mu, e.lambda, deformation_gradient_2d(e, x)),
        project_psd);
  return hessian_from_stress_derivative<3>(
      e, stress_derivative(e.material, e.mu, e.lambda, deformation_gradient(e, x)), project_psd);
}

}  // namespace pbdbench::fem
