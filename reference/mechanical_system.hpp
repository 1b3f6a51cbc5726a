// What an integrator integrates: a second-order system over n degrees of freedom
//
//   M q'' = f(t, q, u),   u = q',   M diagonal (mass per dof)
//
// with the Jacobians of the force in a fixed sparse pattern. The integrators (ref_*.cpp) see only
// this; reference/scene_system.hpp adapts a Model (through EnergyModel) to it, and tests can hand
// them any small system with a known solution.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "reference/energy.hpp"

namespace pbdbench {

class MechanicalSystem {
 public:
  virtual ~MechanicalSystem() = default;

  virtual int dofs() const = 0;
  virtual const Eigen::VectorXd& mass() const = 0;  // (n) kg per dof, > 0

  // f(t, q, u) (N per dof).
  virtual void force(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
                     Eigen::VectorXd& f) const = 0;

  // The pattern of both Jacobians below (symmetric, whole, with every diagonal entry).
  virtual const SparsityPattern& pattern() const = 0;
  // K = -df/dq and D = -df/du at (t, q, u), values in pattern() order. K may be approximate in
  // the terms that come from damping (the converged solution does not depend on it); it is exact
  // otherwise.
  virtual void stiffness(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
                         std::vector<double>& values) const = 0;
  virtual void damping(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u,
                       std::vector<double>& values) const = 0;
  virtual bool has_damping() const = 0;

  // The potential energy U(t, q) whose negative gradient is the conservative part of f (J), for
  // the static solve's line search and for energy checks.
  virtual double potential(double t, const Eigen::VectorXd& q) const = 0;
};

}  // namespace pbdbench
