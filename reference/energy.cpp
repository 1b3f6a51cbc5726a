// EnergyModel (reference/energy.hpp): the scene as U(q) over the dynamic dofs, with exact
// gradients and Hessians assembled into a sparsity pattern fixed at construction.
//
// Each term of U is C^2 / (2 alpha) for a compliant constraint or an FEM element's energy. For the
// constraint terms, with g = grad C and H = hess C over the stencil:
//   grad = C g / alpha,   Hessian = (g g^T + C H) / alpha.
// H of each kind is exact (below). Assembly: every term's dense block goes to precomputed
// positions in the values array (slots_), nothing is searched or allocated while evaluating.
#include "reference/energy.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "core/constraint_functions.hpp"
#include "core/fem.hpp"
#include "core/psd_projection.hpp"

namespace pbdbench {

std::int64_t SparsityPattern::find(int r, int c) const {
  if (r < 0 || c < 0 || r >= n || c >= n) return -1;
  const auto begin = row.begin() + column_start[static_cast<size_t>(c)];
  const auto end = row.begin() + column_start[static_cast<size_t>(c) + 1];
  const auto it = std::lower_bound(begin, end, static_cast<std::int64_t>(r));
  return (it != end && *it == r) ? static_cast<std::int64_t>(it - row.begin()) : -1;
}

namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat9 = Eigen::Matrix<double, 9, 9>;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using fem::Mat12;
using fem::Vec12;

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string constraint_name(const Model& model, int j) {
  return "constraint " + std::to_string(j) + " (" +
         to_string(model.constraints[static_cast<size_t>(j)].kind) + ")";
}

Mat3 cross_matrix(const Vec3& v) {
  Mat3 m;
  m << 0.0, -v.z(), v.y(),  //
      v.z(), 0.0, -v.x(),   //
      -v.y(), v.x(), 0.0;
  return m;
}

// ---------------------------------------------------------------------------------------------
// Hessians of the constraint functions.

// Expands a Hessian over the edge vectors y = (x1 - x0, x2 - x0, x3 - x0) (9 x 9) to one over
// (x0, x1, x2, x3): T^T Hy T with T = [-I I 0 0; -I 0 I 0; -I 0 0 I].
Mat12 expand_edge_hessian(const Mat9& Hy) {
  Mat12 H;
  H.bottomRightCorner<9, 9>() = Hy;
  Mat3 total = Mat3::Zero();
  for (int i = 0; i < 3; ++i) {
    Mat3 row_sum = Mat3::Zero(), col_sum = Mat3::Zero();
    for (int j = 0; j < 3; ++j) {
      row_sum += Hy.block<3, 3>(3 * i, 3 * j);
      col_sum += Hy.block<3, 3>(3 * j, 3 * i);
    }
    H.block<3, 3>(3 + 3 * i, 0) = -row_sum;
    H.block<3, 3>(0, 3 + 3 * i) = -col_sum;
    total += row_sum;
  }
  H.block<3, 3>(0, 0) = total;
  return H;
}

// Volume, C = (1/6) e1 . (e2 x e3), e_i = x_i - x0: bilinear in each pair of edges, so its
// second derivatives are constant skew blocks, d2C/de_i de_j = -[e_k]x / 6 for (i, j, k) a cyclic
// permutation of (1, 2, 3) and the transpose for the others; d2C/de_i^2 = 0.
Mat12 volume_hessian(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  const Vec3 e[3] = {x1 - x0, x2 - x0, x3 - x0};
  Mat9 Hy = Mat9::Zero();
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3, k = (i + 2) % 3;
    const Mat3 b = -cross_matrix(e[k]) / 6.0;
    Hy.block<3, 3>(3 * i, 3 * j) = b;
    Hy.block<3, 3>(3 * j, 3 * i) = b.transpose();
  }
  return expand_edge_hessian(Hy);
}

