// Linear finite elements (tetrahedra; triangles for the StVK material): deformation gradients, the
// energy densities of the materials (Model::Material), their stresses and stress derivatives,
// element gradients and Hessians, the XPBD constraint forms (the stable neo-Hookean pair; the
// strain vector of StVK and linear elements), and the builders that add elements to a model. Pure
// functions; every derivative is checked against finite differences in tests/core/test_fem.cpp
// and tests/core/test_fem_strain.cpp.
//
// Conventions: Ds = [x1-x0, x2-x0, x3-x0], F = Ds Dm^-1 (3x3). vec(F) stacks F column by column
// (Eigen's column-major order), so dP/dF is a 9x9 matrix acting on vec(dF). Element vectors stack
// the four vertices: (x0, y0, z0, x1, ..., z3); a triangle's fourth vertex is absent (its entries
// are 0). A triangle (FemElement::vertices = 3) is a 2D element of the xy plane (Macklin et al.
// 2016 simulate their beam in 2D): Ds = the x and y of [x1-x0, x2-x0] (2x2), F = Ds Dm^-1 stored
// as a 3x2 matrix whose third row is 0, and a 2x2 strain (plane strain). Its forces lie in the
// plane and z is left alone: embedded in 3D as a membrane instead, a compressed beam would fold
// out of its plane at no cost.
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

#include "core/generators.hpp"
#include "core/model.hpp"
#include "core/constraint_functions.hpp"

