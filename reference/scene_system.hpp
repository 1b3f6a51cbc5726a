// A Model as a MechanicalSystem (reference/mechanical_system.hpp), through its EnergyModel:
//
//   M q'' = f(t, q, u) = -dU/dq (x(t, q)) + f_d(x(t, q), v(t, u))
//
// with x(t, q) all particle positions (the kinematic particles on their targets at time t, so f
// depends on t) and v(t, u) all velocities (the kinematic ones from their motions). The damping
// force f_d = -sum beta grad C (grad C . v) sees the kinematic particles' velocities too: it is
// -D(q) u plus the drag of the moving targets, which does not depend on u. The Jacobians:
//   K = -df/dq = d2U/dq2, exact for U. The damping force's dependence on q (through grad C) is
//       left out of K, as MechanicalSystem allows: it vanishes at rest and does not change the
//       converged solution of an implicit step.
//   D = -df/du = sum beta grad C grad C^T (EnergyModel::damping_matrix), exact.
// The potential is U(x(t, q)).
//
// Not thread-safe: force, stiffness, damping and potential share scratch buffers (the positions
// and velocities of all particles), so that they allocate nothing after the first call.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"
#include "reference/energy.hpp"
#include "reference/mechanical_system.hpp"

namespace pbdbench {

class SceneSystem final : public MechanicalSystem {
 public:
  // Keeps a pointer to `model`, which must outlive this object. Throws what EnergyModel throws.
  explicit SceneSystem(const Model& model);

  int dofs() const override { return energy_.dofs(); }
  const Eigen::VectorXd& mass() const override { return energy_.mass(); }
  void force(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
             Eigen::VectorXd& f) const override;
  const SparsityPattern& pattern() const override { return energy_.hessian_pattern(); }
  void stiffness(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
                 std::vector<double>& values) const override;
  void damping(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
               std::vector<double>& values) const override;
  bool has_damping() const override { return energy_.has_damping(); }
  double potential(double t, const Eigen::VectorXd& q) const override;

  // q and u (dofs) from a state's positions and velocities.
  void gather(const State& s, Eigen::VectorXd& q, Eigen::VectorXd& u) const;
  // Writes all positions and velocities of s from (q, u) at time t (kinematic particles on their
  // targets) and the multipliers of the compliant constraints, -C/alpha (EnergyModel::
  // constraint_forces; s.lambda is sized to the constraint count first). The other entries of
  // s.lambda, s.time and s.step are left as they are.
  void scatter(const Eigen::VectorXd& q, const Eigen::VectorXd& u, double t, State& s) const;

  const EnergyModel& energy() const { return energy_; }

 private:
  EnergyModel energy_;
  mutable Points x_;             // (n x 3) m, scratch: all positions
  mutable Points v_;             // (n x 3) m/s, scratch: all velocities
  mutable Eigen::VectorXd fd_;   // (dofs) N, scratch: damping force
};

}  // namespace pbdbench