// The bending term, C = theta - rest with theta the dihedral angle acos(n1 . n2) in [0, pi] of
// eval_bending (Mueller et al. 2007, appendix A): n_k = c_k / l_k, l_k = |c_k|, c1 = e x a,
// c2 = e x b, e = x1 - x0, a = x2 - x0, b = x3 - x0; a flat hinge has theta = pi. The derivatives
// of acos(n1 . n2) carry 1 / sin(theta), singular at flat, where cloth rests; here theta is written
// through a signed angle that is smooth there:
//   phi = signed angle from n1 to -n2 about u = e / |e|
//       = atan2((n1 x (-n2)) . u, n1 . (-n2)) = atan2(-|e| V, -c1 . c2),  V = e . (a x b)
//   (c1 x c2 = V e), in (-pi, pi];  theta = pi - |phi|,  C = pi - |phi| - rest.
// phi = 0 at flat, where it is smooth; its branch cut (phi = +-pi) is the fully closed hinge
// theta = 0 (the wings folded onto each other), where phi jumps by 2 pi but grad phi and
// hess phi stay smooth. sign(phi) = -sign(V).
//   grad C = -s grad phi,  s = sign(phi),
//   hess (C^2 / 2) = grad phi grad phi^T - C s hess phi.
// With rest = pi, C = -|phi| and this is grad phi grad phi^T + phi hess phi: smooth through flat
// (the gradient C grad C = phi grad phi vanishes there). With rest < pi, C^2 has a kink at flat
// (an unsigned angle's property: both ways out of flat decrease theta); there, and at the closed
// hinge for rest > 0, the values are one-sided: s = +1 at phi = 0 (-1 at phi = -0), and atan2's
// side at phi = +-pi.
//
// grad phi. Moving x2 by h1 delta along n1 (h1 = l1 / |e|, the distance of x2 from the hinge
// line) turns wing 1, hence n1, by delta about u, so the angle from n1 to -n2 drops by delta;
// likewise for x3 with the opposite sign. Over y = (e, a, b) (x0 fixed; grad_x0 = -(sum)):
//   d phi/da = g_a = -|e| c1 / l1^2 = -n1 / h1,   d phi/db = g_b = |e| c2 / l2^2 = n2 / h2,
//   d phi/de = g_e = -t1 g_a - t2 g_b,   t1 = (a . e) / |e|^2, t2 = (b . e) / |e|^2
// (t_k: where the wing vertex projects on the hinge, 0 at x0, 1 at x1). g_e follows from the
// invariances of phi: rotating everything, e x g_e + a x g_a + b x g_b = 0 fixes the part of g_e
// normal to e ((a - t1 e) x g_a = -u and (b - t2 e) x g_b = u cancel), and scaling about x0,
// e . g_e + a . g_a + b . g_b = 0 with a . g_a = b . g_b = 0 makes e . g_e = 0 (the closed form of
// Bridson et al. 2003 and Tamstorf & Grinspun 2013, written over the edge vectors).
// hess phi, row blocks d g_a/dy, d g_b/dy, d g_e/dy, with d(c / |c|^2)/dc = (I - 2 n n^T) / |c|^2,
// dc1/de = -[a]x, dc1/da = [e]x, dc2/de = -[b]x, dc2/db = [e]x, d|e|/de = u^T:
//   d g_a/de = -n1 u^T / l1 + k1 R1 [a]x,   d g_a/da = -k1 R1 [e]x,   d g_a/db = 0,
//   d g_b/de =  n2 u^T / l2 - k2 R2 [b]x,   d g_b/db =  k2 R2 [e]x,   d g_b/da = 0,
//   k_k = |e| / l_k^2, R_k = I - 2 n_k n_k^T,
//   d g_e/dy = -g_a grad t1^T - t1 d g_a/dy - g_b grad t2^T - t2 d g_b/dy,
//   grad t1 = ((a - 2 t1 e) / |e|^2, e / |e|^2, 0), grad t2 = ((b - 2 t2 e) / |e|^2, 0, e / |e|^2).
// Every factor is bounded while l1, l2 > 0: no 1 / sin(theta) anywhere. The 9 x 9 over y is
// symmetric up to rounding (symmetrized) and expanded to (x0, x1, x2, x3) as the others.
//
// The PBD side (eval_bending, dihedral_angle) keeps acos(n1 . n2): it agrees with pi - |phi| up
// to the rounding of acos near d = n1 . n2 = -1, ~eps / sqrt(2 (1 + d)) = eps / (pi - theta)
// (measured in test_energy.cpp, BendingAngleAgreesWithTheAcosFormUpToItsRounding, 200 hinges
// each: at most 2.5e-12 rad at 1e-4 rad from flat, 2.9e-10 at 1e-6, 1.6e-8 at 1e-8, where acos
// can only return pi or pi - 1.5e-8; 1e-15 at 0.3). pi - |phi| stays within 1.1e-15 rad of the
// angle the hinges were built with at every distance. Near flat, phi itself carries an absolute
// rounding of ~eps (the triple product e . (a x b) cancels), as any angle computed from rounded
// positions does.
//
// Returns false for a degenerate wing (l1 = 0 or l2 = 0, |e| = 0 included): no normal, phi and
// its derivatives undefined (eval_bending reports valid = false there too). grad and hess are
// optional (null: not computed).
bool signed_dihedral(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3, double& phi,
                     Vec12* grad, Mat12* hess) {
  const Vec3 e = x1 - x0, a = x2 - x0, b = x3 - x0;
  const Vec3 c1 = e.cross(a), c2 = e.cross(b);
  const double l1sq = c1.squaredNorm(), l2sq = c2.squaredNorm();
  if (!(l1sq > 0.0) || !(l2sq > 0.0)) return false;
  const double le2 = e.squaredNorm(), le = std::sqrt(le2);
  phi = std::atan2(-le * e.dot(a.cross(b)), -c1.dot(c2));
  if (!grad && !hess) return true;

  const double k1 = le / l1sq, k2 = le / l2sq;
  const Vec3 ga = -k1 * c1, gb = k2 * c2;
  const double t1 = a.dot(e) / le2, t2 = b.dot(e) / le2;
  const Vec3 ge = -t1 * ga - t2 * gb;
  if (grad) {
    grad->segment<3>(3) = ge;
    grad->segment<3>(6) = ga;
    grad->segment<3>(9) = gb;
    grad->segment<3>(0) = -(ge + ga + gb);
  }
  if (!hess) return true;

  const double l1 = std::sqrt(l1sq), l2 = std::sqrt(l2sq);
  const Vec3 n1 = c1 / l1, n2 = c2 / l2, u = e / le;
  const Mat3 R1 = Mat3::Identity() - 2.0 * n1 * n1.transpose();
  const Mat3 R2 = Mat3::Identity() - 2.0 * n2 * n2.transpose();
  const Mat3 ex = cross_matrix(e);
  // Rows: d g_a/dy and d g_b/dy (9 columns over (e, a, b)).
  Eigen::Matrix<double, 3, 9> Da = Eigen::Matrix<double, 3, 9>::Zero();
  Eigen::Matrix<double, 3, 9> Db = Eigen::Matrix<double, 3, 9>::Zero();
  Da.block<3, 3>(0, 0) = -n1 * u.transpose() / l1 + k1 * R1 * cross_matrix(a);
  Da.block<3, 3>(0, 3) = -k1 * R1 * ex;
  Db.block<3, 3>(0, 0) = n2 * u.transpose() / l2 - k2 * R2 * cross_matrix(b);
  Db.block<3, 3>(0, 6) = k2 * R2 * ex;
  Vec9 dt1 = Vec9::Zero(), dt2 = Vec9::Zero();
  dt1.segment<3>(0) = (a - 2.0 * t1 * e) / le2;
  dt1.segment<3>(3) = e / le2;
  dt2.segment<3>(0) = (b - 2.0 * t2 * e) / le2;
  dt2.segment<3>(6) = e / le2;
  Mat9 Hy;
  Hy.block<3, 9>(0, 0) = -ga * dt1.transpose() - t1 * Da - gb * dt2.transpose() - t2 * Db;
  Hy.block<3, 9>(3, 0) = Da;
  Hy.block<3, 9>(6, 0) = Db;
  *hess = expand_edge_hessian(0.5 * (Hy + Hy.transpose()));
  return true;
}