namespace pbdbench::fem {

using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;
using Mat9 = Eigen::Matrix<double, 9, 9>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat32 = Eigen::Matrix<double, 3, 2>;  // a triangle's F

// Lame parameters of linear elasticity from Young's modulus E (Pa) and Poisson's ratio nu
// (-1 < nu < 0.5): mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu)).
struct Lame {
  double mu = 0.0;      // Pa
  double lambda = 0.0;  // Pa
};
Lame lame(double youngs_modulus, double poisson_ratio);

// The stable neo-Hookean's lambda: lambda + mu (see Material::StableNeoHookean).
double snh_lambda(double mu, double lambda);

// True for the materials with an XPBD constraint form (the FEM kinds of core/model.hpp): the
// stable neo-Hookean (two scalar constraints), StVK and linear (one strain vector); not corotated.
bool has_constraint_form(Material material);

// F of tet element e at positions x (n x 3); F of triangle element e (3 x 2).
Mat3 deformation_gradient(const FemElement& e, const Points& x);
Mat32 deformation_gradient_2d(const FemElement& e, const Points& x);

// Energy density Psi(F) (J/m^3), first Piola-Kirchhoff stress P = dPsi/dF (Pa) and
// dP/dF (9x9, Pa) of a material with Lame parameters (mu, lambda). For StableNeoHookean the
// rest value Psi(I) = mu^2 / (2 lambda_snh) is not zero; energy() subtracts it.
double energy_density(Material material, double mu, double lambda, const Mat3& F);
Mat3 first_piola(Material material, double mu, double lambda, const Mat3& F);
Mat9 stress_derivative(Material material, double mu, double lambda, const Mat3& F);

// The same for a triangle's 3 x 2 F (StVK only, the material that has triangles: Psi = mu E : E +
// lambda/2 tr(E)^2 with the 2 x 2 Green strain E = (F^T F - I) / 2; P = F S, S = 2 mu E + lambda
// tr(E) I; dP/dF is 6 x 6 on vec(F)). Other materials throw std::invalid_argument.
double energy_density_2d(Material material, double mu, double lambda, const Mat32& F);
Mat32 first_piola_2d(Material material, double mu, double lambda, const Mat32& F);
Mat6 stress_derivative_2d(Material material, double mu, double lambda, const Mat32& F);

// Element energy V0 (Psi(F) - Psi(I)) (J), its gradient (12, N) and Hessian (12 x 12, N/m) with
// respect to the element's four vertices (a triangle's three: the last three entries, rows and
// columns are 0). With project_psd the Hessian is projected onto the
// positive semi-definite cone (its negative eigenvalues clamped to 0), for Newton solves that
// need a descent direction; without, it is exact.
double element_energy(const FemElement& e, const Points& x);
Vec12 element_gradient(const FemElement& e, const Points& x);
Mat12 element_hessian(const FemElement& e, const Points& x, bool project_psd = false);

// The XPBD form of a stable neo-Hookean element (Macklin and Mueller 2021): the deviatoric
// constraint C_D = sqrt(tr F^T F) with compliance 1/(mu V0) and the hydrostatic constraint
// C_H = det F - (1 + mu / lambda_snh) with compliance 1/(lambda_snh V0), so that
// C_D^2 / (2 alpha_D) + C_H^2 / (2 alpha_H) = V0 Psi_snh(F) + const.
ConstraintEval eval_deviatoric(const FemElement& e, const Points& x);
ConstraintEval eval_hydrostatic(const FemElement& e, const Points& x, double rest);

// The strain vector of a StVK or linear element (Macklin et al. 2016, sec. 6.3, eq. 27: the
// entries of the strain tensor of an element as one vector constraint), in Mandel's form of
// Voigt's vector so that the energy is a plain quadratic form:
//   tet:      C = (E00, E11, E22, sqrt2 E12, sqrt2 E02, sqrt2 E01)    (6 components)
//   triangle: C = (E00, E11, sqrt2 E01)                               (3 components)
// E = (F^T F - I) / 2 (StVK) or (F + F^T) / 2 - I (linear), and grad[c][v] = dC_c / dx_v: with
// b_v the shape gradient of vertex v (dF = dx_v b_v^T), dE_ab / dx_v = (b_v(a) F_b + b_v(b) F_a) / 2
// (F_a the column a of F; F = I for the linear strain).
struct StrainEval {
  int components = 0;                           // 6 (tet) or 3 (triangle)
  Vec6 C = Vec6::Zero();                        // the first `components` entries are used
  std::array<std::array<Vec3, 4>, 6> grad{};    // grad[c][v], (1/m); v < FemElement::vertices
};
StrainEval eval_strain(const FemElement& e, const Points& x);

// The compliance matrix of an element's strain vector, alpha = K^-1 / V0 (Macklin et al. 2016,
// eq. 28), K the linear isotropic stiffness in Mandel's form: K = 2 mu I + lambda m m^T, m = 1 on
// the d diagonal components (d = 3 for a tet, 2 for a triangle: plane strain), so that
//   K^-1 = (I - lambda / (2 mu + d lambda) m m^T) / (2 mu)   and   C^T alpha^-1 C / 2 = V0 Psi.
// The top-left components x components block is used; the rest is 0. (1/(Pa m^3))
Mat6 strain_compliance(const FemElement& e);

// The XPBD update of one element's strain vector: Macklin et al. 2016, eq. 16 for the block of its
// components (the Gauss-Seidel update of sec. 4.1 applied to a vector constraint), with J_v =
// grad[.][v] (components x 3) and w_v the inverse masses of its vertices (1/kg):
//   (sum_v w_v J_v J_v^T + alpha~) dlambda = -C - alpha~ lambda,   dx_v = w_v J_v^T dlambda,
// alpha~ = strain_compliance / h^2. Returns false (nothing written) when the matrix is not
// positive definite (every vertex pinned, or a degenerate element).
bool xpbd_strain_update(const StrainEval& e, const std::array<double, 4>& w,
                        const Mat6& alpha_tilde, const Vec6& lambda, std::array<Vec3, 4>& dx,
                        Vec6& dlambda);

// Adds one element per tet (rest shape from model.rest_positions; each tet must be positively
// oriented and non-degenerate, else std::invalid_argument naming it) with the given material
// and moduli. It also adds the XPBD constraints of each element: for StableNeoHookean the pair of
// groups "fem_deviatoric" and "fem_hydrostatic", for StVK and Linear one FemStrainTet (group
// "fem_strain"); Corotated has no XPBD form.
void add_fem_elements(Model& model, const std::vector<std::array<int, 4>>& tets, Material material,
                      double youngs_modulus, double poisson_ratio);

// Adds one StVK triangle element per triangle, a 2D element of the xy plane (rest shape from
// model.rest_positions; a degenerate one, or one whose vertices do not share z, is refused naming
// it), of the given thickness (m, > 0: its rest volume is its
// area times the thickness), with one FemStrainTriangle constraint each (group "fem_strain").
// Only Material::StVK has triangles (std::invalid_argument otherwise).
void add_fem_triangles(Model& model, const std::vector<std::array<int, 3>>& triangles,
                       Material material, double youngs_modulus, double poisson_ratio,
                       double thickness);

}  // namespace pbdbench::fem
