// The kinematic and constraint part of core/fem.hpp: Lame parameters, the deformation gradients,
// the XPBD forms (the stable neo-Hookean pair; the strain vector of StVK and linear elements and
// its block update) and the builders that add elements to a model.
// (Energy densities, stresses, element gradients and Hessians are in core/fem.cpp.)
//
// Notation: Ds = [x1-x0, x2-x0, x3-x0], F = Ds Dm^-1 = [f0 f1 f2] by columns. For a function
// C(F), dC/dDs = (dC/dF) Dm^-T, whose column k is dC/dx_{k+1}; dC/dx0 = -(sum of the columns),
// since translating all four vertices leaves F unchanged.
#include <Eigen/Cholesky>
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

// Young's modulus above 0 and finite, Poisson's ratio in (-1, 0.5), else std::invalid_argument.
void require_moduli(double youngs_modulus, double poisson_ratio) {
  if (!(youngs_modulus > 0.0) || !std::isfinite(youngs_modulus))
    throw std::invalid_argument("youngs_modulus = " + format_number(youngs_modulus, kShortDigits) +
                                " Pa must be finite and above 0");
  if (!(poisson_ratio > -1.0 && poisson_ratio < 0.5))
    throw std::invalid_argument("poisson_ratio = " + format_number(poisson_ratio, kShortDigits) +
                                " must be in (-1, 0.5)");
}

// Every index of an element in [0, n), else std::invalid_argument naming the element.
template <size_t K>
void require_in_range(const std::string& name, const std::array<int, K>& t, int n) {
  for (int p : t)
    if (p < 0 || p >= n)
      throw std::invalid_argument(name + ": particle index " + std::to_string(p) +
                                  " is out of range (the model has " + std::to_string(n) +
                                  " particles)");
}

// One strain-vector constraint of `kind` (group "fem_strain") per element, elements[k] being
// model.elements[first + k]; the scalar compliance records the matrix's deviatoric entry.
void add_strain_constraints(Model& model, ConstraintKind kind, const std::vector<FemElement>& elements,
                            int first) {
  const std::uint16_t group = model.group_index("fem_strain");
  for (size_t k = 0; k < elements.size(); ++k) {
    Constraint c;
    c.kind = kind;
    c.particles = elements[k].particles;
    c.rest = 0.0;
    c.compliance = 1.0 / (2.0 * elements[k].mu * elements[k].rest_volume);
    c.group = group;
    c.element = first + static_cast<int>(k);
    model.constraints.push_back(c);
  }
}

}  // namespace

Lame lame(double youngs_modulus, double poisson_ratio) {
  const double E = youngs_modulus, nu = poisson_ratio;
  return {E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))};
}

double snh_lambda(double mu, double lambda) { return lambda + mu; }

bool has_constraint_form(Material material) { return material != Material::Corotated; }

Mat3 deformation_gradient(const FemElement& e, const Points& x) {
  return edge_matrix(x, e.particles) * e.rest_inverse;
}

