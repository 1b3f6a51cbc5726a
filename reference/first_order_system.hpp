// A MechanicalSystem M q'' = f(t, q, u) over n dofs as the first-order system the ODE
// integrators (ref-bdf, ref-be, ref-sdirk2) integrate, over 2n unknowns y = [q; u]:
//
//   y' = [u; M^-1 f(t, q, u)]
//   J = dy'/dy = [[0,         I        ],      (K = -df/dq, D = -df/du, both from the
//                 [-M^-1 K,  -M^-1 D   ]]       MechanicalSystem in its pattern)
//
// J's pattern is built once: column j < n holds (j, j), an explicit zero, then the rows n + i of
// the pattern's column j (-K_ij / m_i); column n + j holds (j, n + j) = 1, then the rows n + i of
// the pattern's column j (-D_ij / m_i) when the system has damping, else only (n + j, n + j), an
// explicit zero. So every diagonal entry of the 2n x 2n matrix is in the pattern, and the
// integrators' I - gamma J (SUNMatScaleAddI) keeps it: KLU's symbolic analysis is done once.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "reference/mechanical_system.hpp"
#include "reference/sundials_support.hpp"

namespace pbdbench {

class FirstOrderSystem {
 public:
  // Keeps a reference to `system`, which must outlive this object.
  explicit FirstOrderSystem(const MechanicalSystem& system);

  int dofs() const { return n_; }       // n
  int size() const { return 2 * n_; }   // 2n
  const MechanicalSystem& system() const { return system_; }

  // y' at (t, y): ydot = [u; M^-1 f(t, q, u)]. y and ydot have size() entries, distinct.
  void rhs(double t, const double* y, double* ydot);
  // J's values at (t, y) in jacobian_pattern() order, every entry written (explicit zeros too).
  void jacobian(double t, const double* y, double* values);
  const sun::CscPattern& jacobian_pattern() const { return pattern_; }

  // Where J's blocks sit in jacobian_pattern(), for a linear solver that works on the n x n
  // blocks of I - gamma J (ReducedLinearSolver): for entry p of system().pattern() (row i,
  // column j), the slot of (n + i, j) (-K_ij / m_i) and of (n + i, n + j) (-D_ij / m_i; -1
  // without damping); for each j, the slots of (j, j) (the explicit zero of the position
  // block), (j, n + j) (the identity block) and (n + j, n + j).
  const std::vector<sunindextype>& stiffness_slots() const { return k_slot_; }
  const std::vector<sunindextype>& damping_slots() const { return d_slot_; }
  const std::vector<sunindextype>& position_diagonal_slots() const { return q_diag_slot_; }
  const std::vector<sunindextype>& identity_slots() const { return identity_slot_; }
  const std::vector<sunindextype>& velocity_diagonal_slots() const { return u_diag_slot_; }

  // y = [q; u] and back.
  void pack(const Eigen::VectorXd& q, const Eigen::VectorXd& u, double* y) const;
  void unpack(const double* y, Eigen::VectorXd& q, Eigen::VectorXd& u) const;

 private:
  void load(const double* y);  // q_, u_ from y

  const MechanicalSystem& system_;
  int n_ = 0;
  Eigen::VectorXd inv_mass_;  // (n) 1/kg per dof
  sun::CscPattern pattern_;   // (2n x 2n)
  // For entry p of system_.pattern() (row i, column j): the slot of (n + i, j) in pattern_, and
  // of (n + i, n + j) when the system has damping; the row i of each entry.
  std::vector<sunindextype> k_slot_, d_slot_;
  std::vector<int> entry_row_;
  std::vector<sunindextype> identity_slot_;  // (n) slot of (j, n + j)
  std::vector<sunindextype> q_diag_slot_;    // (n) slot of (j, j)
  std::vector<sunindextype> u_diag_slot_;    // (n) slot of (n + j, n + j)
  // Scratch.
  Eigen::VectorXd q_, u_, f_;
  std::vector<double> k_values_, d_values_;
};

}  // namespace pbdbench
