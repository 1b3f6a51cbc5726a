// The kinematic and constraint part of core/fem.hpp: Lame parameters, the deformation gradient,
// the XPBD form of the stable neo-Hookean material and the builder that adds elements to a model.
// (Energy densities, stresses, element gradients and Hessians are in core/fem.cpp.)
//
// Notation: Ds = [x1-x0, x2-x0, x3-x0], F = Ds Dm^-1 = [f0 f1 f2] by columns. For a function
// C(F), dC/dDs = (dC/dF) Dm^-T, whose column k is dC/dx_{k+1}; dC/dx0 = -(sum of the columns),
// since translating all four vertices leaves F unchanged.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/build_helpers.hpp"
#include "core/constraint_stencils.hpp"
#include "core/fem.hpp"

namespace pbdbench::fem {

namespace {

using core::detail::format_number;
using core::detail::index_list;
using core::detail::kShortDigits;

Mat3 edge_matrix(const Points& x, const std::array<int, 4>& p) {
  Mat3 D;
  const Vec3 x0 = x.row(p[0]);
  for (int k = 0; k < 3; ++k) D.col(k) = Vec3(x.row(p[static_cast<size_t>(k + 1)])) - x0;
  return D;
}

}  // namespace

Lame lame(double youngs_modulus, double poisson_ratio) {
  const double E = youngs_modulus, nu = poisson_ratio;
  return {E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))};
}

double snh_lambda(double mu, double lambda) { return lambda + mu; }

Mat3 deformation_gradient(const FemElement& e, const Points& x) {
  return edge_matrix(x, e.particles) * e.rest_inverse;
}

namespace {

// The element's particles at x and Dm^-1 by rows, as core/constraint_stencils.hpp takes them.
struct ElementStencil {
  std::array<V3<double>, 4> x;
  double dm[9];
};

ElementStencil element_stencil(const FemElement& e, const Points& x) {
  ElementStencil s;
  for (int i = 0; i < 4; ++i) {
    const auto row = x.row(e.particles[static_cast<size_t>(i)]);
    s.x[static_cast<size_t>(i)] = {row(0), row(1), row(2)};
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) s.dm[3 * r + c] = e.rest_inverse(r, c);
  return s;
}

ConstraintEval to_eval(const StencilEval<double>& s) {
  ConstraintEval out;
  out.C = s.C;
  out.valid = s.valid;
  for (int i = 0; i < 4; ++i) {
    const V3<double>& g = s.grad[static_cast<size_t>(i)];
    out.grad[static_cast<size_t>(i)] = Vec3(g.x, g.y, g.z);
  }
  return out;
}

}  // namespace

// C_D = sqrt(tr F^T F) = |F|_Frobenius (Macklin and Mueller 2021, the deviatoric constraint);
// dC_D/dF = F / |F|, undefined at F = 0 (core/constraint_stencils.hpp).
ConstraintEval eval_deviatoric(const FemElement& e, const Points& x) {
  const ElementStencil s = element_stencil(e, x);
  return to_eval(fem_deviatoric_stencil(s.x[0], s.x[1], s.x[2], s.x[3], s.dm, 0.0));
}

// C_H = det F - rest (Macklin and Mueller 2021, the hydrostatic constraint); dC_H/dF = cof F.
ConstraintEval eval_hydrostatic(const FemElement& e, const Points& x, double rest) {
  const ElementStencil s = element_stencil(e, x);
  return to_eval(fem_hydrostatic_stencil(s.x[0], s.x[1], s.x[2], s.x[3], s.dm, rest));
}