// The bending term's C (energy: the accurate angle pi - |phi|, not acos), and optionally
// grad C = -s grad phi and the Hessian of C^2 / 2, grad phi grad phi^T - C s hess phi (see
// signed_dihedral). A degenerate wing reports the angle as 0 (C = -rest) and valid = false, as
// eval_bending does.
struct BendingTerm {
  double C = 0.0;
  bool valid = true;
};

BendingTerm bending_term(const Constraint& c, const Points& x, Vec12* grad_C, Mat12* hess_half_C2) {
  const auto& p = c.particles;
  const Vec3 x0 = x.row(p[0]), x1 = x.row(p[1]), x2 = x.row(p[2]), x3 = x.row(p[3]);
  BendingTerm t;
  double phi = 0.0;
  Vec12 gphi;
  Mat12 hphi;
  if (!signed_dihedral(x0, x1, x2, x3, phi, grad_C || hess_half_C2 ? &gphi : nullptr,
                       hess_half_C2 ? &hphi : nullptr)) {
    t.C = -c.rest;
    t.valid = false;
    return t;
  }
  t.C = (std::numbers::pi - c.rest) - std::abs(phi);  // exactly -|phi| for rest = pi (as a double)
  const double s = std::signbit(phi) ? -1.0 : 1.0;
  if (grad_C) *grad_C = -s * gphi;
  if (hess_half_C2) *hess_half_C2 = gphi * gphi.transpose() - (t.C * s) * hphi;
  return t;
}

// Adds the dense block H over K particles (dofs dof[0..K-1], -1 = not dynamic) at its slots.
template <int K>
void scatter(const Eigen::Matrix<double, 3 * K, 3 * K>& H, const std::int64_t* slots,
             const int* dof, const std::int64_t* column_start, double* values) {
  for (int j = 0; j < K; ++j) {
    if (dof[j] < 0) continue;
    const std::int64_t stride = column_start[3 * dof[j] + 1] - column_start[3 * dof[j]];
    for (int i = 0; i < K; ++i) {
      const std::int64_t base = slots[i + K * j];
      if (base < 0) continue;
      for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) values[base + c * stride + r] += H(3 * i + r, 3 * j + c);
    }
  }
}

}  // namespace