Mat32 deformation_gradient_2d(const FemElement& e, const Points& x) {
  // A 2D element of the xy plane: the x and y of its edges only; the third row of F is 0.
  Mat32 Ds = Mat32::Zero();
  const Vec3 x0 = x.row(e.particles[0]);
  Ds.col(0).head<2>() = (Vec3(x.row(e.particles[1])) - x0).head<2>();
  Ds.col(1).head<2>() = (Vec3(x.row(e.particles[2])) - x0).head<2>();
  return Ds * e.rest_inverse.topLeftCorner<2, 2>();
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

namespace {

// The (row, column) of each strain component in Mandel's order, and its factor (1 on the
// diagonal, sqrt 2 off it).
constexpr int kTetPairs[6][2] = {{0, 0}, {1, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}};
constexpr int kTrianglePairs[3][2] = {{0, 0}, {1, 1}, {0, 1}};

// The strain vector and its gradients for a 3 x D F (D = 3 or 2) and the shape gradients b
// (D x (D + 1), column v = b_v); `green` picks E = (F^T F - I) / 2, else (F + F^T) / 2 - I (D = 3).
template <int D>
StrainEval strain_vector(const Eigen::Matrix<double, 3, D>& F, const Eigen::Matrix<double, D, D + 1>& b,
                         bool green) {
  StrainEval out;
  constexpr int kComponents = D == 3 ? 6 : 3;
  const auto& pairs = [] {
    if constexpr (D == 3) return kTetPairs;
    else return kTrianglePairs;
  }();
  out.components = kComponents;
  Eigen::Matrix<double, 3, D> G;  // the columns F_a the gradient formula uses
  if (green) {
    G = F;
  } else {
    G = Eigen::Matrix<double, 3, D>::Identity();
  }
  Eigen::Matrix<double, D, D> E;
  if (green) {
    E = 0.5 * (F.transpose() * F - Eigen::Matrix<double, D, D>::Identity());
  } else {
    const Eigen::Matrix<double, D, D> top = F.template topRows<D>();
    E = 0.5 * (top + top.transpose()) - Eigen::Matrix<double, D, D>::Identity();
  }
  for (int c = 0; c < kComponents; ++c) {
    const int a = pairs[c][0], bb = pairs[c][1];
    const double factor = a == bb ? 1.0 : std::sqrt(2.0);
    out.C(c) = factor * E(a, bb);
    for (int v = 0; v <= D; ++v)
      out.grad[static_cast<size_t>(c)][static_cast<size_t>(v)] =
          (0.5 * factor) * (b(a, v) * G.col(bb) + b(bb, v) * G.col(a));
  }
  return out;
}

}  // namespace

StrainEval eval_strain(const FemElement& e, const Points& x) {
  if (e.material != Material::StVK && e.material != Material::Linear)
    throw std::invalid_argument(std::string("eval_strain: an element of material ") +
                                to_string(e.material) + " has no strain-vector constraint");
  if (e.vertices == 3) {
    Eigen::Matrix<double, 2, 3> b;
    b.rightCols<2>() = e.rest_inverse.topLeftCorner<2, 2>().transpose();
    b.col(0) = -b.rightCols<2>().rowwise().sum();
    return strain_vector<2>(deformation_gradient_2d(e, x), b, true);
  }
  Eigen::Matrix<double, 3, 4> b;
  b.rightCols<3>() = e.rest_inverse.transpose();
  b.col(0) = -b.rightCols<3>().rowwise().sum();
  return strain_vector<3>(deformation_gradient(e, x), b, e.material == Material::StVK);
}

Mat6 strain_compliance(const FemElement& e) {
  const int components = e.vertices == 3 ? 3 : 6;
  const int diagonal = e.vertices == 3 ? 2 : 3;  // the components on the diagonal come first
  Mat6 a = Mat6::Zero();
  const double inv_2mu = 1.0 / (2.0 * e.mu);
  const double coupling = e.lambda / (2.0 * e.mu + diagonal * e.lambda);
  for (int i = 0; i < components; ++i) a(i, i) = inv_2mu;
  for (int i = 0; i < diagonal; ++i)
    for (int j = 0; j < diagonal; ++j) a(i, j) -= inv_2mu * coupling;
  return a / e.rest_volume;
}

bool xpbd_strain_update(const StrainEval& e, const std::array<double, 4>& w,
                        const Mat6& alpha_tilde, const Vec6& lambda, std::array<Vec3, 4>& dx,
                        Vec6& dlambda) {
  const int k = e.components;
  // A = sum_v w_v J_v J_v^T + alpha~, J_v(c, :) = grad[c][v]^T.
  Mat6 A = alpha_tilde;
  for (int v = 0; v < 4; ++v) {
    if (!(w[static_cast<size_t>(v)] > 0.0)) continue;
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j)
        A(i, j) += w[static_cast<size_t>(v)] *
                   e.grad[static_cast<size_t>(i)][static_cast<size_t>(v)].dot(
                       e.grad[static_cast<size_t>(j)][static_cast<size_t>(v)]);
  }
  const Vec6 rhs = -e.C - alpha_tilde * lambda;
  Vec6 solution = Vec6::Zero();
  if (k == 6) {
    const Eigen::LLT<Mat6> llt(A);
    if (llt.info() != Eigen::Success) return false;
    solution = llt.solve(rhs);
  } else {
    const Eigen::Matrix3d A3 = A.topLeftCorner<3, 3>();
    const Eigen::LLT<Eigen::Matrix3d> llt(A3);
    if (llt.info() != Eigen::Success) return false;
    solution.head<3>() = llt.solve(rhs.head<3>());
  }
  if (!solution.allFinite()) return false;
  dlambda = solution;
  for (int v = 0; v < 4; ++v) {
    Vec3 d = Vec3::Zero();
    for (int c = 0; c < k; ++c) d += dlambda(c) * e.grad[static_cast<size_t>(c)][static_cast<size_t>(v)];
    dx[static_cast<size_t>(v)] = w[static_cast<size_t>(v)] * d;
  }
  return true;
}

