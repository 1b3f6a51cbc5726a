// ref-static's solver: the static equilibrium f(t, q, 0) = 0 of a MechanicalSystem, by KINSOL's
// Newton method with a line search on the analytic stiffness K = -df/dq (KLU).
// docs/reference.md, "ref-static".
//
// KINSOL solves F(q) = -f(t, q, 0) = 0 (F = dU/dq when the force is conservative), with
//   - the Jacobian K evaluated at every iteration (KINSetMaxSetupCalls 1: exact Newton); with a
//     direct linear solver KINSOL's line search takes the slope of |F|^2 along the step from
//     K p = -F, which holds to round-off;
//   - the step test as the main stopping criterion: the last Newton step moved every dof by at
//     most rtol |q_i| + atol (KINSOL's scaled step test with uscale = rtol / atol, scsteptol =
//     rtol). Exact Newton converges quadratically, so the error after that step is far smaller.
//   - a force test that ends the iteration early once every |F_i| is at most 1e-2 times the
//     force k_i (rtol |q0_i| + atol) that a displacement of one tolerance produces through the
//     diagonal stiffness k_i = max(K_ii(q0), 1e-8 max_j K_jj(q0)) (fscale = 1 / that force,
//     fnormtol = 1e-2; the factor leaves room for K^-1 spreading a force over many dofs, as
//     along a chain). KINSOL takes a start within 1e-2 of that (1e-4 of the force) as solved;
//   - at most max_newton iterations.
// KINSOL's line search fails once |F| sits at its round-off floor before the force test passed
// (the full step no longer lowers |F|^2 and any shorter one is below the step tolerance); the
// last iterate is then accepted when one more exact Newton step from it is within tolerance,
// and that step is taken.
//
// When that fails (K singular, as for a flat membrane under a load across it, or indefinite far
// from equilibrium, where Newton's direction need not lead anywhere useful), a fallback runs
// from the same start: a projected Newton descent on the potential U (potential()), with the
// steps (K+ + mu M) p = -F, K+ the PSD-projected stiffness when one is given (else K), mu >= 0
// a Levenberg shift raised tenfold whenever the factorisation fails, p is not a descent
// direction, or the Armijo backtracking on U needs more than a few halvings, and lowered tenfold
// after every full step (to 0 below 1e-12 of the scale max K_ii / m_i; it starts at 1e-6 of it).
// It stops once a step with a negligible shift (mu <= 1e-6 of the scale) is within tolerance;
// KINSOL then polishes (and certifies) the result from there. If KINSOL still fails, solve() throws std::runtime_error
// naming the flag of each attempt. The fallback assumes f(t, q, 0) = -dU/dq: no damping force
// from moving kinematic particles at the static solve's time.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "reference/mechanical_system.hpp"
#include "reference/sundials_support.hpp"

namespace pbdbench {

struct StaticSettings {
  double rtol = 1e-8;       // relative tolerance on q, > 0
  double atol = 1e-10;      // absolute tolerance on q, m, > 0
  int max_newton = 50;      // iterations per attempt (KINSetNumMaxIters), >= 1
  bool line_search = true;  // KIN_LINESEARCH; false: KIN_NONE, full Newton steps
  bool fallback = true;     // run the projected-Newton fallback when KINSOL fails
};

// PSD-projected stiffness values at (t, q) in the system's pattern order.
using ProjectedStiffness =
    std::function<void(double t, const Eigen::VectorXd& q, std::vector<double>& values)>;

class StaticSolver {
 public:
  // Keeps a reference to `system`, which must outlive it. `projected` may be empty.
  StaticSolver(const MechanicalSystem& system, const StaticSettings& settings,
               ProjectedStiffness projected = {});
  ~StaticSolver();
  StaticSolver(const StaticSolver&) = delete;
  StaticSolver& operator=(const StaticSolver&) = delete;

  // Solves f(t, q, 0) = 0 for q, starting from q. Throws std::runtime_error when it cannot.
  void solve(double t, Eigen::VectorXd& q);

  // Cumulative since construction. steps counts solves; convergence_failures counts KINSOL
  // attempts that failed (each followed by the fallback).
  sun::Counters counters() const;
  // Of the last solve: KINSOL's return flag (KIN_SUCCESS, KIN_INITIAL_GUESS_OK or
  // KIN_STEP_LT_STPTOL) and whether the fallback ran.
  int last_flag() const;
  bool last_used_fallback() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pbdbench
