// A scene as an energy, over its dynamic degrees of freedom: what every reference integrator
// integrates. Built once from a Model (the sparsity pattern of the Hessian is fixed then), then
// evaluated at any positions.
//
//   U(x) = sum over compliant constraints (compliance > 0) of C(x)^2 / (2 alpha)
//        + sum over FEM elements of V0 (Psi(F) - Psi(I))       (FEM-kind constraints are skipped:
//                                                               their elements stand for them)
//        - sum over dynamic particles of m g . x
//   damping force f_d(x, v) = - sum over constraints of beta grad C (grad C . v)
//                             (compliant and FEM-kind constraints, v including the kinematic
//                             particles' velocities; a rigid constraint's beta is ignored: XPBD's
//                             gamma = alpha beta / h vanishes with alpha)
//
// The degrees of freedom q are the coordinates of the dynamic particles (inv_mass > 0), three per
// particle in particle order; kinematic and pinned particles sit on their targets at time t.
// Rigid constraints (compliance 0) are not part of U: they are listed for ref-dae.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/model.hpp"

namespace pbdbench {

// A compressed sparse column pattern of a symmetric n x n matrix, stored whole (both triangles)
// with every diagonal entry present, row indices sorted within each column.
struct SparsityPattern {
  int n = 0;
  std::vector<std::int64_t> column_start;  // (n + 1)
  std::vector<std::int64_t> row;           // (nnz)
  std::int64_t nnz() const { return static_cast<std::int64_t>(row.size()); }
  // Position of entry (r, c) in `row` (and in any values array of this pattern), or -1.
  std::int64_t find(int r, int c) const;
};

class EnergyModel {
 public:
  // Keeps a pointer to `model`, which must outlive this object. Throws std::invalid_argument
  // naming the constraint or element when the model has something U cannot express.
  // (Mueller et al. 2007's bending constraint uses the unsigned angle theta in [0, pi]; U writes
  // it as pi - |phi| with phi a signed angle smooth at flat (reference/energy.cpp,
  // signed_dihedral), so a flat hinge with rest angle pi has a smooth term. C^2 has a kink at a
  // flat hinge unless its rest angle is pi, and at a fully folded one unless it is 0: there the
  // gradient and Hessian take one-sided values. A hinge with a degenerate wing has no angle: its
  // term contributes its energy with the angle taken as 0, and no gradient or Hessian.)
  explicit EnergyModel(const Model& model);

  int dofs() const { return static_cast<int>(dof_particle_.size()) * 3; }
  const std::vector<int>& dynamic_particles() const { return dof_particle_; }  // (dofs/3)
  const Eigen::VectorXd& mass() const { return mass_; }                      // (dofs), kg per dof
  const std::vector<int>& rigid_constraints() const { return rigid_; }       // model indices

  // All particle positions (n x 3) from q at time t: dynamic ones from q, the others on their
  // attachment targets (or their rest positions when pinned without an attachment).
  void positions(const Eigen::VectorXd& q, double t, Points& x) const;
  // All particle velocities from u (the dofs' velocities) at time t (kinematic ones from their
  // motions, pinned ones zero).
  void velocities(const Eigen::VectorXd& u, double t, Points& v) const;
  // q (and u) from all particle positions (velocities).
  Eigen::VectorXd gather(const Points& all) const;

  // U(x) (J), its gradient dU/dq (N) and Hessian d2U/dq2 (N/m) in hessian_pattern() order.
  double energy(const Points& x) const;
  void gradient(const Points& x, Eigen::VectorXd& g) const;
  const SparsityPattern& hessian_pattern() const { return pattern_; }
  // With project_psd each term's dense block is projected onto the positive semi-definite cone
  // (negative eigenvalues clamped to 0) before it is added, so the sum is PSD.
  void hessian(const Points& x, std::vector<double>& values, bool project_psd = false) const;
  // out = (d2U/dq2) v term by term, never assembled (the same terms and projection as hessian()).
  void hessian_product(const Points& x, const Eigen::VectorXd& v, Eigen::VectorXd& out,
                       bool project_psd = false) const;

  // Damping force f_d (N, per dof) and the matrix D = sum beta grad C grad C^T (N s/m, in
  // hessian_pattern() order) with f_d = -D v. Zero when no constraint has damping.
  bool has_damping() const { return has_damping_; }
  void damping_force(const Points& x, const Points& v, Eigen::VectorXd& f) const;
  void damping_matrix(const Points& x, std::vector<double>& values) const;

  // Force multipliers of the compliant constraints, -C/alpha (N per unit of C), written into
  // lambda (model.constraint_count()); rigid and FEM-kind entries are left untouched.
  void constraint_forces(const Points& x, std::vector<double>& lambda) const;

 private:
  const Model* model_;
  std::vector<int> dof_particle_;   // particle of dof block k
  std::vector<int> particle_dof_;   // dof block of a particle, or -1
  Eigen::VectorXd mass_;
  std::vector<int> rigid_;
  std::vector<int> compliant_;      // model constraints in U
  std::vector<int> damped_;         // model constraints in f_d: compliant or FEM-kind, damping > 0
  std::vector<int> damped_term_;    // (damped_.size()) the term whose slots each one uses
  bool has_damping_ = false;
  SparsityPattern pattern_;
  // Hessian slots, one per 3x3 block. Terms: the compliant constraints, then the FEM elements,
  // then the damped FEM-kind constraints. Term k owns slots_[slot_start_[k] ...] (arity^2 of
  // them): for particles (i, j) of its stencil, slot i + arity j is the pattern position of entry
  // (3 dof_i, 3 dof_j), -1 where a particle is not dynamic; entry (3 dof_i + r, 3 dof_j + c) is at
  // that position + c (column_start[3 dof_j + 1] - column_start[3 dof_j]) + r.
  std::vector<std::int64_t> slots_;
  std::vector<std::int64_t> slot_start_;  // (terms + 1)

  // Calls visit(H, slots, dof) for each term of d2U/dq2 with its dense block H (6 x 6 or
  // 12 x 12), its slots and the dof blocks of its particles (-1: not dynamic).
  template <class Visit>
  void visit_hessian_terms(const Points& x, bool project, Visit&& visit) const;
};

// A bending constraint's C as U writes it (pi - |phi| - rest, phi the signed angle smooth at
// flat; see EnergyModel) and, when grad_C is given, its gradient over the four particles. valid
// is false for a degenerate wing (C = -rest then).
double smooth_bending(const Constraint& c, const Points& x, Eigen::Matrix<double, 12, 1>* grad_C,
                      bool* valid = nullptr);

// d2C/dx2 of the volume constraint C = (1/6) (x1-x0) . ((x2-x0) x (x3-x0)) - rest (12 x 12 over
// x0..x3; C is cubic, so this is linear in the positions).
Eigen::Matrix<double, 12, 12> volume_constraint_hessian(const Vec3& x0, const Vec3& x1,
                                                        const Vec3& x2, const Vec3& x3);

}  // namespace pbdbench