void add_fem_elements(Model& model, const std::vector<std::array<int, 4>>& tets, Material material,
                      double youngs_modulus, double poisson_ratio) {
  require_moduli(youngs_modulus, poisson_ratio);
  const Lame moduli = lame(youngs_modulus, poisson_ratio);
  const int n = model.particle_count();
  const char* material_name = to_string(material);

  // Check every tet before changing the model, so that a refusal leaves it as it was.
  std::vector<FemElement> elements;
  elements.reserve(tets.size());
  for (size_t k = 0; k < tets.size(); ++k) {
    const auto& t = tets[k];
    const std::string name = "tet " + std::to_string(k) + " (particles " + index_list(t, 4) + ")";
    require_in_range(name, t, n);
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
  if (!has_constraint_form(material)) return;  // corotated: no XPBD form
  if (material == Material::StVK || material == Material::Linear) {
    // Macklin et al. 2016, sec. 6.3: one strain-vector constraint per element, its compliance
    // matrix from the element (strain_compliance); the scalar compliance is its deviatoric entry.
    add_strain_constraints(model, ConstraintKind::FemStrainTet, elements, first);
    return;
  }

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

void add_fem_triangles(Model& model, const std::vector<std::array<int, 3>>& triangles,
                       Material material, double youngs_modulus, double poisson_ratio,
                       double thickness) {
  if (material != Material::StVK)
    throw std::invalid_argument(std::string("a triangle element of material ") + to_string(material) +
                                ": only stvk has triangles");
  require_moduli(youngs_modulus, poisson_ratio);
  if (!(thickness > 0.0) || !std::isfinite(thickness))
    throw std::invalid_argument("thickness = " + format_number(thickness, kShortDigits) +
                                " m must be finite and above 0");
  const Lame moduli = lame(youngs_modulus, poisson_ratio);
  const int n = model.particle_count();
  std::vector<FemElement> elements;
  elements.reserve(triangles.size());
  for (size_t k = 0; k < triangles.size(); ++k) {
    const auto& t = triangles[k];
    const std::string name = "triangle " + std::to_string(k) + " (particles " + index_list(t, 3) + ")";
    require_in_range(name, t, n);
    const Vec3 x0 = model.rest_positions.row(t[0]);
    const Vec3 e1 = Vec3(model.rest_positions.row(t[1])) - x0;
    const Vec3 e2 = Vec3(model.rest_positions.row(t[2])) - x0;
    const double longest = std::max({e1.norm(), e2.norm(), (e2 - e1).norm()});
    // A 2D element of the xy plane: its rest vertices share z.
    if (!(std::abs(e1.z()) <= 1e-12 * longest && std::abs(e2.z()) <= 1e-12 * longest))
      throw std::invalid_argument(name + " does not lie in a plane z = const: a stvk triangle is a "
                                  "2D element of the xy plane");
    Eigen::Matrix2d Dm;
    Dm << e1.x(), e2.x(), e1.y(), e2.y();
    const double area = 0.5 * std::abs(Dm.determinant());
    // Degenerate as core/model_checks.cpp: area <= 1e-12 (longest edge)^2, scale-free.
    if (!(area > 1e-12 * longest * longest))
      throw std::invalid_argument(name + " is degenerate: rest area " +
                                  format_number(area, kShortDigits) +
                                  " m^2; a stvk triangle needs a non-zero area");
    FemElement e;
    e.particles = {t[0], t[1], t[2], -1};
    e.vertices = 3;
    e.rest_inverse = Mat3::Zero();
    e.rest_inverse.topLeftCorner<2, 2>() = Dm.inverse();
    e.rest_volume = area * thickness;
    e.material = material;
    e.mu = moduli.mu;
    e.lambda = moduli.lambda;
    elements.push_back(e);
  }
  const int first = static_cast<int>(model.elements.size());
  for (const FemElement& e : elements) model.elements.push_back(e);
  add_strain_constraints(model, ConstraintKind::FemStrainTriangle, elements, first);
}

}  // namespace pbdbench::fem
