// Linear tetrahedral finite elements: deformation gradients, the energy densities of the two
// materials (Model::Material), their stresses and stress derivatives, element gradients and
// Hessians, the XPBD constraint form of the stable neo-Hookean material, and the builder that adds
// elements to a model. Pure functions; every derivative is checked against finite differences in
// tests/core/test_fem.cpp.
//
// Conventions: Ds = [x1-x0, x2-x0, x3-x0], F = Ds Dm^-1 (3x3). vec(F) stacks F column by column
// (Eigen's column-major order), so dP/dF is a 9x9 matrix acting on vec(dF). Element vectors stack
// the four vertices: (x0, y0, z0, x1, ..., z3).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/generators.hpp"
#include "core/model.hpp"
#include "core/constraint_functions.hpp"

namespace pbdbench::fem {

using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;
using Mat9 = Eigen::Matrix<double, 9, 9>;

// Lame parameters of linear elasticity from Young's modulus E (Pa) and Poisson's ratio nu
// (-1 < nu < 0.5): mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu)).
struct Lame {
  double mu = 0.0;      // Pa
  double lambda = 0.0;  // Pa
};
Lame lame(double youngs_modulus, double poisson_ratio);

// The stable neo-Hookean's lambda: lambda + mu (see Material::StableNeoHookean).
double snh_lambda(double mu, double lambda);

// F of element e at positions x (n x 3).
Mat3 deformation_gradient(const FemElement& e, const Points& x);

// Energy density Psi(F) (J/m^3), first Piola-Kirchhoff stress P = dPsi/dF (Pa) and
// dP/dF (9x9, Pa) of a material with Lame parameters (mu, lambda). For StableNeoHookean the
// rest value Psi(I) = mu^2 / (2 lambda_snh) is not zero; energy() subtracts it.
double energy_density(Material material, double mu, double lambda, const Mat3& F);
Mat3 first_piola(Material material, double mu, double lambda, const Mat3& F);
Mat9 stress_derivative(Material material, double mu, double lambda, const Mat3& F);

// Element energy V0 (Psi(F) - Psi(I)) (J), its gradient (12, N) and Hessian (12 x 12, N/m) with
// respect to the element's four vertices. With project_psd the Hessian is projected onto the
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

// Adds one element per tet (rest shape from model.rest_positions; each tet must be positively
// oriented and non-degenerate, else std::invalid_argument naming it) with the given material
// and moduli. For StableNeoHookean it also adds the XPBD constraints of each element (groups
// "fem_deviatoric" and "fem_hydrostatic"); the other materials have no XPBD form.
void add_fem_elements(Model& model, const std::vector<std::array<int, 4>>& tets, Material material,
                      double youngs_modulus, double poisson_ratio);

}  // namespace pbdbench::fem