void add_fem_elements(Model& model, const std::vector<std::array<int, 4>>& tets, Material material,
                      double youngs_modulus, double poisson_ratio) {
  if (!(youngs_modulus > 0.0) || !std::isfinite(youngs_modulus))
    throw std::invalid_argument("youngs_modulus = " + format_number(youngs_modulus, kShortDigits) +
                                " Pa must be finite and above 0");
  if (!(poisson_ratio > -1.0 && poisson_ratio < 0.5))
    throw std::invalid_argument("poisson_ratio = " + format_number(poisson_ratio, kShortDigits) +
                                " must be in (-1, 0.5)");
  const Lame moduli = lame(youngs_modulus, poisson_ratio);
  const int n = model.particle_count();
  const char* material_name = to_string(material);

  // Check every tet before changing the model, so that a refusal leaves it as it was.
  std::vector<FemElement> elements;
  elements.reserve(tets.size());
  for (size_t k = 0; k < tets.size(); ++k) {
    const auto& t = tets[k];
    const std::string name = "tet " + std::to_string(k) + " (particles " + index_list(t, 4) + ")";
    for (int p : t)
      if (p < 0 || p >= n)
        throw std::invalid_argument(name + ": particle index " + std::to_string(p) +
                                    " is out of range (the model has " + std::to_string(n) +
                                    " particles)");
    const Mat3 Dm = edge_matrix(model.rest_positions, t);
    const double volume = Dm.determinant() / 6.0;
    // Degenerate as core/model_checks.cpp: |V| <= 1e-9 (longest edge)^3, scale-free.
    double longest = std::max({Dm.col(0).norm(), Dm.col(1).norm(), Dm.col(2).norm(),
                               (Dm.col(1) - Dm.col(0)).norm(), (Dm.col(2) - Dm.col(0)).norm(),
                               (Dm.col(2) - Dm.col(1)).norm()});
    if (!(std::abs(volume) > 1e-9 * longest * longest * longest))
      throw std::invalid_argument(name + " is degenerate: rest volume " +
                                  format_number(volume, kShortDigits) + " m^3; a " +
                                  material_name + " element needs a tet of non-zero volume");
    if (volume < 0.0)
      throw std::invalid_argument(name + " is negatively oriented: rest volume " +
                                  format_number(volume, kShortDigits) + " m^3; a " +
                                  material_name + " element needs det Dm > 0");
    FemElement e;
    e.particles = t;
    e.rest_inverse = Dm.inverse();
    e.rest_volume = volume;
    e.material = material;
    e.mu = moduli.mu;
    e.lambda = moduli.lambda;
    elements.push_back(e);
  }

  const int first = static_cast<int>(model.elements.size());
  for (const FemElement& e : elements) model.elements.push_back(e);
  if (material != Material::StableNeoHookean) return;  // no XPBD form

  // Macklin and Mueller 2021: per element, C_D = sqrt(tr F^T F) with alpha_D = 1 / (mu V0) and
  // C_H = det F - (1 + mu / lambda_snh) with alpha_H = 1 / (lambda_snh V0), so that
  // C_D^2 / (2 alpha_D) + C_H^2 / (2 alpha_H) = V0 Psi_snh(F) + 3 mu V0 / 2. The pair of each
  // element is consecutive (deviatoric, then hydrostatic), so a sequential sweep treats one
  // element at a time.
  const std::uint16_t dev_group = model.group_index("fem_deviatoric");
  const std::uint16_t hyd_group = model.group_index("fem_hydrostatic");
  const double ls = snh_lambda(moduli.mu, moduli.lambda);
  for (size_t k = 0; k < elements.size(); ++k) {
    const FemElement& e = elements[k];
    Constraint dev;
    dev.kind = ConstraintKind::FemDeviatoric;
    dev.particles = e.particles;
    dev.rest = 0.0;
    dev.compliance = 1.0 / (e.mu * e.rest_volume);
    dev.stiffness = 1.0;
    dev.damping = 0.0;
    dev.group = dev_group;
    dev.element = first + static_cast<int>(k);
    Constraint hyd = dev;
    hyd.kind = ConstraintKind::FemHydrostatic;
    hyd.rest = 1.0 + e.mu / ls;
    hyd.compliance = 1.0 / (ls * e.rest_volume);
    hyd.group = hyd_group;
    model.constraints.push_back(dev);
    model.constraints.push_back(hyd);
  }
}

}  // namespace pbdbench::fem