double smooth_bending(const Constraint& c, const Points& x, Eigen::Matrix<double, 12, 1>* grad_C,
                      bool* valid) {
  const BendingTerm t = bending_term(c, x, grad_C, nullptr);
  if (valid) *valid = t.valid;
  return t.C;
}

Eigen::Matrix<double, 12, 12> volume_constraint_hessian(const Vec3& x0, const Vec3& x1,
                                                        const Vec3& x2, const Vec3& x3) {
  return volume_hessian(x0, x1, x2, x3);
}

// ---------------------------------------------------------------------------------------------
// Construction: dofs, masses, term lists, the pattern and the slots.

EnergyModel::EnergyModel(const Model& model) : model_(&model) {
  const int n = model.particle_count();
  if (static_cast<int>(model.inv_mass.size()) != n)
    throw std::invalid_argument("the model has " + std::to_string(n) + " particles but " +
                                std::to_string(model.inv_mass.size()) + " inverse masses");
  particle_dof_.assign(static_cast<size_t>(n), -1);
  for (int p = 0; p < n; ++p) {
    const double w = model.inv_mass[static_cast<size_t>(p)];
    if (!(w >= 0.0) || !std::isfinite(w))
      throw std::invalid_argument("particle " + std::to_string(p) + " has inverse mass " + num(w) +
                                  ": not a finite number >= 0");
    if (w > 0.0) {
      particle_dof_[static_cast<size_t>(p)] = static_cast<int>(dof_particle_.size());
      dof_particle_.push_back(p);
    }
  }
  const int blocks = static_cast<int>(dof_particle_.size());
  mass_.resize(3 * blocks);
  for (int k = 0; k < blocks; ++k)
    mass_.segment<3>(3 * k).setConstant(1.0 / model.inv_mass[static_cast<size_t>(dof_particle_[static_cast<size_t>(k)])]);

  for (size_t a = 0; a < model.attachments.size(); ++a) {
    const Attachment& at = model.attachments[a];
    const std::string name = "attachment " + std::to_string(a);
    if (at.particle < 0 || at.particle >= n)
      throw std::invalid_argument(name + ": particle " + std::to_string(at.particle) + " is out of range");
    if (particle_dof_[static_cast<size_t>(at.particle)] >= 0)
      throw std::invalid_argument(name + ": particle " + std::to_string(at.particle) +
                                  " has inverse mass > 0; an attached particle must have 0");
    if (at.motion >= static_cast<int>(model.motions.size()))
      throw std::invalid_argument(name + ": motion " + std::to_string(at.motion) + " is out of range");
  }

  // Constraints: compliant ones are terms of U, rigid ones are listed, FEM-kind ones stand for
  // their element (and contribute their damping only). The damping of a rigid constraint is left
  // out: XPBD's damping factor gamma = alpha beta / h vanishes with alpha, and on the constraint
  // manifold that ref-dae keeps grad C . v = 0 anyway.
  std::vector<int> damped_fem;
  for (int j = 0; j < model.constraint_count(); ++j) {
    const Constraint& c = model.constraints[static_cast<size_t>(j)];
    const std::string name = constraint_name(model, j);
    for (int i = 0; i < arity(c.kind); ++i) {
      const int p = c.particles[static_cast<size_t>(i)];
      if (p < 0 || p >= n)
        throw std::invalid_argument(name + ": particle " + std::to_string(p) + " is out of range");
    }
    if (!(c.compliance >= 0.0) || !std::isfinite(c.compliance))
      throw std::invalid_argument(name + ": compliance " + num(c.compliance) +
                                  " is not a finite number >= 0");
    if (!(c.damping >= 0.0) || !std::isfinite(c.damping))
      throw std::invalid_argument(name + ": damping " + num(c.damping) + " is not a finite number >= 0");
    if (is_fem_kind(c.kind)) {
      if (c.element < 0 || c.element >= static_cast<int>(model.elements.size()))
        throw std::invalid_argument(name + ": element " + std::to_string(c.element) + " is out of range");
      if (c.damping > 0.0 && is_strain_kind(c.kind))
        throw std::invalid_argument(name + ": damping " + num(c.damping) +
                                    " on a strain-vector constraint is not supported");
      if (c.damping > 0.0) damped_fem.push_back(j);
    } else if (c.compliance == 0.0) {
      rigid_.push_back(j);
    } else {
      if (c.damping > 0.0) {
        damped_.push_back(j);
        damped_term_.push_back(static_cast<int>(compliant_.size()));
      }
      compliant_.push_back(j);
    }
  }
  for (size_t k = 0; k < model.elements.size(); ++k) {
    const FemElement& e = model.elements[k];
    const std::string name = "element " + std::to_string(k);
    for (int i = 0; i < e.vertices; ++i)
      if (const int p = e.particles[static_cast<size_t>(i)]; p < 0 || p >= n)
        throw std::invalid_argument(name + ": particle " + std::to_string(p) + " is out of range");
    if (!(e.rest_volume > 0.0) || !std::isfinite(e.rest_volume))
      throw std::invalid_argument(name + ": rest volume " + num(e.rest_volume) + " is not > 0");
    if (!e.rest_inverse.allFinite())
      throw std::invalid_argument(name + ": rest inverse is not finite");
    if (!std::isfinite(e.mu) || !std::isfinite(e.lambda) || !(e.mu >= 0.0))
      throw std::invalid_argument(name + ": mu " + num(e.mu) + " or lambda " + num(e.lambda) +
                                  " is not finite, or mu < 0");
    if (e.material == Material::StableNeoHookean && !(fem::snh_lambda(e.mu, e.lambda) > 0.0))
      throw std::invalid_argument(name + ": lambda + mu = " + num(e.mu + e.lambda) +
                                  " is not > 0 (stable neo-Hookean)");
  }
  const int first_fem_term = static_cast<int>(compliant_.size() + model.elements.size());
  for (size_t k = 0; k < damped_fem.size(); ++k) {
    damped_.push_back(damped_fem[k]);
    damped_term_.push_back(first_fem_term + static_cast<int>(k));
  }
  has_damping_ = !damped_.empty();

  // The stencil of every term, in term order.
  const size_t terms = compliant_.size() + model.elements.size() + damped_fem.size();
  std::vector<const int*> stencil(terms);
  std::vector<int> stencil_size(terms);
  // A triangle element's fourth stencil entry is -1: no particle, no dof.
  auto dof_of = [&](int p) { return p < 0 ? -1 : particle_dof_[static_cast<size_t>(p)]; };
  {
    size_t t = 0;
    for (int j : compliant_) {
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      stencil[t] = c.particles.data();
      stencil_size[t++] = arity(c.kind);
    }
    for (const FemElement& e : model.elements) {
      stencil[t] = e.particles.data();
      stencil_size[t++] = 4;
    }
    for (int j : damped_fem) {
      stencil[t] = model.constraints[static_cast<size_t>(j)].particles.data();
      stencil_size[t++] = 4;
    }
  }

  // Block pattern (one entry per pair of dof blocks), by counting then filling: every pair of
  // dynamic particles of a stencil, and every diagonal block.
  std::vector<std::int64_t> block_start(static_cast<size_t>(blocks) + 1, 0);
  for (int k = 0; k < blocks; ++k) block_start[static_cast<size_t>(k) + 1] = 1;
  for (size_t t = 0; t < terms; ++t)
    for (int j = 0; j < stencil_size[t]; ++j) {
      const int dj = dof_of(stencil[t][j]);
      if (dj < 0) continue;
      for (int i = 0; i < stencil_size[t]; ++i)
        if (dof_of(stencil[t][i]) >= 0) ++block_start[static_cast<size_t>(dj) + 1];
    }
  for (int k = 0; k < blocks; ++k) block_start[static_cast<size_t>(k) + 1] += block_start[static_cast<size_t>(k)];
  std::vector<int> block_row(static_cast<size_t>(block_start.back()));
  {
    std::vector<std::int64_t> fill(block_start.begin(), block_start.end() - 1);
    for (int k = 0; k < blocks; ++k) block_row[static_cast<size_t>(fill[static_cast<size_t>(k)]++)] = k;
    for (size_t t = 0; t < terms; ++t)
      for (int j = 0; j < stencil_size[t]; ++j) {
        const int dj = dof_of(stencil[t][j]);
        if (dj < 0) continue;
        for (int i = 0; i < stencil_size[t]; ++i) {
          const int di = dof_of(stencil[t][i]);
          if (di >= 0) block_row[static_cast<size_t>(fill[static_cast<size_t>(dj)]++)] = di;
        }
      }
  }
  // Sort and deduplicate each block column, compacting in place.
  std::int64_t out = 0;
  for (int k = 0; k < blocks; ++k) {
    const auto begin = block_row.begin() + block_start[static_cast<size_t>(k)];
    const auto end = block_row.begin() + block_start[static_cast<size_t>(k) + 1];
    std::sort(begin, end);
    const auto last = std::unique(begin, end);
    block_start[static_cast<size_t>(k)] = out;
    for (auto it = begin; it != last; ++it) block_row[static_cast<size_t>(out++)] = *it;
  }
  block_start[static_cast<size_t>(blocks)] = out;
  block_row.resize(static_cast<size_t>(out));

  // Scalar pattern: block column k gives columns 3k, 3k+1, 3k+2, each with the rows 3b, 3b+1,
  // 3b+2 of every block row b (sorted, since the block rows are).
  pattern_.n = 3 * blocks;
  pattern_.column_start.assign(static_cast<size_t>(3 * blocks) + 1, 0);
  pattern_.row.resize(static_cast<size_t>(9 * out));
  for (int k = 0; k < blocks; ++k) {
    const std::int64_t first = block_start[static_cast<size_t>(k)];
    const std::int64_t count = block_start[static_cast<size_t>(k) + 1] - first;
    for (int c = 0; c < 3; ++c) {
      const std::int64_t start = 9 * first + 3 * count * c;
      pattern_.column_start[static_cast<size_t>(3 * k + c)] = start;
      for (std::int64_t m = 0; m < count; ++m)
        for (int r = 0; r < 3; ++r)
          pattern_.row[static_cast<size_t>(start + 3 * m + r)] = 3 * block_row[static_cast<size_t>(first + m)] + r;
    }
  }
  pattern_.column_start[static_cast<size_t>(3 * blocks)] = 9 * out;

  // Slots: for block (i, j) of a term, the position of entry (3 dof_i, 3 dof_j).
  slot_start_.assign(terms + 1, 0);
  for (size_t t = 0; t < terms; ++t)
    slot_start_[t + 1] = slot_start_[t] + stencil_size[t] * stencil_size[t];
  slots_.assign(static_cast<size_t>(slot_start_.back()), -1);
  for (size_t t = 0; t < terms; ++t) {
    const int K = stencil_size[t];
    for (int j = 0; j < K; ++j) {
      const int dj = dof_of(stencil[t][j]);
      if (dj < 0) continue;
      const auto begin = block_row.begin() + block_start[static_cast<size_t>(dj)];
      const auto end = block_row.begin() + block_start[static_cast<size_t>(dj) + 1];
      for (int i = 0; i < K; ++i) {
        const int di = dof_of(stencil[t][i]);
        if (di < 0) continue;
        const std::int64_t m = std::lower_bound(begin, end, di) - begin;
        slots_[static_cast<size_t>(slot_start_[t] + i + K * j)] =
            pattern_.column_start[static_cast<size_t>(3 * dj)] + 3 * m;
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Positions and velocities.

void EnergyModel::positions(const Eigen::VectorXd& q, double t, Points& x) const {
  const Model& model = *model_;
  const int n = model.particle_count();
  x.resize(n, 3);
  for (int p = 0; p < n; ++p) {
    const int d = particle_dof_[static_cast<size_t>(p)];
    if (d >= 0) x.row(p) = q.segment<3>(3 * d).transpose();
    else x.row(p) = model.rest_positions.row(p);
  }
  for (const Attachment& a : model.attachments)
    x.row(a.particle) = attachment_target(model, a, t).transpose();
}

void EnergyModel::velocities(const Eigen::VectorXd& u, double t, Points& v) const {
  const Model& model = *model_;
  const int n = model.particle_count();
  v.resize(n, 3);
  for (int p = 0; p < n; ++p) {
    const int d = particle_dof_[static_cast<size_t>(p)];
    if (d >= 0) v.row(p) = u.segment<3>(3 * d).transpose();
    else v.row(p).setZero();
  }
  for (const Attachment& a : model.attachments)
    if (a.motion >= 0)
      v.row(a.particle) = motion_velocity(model.motions[static_cast<size_t>(a.motion)], t).transpose();
}

Eigen::VectorXd EnergyModel::gather(const Points& all) const {
  Eigen::VectorXd q(dofs());
  for (size_t k = 0; k < dof_particle_.size(); ++k)
    q.segment<3>(3 * static_cast<Eigen::Index>(k)) = all.row(dof_particle_[k]).transpose();
  return q;
}

// ---------------------------------------------------------------------------------------------
// Energy, gradient, Hessian.

double EnergyModel::energy(const Points& x) const {
  const Model& model = *model_;
  double U = 0.0;
  for (int j : compliant_) {
    const Constraint& c = model.constraints[static_cast<size_t>(j)];
    const double C = c.kind == ConstraintKind::Bending ? bending_term(c, x, nullptr, nullptr).C
                                                       : eval_constraint(c, x).C;
    U += C * C / (2.0 * c.compliance);
  }
  for (const FemElement& e : model.elements) U += fem::element_energy(e, x);
  for (size_t k = 0; k < dof_particle_.size(); ++k) {
    const int p = dof_particle_[k];
    U -= mass_(3 * static_cast<Eigen::Index>(k)) * model.gravity.dot(x.row(p).transpose());
  }
  return U;
}

void EnergyModel::gradient(const Points& x, Eigen::VectorXd& g) const {
  const Model& model = *model_;
  g.setZero(dofs());
  for (int j : compliant_) {
    const Constraint& c = model.constraints[static_cast<size_t>(j)];
    if (c.kind == ConstraintKind::Bending) {  // the smooth form, see signed_dihedral
      Vec12 gC;
      const BendingTerm bt = bending_term(c, x, &gC, nullptr);
      if (!bt.valid) continue;
      const double f = bt.C / c.compliance;
      for (int i = 0; i < 4; ++i) {
        const int d = particle_dof_[static_cast<size_t>(c.particles[static_cast<size_t>(i)])];
        if (d >= 0) g.segment<3>(3 * d) += f * gC.segment<3>(3 * i);
      }
      continue;
    }
    const ConstraintEval ev = eval_constraint(c, x);
    if (!ev.valid) continue;
    const double f = ev.C / c.compliance;
    for (int i = 0; i < arity(c.kind); ++i) {
      const int d = particle_dof_[static_cast<size_t>(c.particles[static_cast<size_t>(i)])];
      if (d >= 0) g.segment<3>(3 * d) += f * ev.grad[static_cast<size_t>(i)];
    }
  }
  for (const FemElement& e : model.elements) {
    const Vec12 ge = fem::element_gradient(e, x);
    for (int i = 0; i < e.vertices; ++i) {
      const int d = particle_dof_[static_cast<size_t>(e.particles[static_cast<size_t>(i)])];
      if (d >= 0) g.segment<3>(3 * d) += ge.segment<3>(3 * i);
    }
  }
  for (size_t k = 0; k < dof_particle_.size(); ++k)
    g.segment<3>(3 * static_cast<Eigen::Index>(k)) -= mass_(3 * static_cast<Eigen::Index>(k)) * model.gravity;
}

template <class Visit>
void EnergyModel::visit_hessian_terms(const Points& x, bool project, Visit&& visit) const {
  const Model& model = *model_;
  int dof[4];
  size_t t = 0;
  for (int j : compliant_) {
    const Constraint& c = model.constraints[static_cast<size_t>(j)];
    const std::int64_t* slots = slots_.data() + slot_start_[t++];
    const auto& p = c.particles;
    for (int i = 0; i < arity(c.kind); ++i) dof[i] = particle_dof_[static_cast<size_t>(p[static_cast<size_t>(i)])];
    const double inv_alpha = 1.0 / c.compliance;
    switch (c.kind) {
      case ConstraintKind::Distance: {
        // C = |d| - rest, d = x1 - x0, n = d / |d|: hess C = [K -K; -K K], K = (I - n n^T) / |d|.
        // The term's block is [B -B; -B B], B = (n n^T + (C / |d|) (I - n n^T)) / alpha; its
        // projection replaces C / |d| by max(C / |d|, 0) (the eigenvalues of B are 1/alpha and
        // C / (|d| alpha) twice, those of the whole twice these).
        const Vec3 d = x.row(p[1]) - x.row(p[0]);
        const double len = d.norm();
        if (!(len > 0.0)) continue;
        const Vec3 nrm = d / len;
        double ratio = (len - c.rest) / len;
        if (project) ratio = std::max(ratio, 0.0);
        const Mat3 nn = nrm * nrm.transpose();
        const Mat3 B = inv_alpha * (nn + ratio * (Mat3::Identity() - nn));
        Mat6 H;
        H << B, -B, -B, B;
        visit(H, slots, dof);
        break;
      }
      case ConstraintKind::Volume: {
        const Vec3 x0 = x.row(p[0]), x1 = x.row(p[1]), x2 = x.row(p[2]), x3 = x.row(p[3]);
        const ConstraintEval ev = eval_volume(x0, x1, x2, x3, c.rest);
        if (!ev.valid) continue;
        if (project) {  // the same projection through the term's analytic eigensystem
          visit(psd::volume_term_hessian_psd(x0, x1, x2, x3, c.rest, c.compliance), slots, dof);
          break;
        }
        Vec12 g;
        for (int i = 0; i < 4; ++i) g.segment<3>(3 * i) = ev.grad[static_cast<size_t>(i)];
        const Mat12 H = inv_alpha * (g * g.transpose() + ev.C * volume_hessian(x0, x1, x2, x3));
        visit(H, slots, dof);
        break;
      }
      case ConstraintKind::Bending: {
        // (grad phi grad phi^T - C s hess phi) / alpha, see signed_dihedral: defined at flat.
        Mat12 H;
        if (!bending_term(c, x, nullptr, &H).valid) continue;
        H *= inv_alpha;
        if (project)  // 8 x 8: a hinge sees neither translations nor the slide along its edge
          psd::project_psd_hinge(H, x.row(p[0]), x.row(p[1]), x.row(p[2]), x.row(p[3]));
        visit(H, slots, dof);
        break;
      }
      case ConstraintKind::FemDeviatoric:
      case ConstraintKind::FemHydrostatic:
      case ConstraintKind::FemStrainTriangle:
      case ConstraintKind::FemStrainTet:
        break;  // never in compliant_
    }
  }
  for (const FemElement& e : model.elements) {
    const std::int64_t* slots = slots_.data() + slot_start_[t++];
    for (int i = 0; i < 4; ++i)
      dof[i] = i < e.vertices ? particle_dof_[static_cast<size_t>(e.particles[static_cast<size_t>(i)])] : -1;
    const Mat12 H = fem::element_hessian(e, x, project);
    visit(H, slots, dof);
  }
}

void EnergyModel::hessian(const Points& x, std::vector<double>& values, bool project) const {
  values.assign(static_cast<size_t>(pattern_.nnz()), 0.0);
  double* out = values.data();
  const std::int64_t* cs = pattern_.column_start.data();
  visit_hessian_terms(x, project, [&](const auto& H, const std::int64_t* slots, const int* dof) {
    constexpr int K = std::decay_t<decltype(H)>::RowsAtCompileTime / 3;
    scatter<K>(H, slots, dof, cs, out);
  });
}

void EnergyModel::hessian_product(const Points& x, const Eigen::VectorXd& v, Eigen::VectorXd& out,
                                  bool project) const {
  out.setZero(dofs());
  visit_hessian_terms(x, project, [&](const auto& H, const std::int64_t*, const int* dof) {
    constexpr int K = std::decay_t<decltype(H)>::RowsAtCompileTime / 3;
    Eigen::Matrix<double, 3 * K, 1> local = Eigen::Matrix<double, 3 * K, 1>::Zero();
    for (int i = 0; i < K; ++i)
      if (dof[i] >= 0) local.template segment<3>(3 * i) = v.segment<3>(3 * dof[i]);
    const Eigen::Matrix<double, 3 * K, 1> product = H * local;
    for (int i = 0; i < K; ++i)
      if (dof[i] >= 0) out.segment<3>(3 * dof[i]) += product.template segment<3>(3 * i);
  });
}

// ---------------------------------------------------------------------------------------------
// Damping: f_d = -sum beta grad C (grad C . v), D = sum beta grad C grad C^T.

void EnergyModel::damping_force(const Points& x, const Points& v, Eigen::VectorXd& f) const {
  const Model& model = *model_;
  f.setZero(dofs());
  for (int j : damped_) {
    const Constraint& c = model.constraints[static_cast<size_t>(j)];
    const ConstraintEval ev = eval_constraint(model, c, x);
    if (!ev.valid) continue;
    const int k = arity(c.kind);
    double rate = 0.0;  // dC/dt = grad C . v, kinematic particles included
    for (int i = 0; i < k; ++i)
      rate += ev.grad[static_cast<size_t>(i)].dot(v.row(c.particles[static_cast<size_t>(i)]).transpose());
    for (int i = 0; i < k; ++i) {
      const int d = particle_dof_[static_cast<size_t>(c.particles[static_cast<size_t>(i)])];
      if (d >= 0) f.segment<3>(3 * d) -= (c.damping * rate) * ev.grad[static_cast<size_t>(i)];
    }
  }
}

void EnergyModel::damping_matrix(const Points& x, std::vector<double>& values) const {
  const Model& model = *model_;
  values.assign(static_cast<size_t>(pattern_.nnz()), 0.0);
  int dof[4];
  for (size_t k = 0; k < damped_.size(); ++k) {
    const Constraint& c = model.constraints[static_cast<size_t>(damped_[k])];
    const ConstraintEval ev = eval_constraint(model, c, x);
    if (!ev.valid) continue;
    const std::int64_t* slots = slots_.data() + slot_start_[static_cast<size_t>(damped_term_[k])];
    const int K = arity(c.kind);
    for (int i = 0; i < K; ++i) dof[i] = particle_dof_[static_cast<size_t>(c.particles[static_cast<size_t>(i)])];
    if (K == 2) {
      Eigen::Matrix<double, 6, 1> g;
      g << ev.grad[0], ev.grad[1];
      const Mat6 D = c.damping * (g * g.transpose());
      scatter<2>(D, slots, dof, pattern_.column_start.data(), values.data());
    } else {
      Vec12 g;
      for (int i = 0; i < 4; ++i) g.segment<3>(3 * i) = ev.grad[static_cast<size_t>(i)];
      const Mat12 D = c.damping * (g * g.transpose());
      scatter<4>(D, slots, dof, pattern_.column_start.data(), values.data());
    }
  }
}

void EnergyModel::constraint_forces(const Points& x, std::vector<double>& lambda) const {
  const Model& model = *model_;
  lambda.resize(static_cast<size_t>(model.constraint_count()), 0.0);
  for (int j : compliant_) {
    const Constraint& c = model.constraints[static_cast<size_t>(j)];
    lambda[static_cast<size_t>(j)] = -eval_constraint(c, x).C / c.compliance;
  }
}

}  // namespace pbdbench
