// The core of ref-dae: a MechanicalSystem (reference/mechanical_system.hpp) with rigid distance
// constraints, integrated by IDA in the stabilised index-2 form of Gear, Gupta and Leimkuhler
// (1985, "Automatic integration of Euler-Lagrange equations with constraints"):
//
//   q' = u + M^-1 G^T mu                        (n)  the position update, mu keeps q on C = 0
//   M u' = f(t, q, u) + G^T lambda              (n)  Newton's law with the constraint forces
//   0 = G(q, t) u + dC/dt(q, t)                 (m)  velocity-level constraint
//   0 = C(q, t)                                 (m)  position-level constraint
//
// with C_j = |x_b - x_a| - rest_j (m) for each rigid distance constraint j and G = dC/dq. An end
// of a constraint is either a dof block of the system (a dynamic particle: dofs 3k .. 3k+2) or
// a prescribed point (a kinematic or pinned particle) whose position, velocity and acceleration
// at time t come from a callback; dC/dt is the part of the constraint's rate that comes from the
// prescribed ends. The multiplier lambda_j is a force per unit of C (N for a distance
// constraint): the force of constraint j on the dofs is G_j^T lambda_j. mu is zero along the exact
// solution (it is the Lagrange multiplier of the position-level stabilisation, kg m/s).
//
// Unknowns for IDA: y = (q, u, lambda, mu), (2n + 2m). lambda and mu are algebraic: excluded from
// the local error test (IDASetSuppressAlg); in the Newton convergence test their weights are
// scaled by the step h, as index-2 variables' (dae_system.cpp, dae_weights). The Jacobian
// dF/dy + cj dF/dy' is assembled analytically in a fixed sparse pattern (including the Hessian
// terms of C times lambda, mu and u) and factorised by KLU. The lambda reported at an output is
// recomputed there from the acceleration-level constraint (read_output in dae_system.cpp).
//
// Setup (constraint checks, sparsity pattern, IDA memory) happens in the constructor, start()
// sets an initial state and advance() integrates; the three are separate calls so that the same
// object integrates many output steps without losing IDA's history.
#pragma once

#include <array>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/types.hpp"
#include "reference/mechanical_system.hpp"

namespace pbdbench {

// Position (m), velocity (m/s) and acceleration (m/s^2) of a prescribed point at some time.
struct PrescribedPoint {
  Vec3 x = Vec3::Zero();
  Vec3 v = Vec3::Zero();
  Vec3 a = Vec3::Zero();  // used only for the initial multipliers (start())
};

// The prescribed point with index `point` (as in RigidDistance::point) at time t.
using PrescribedMotion = std::function<PrescribedPoint(int point, double t)>;

// A rigid distance constraint C = |x_b - x_a| - rest, end 0 = a, end 1 = b.
struct RigidDistance {
  std::array<int, 2> block{-1, -1};  // dof block of each end (dofs 3 block .. 3 block + 2), or -1
                                     // when that end is prescribed
  std::array<int, 2> point{-1, -1};  // the PrescribedMotion index of a prescribed end
  double rest = 0.0;                 // m, > 0
  std::string name;                  // names the constraint in messages, e.g.
                                     // "constraint 3 (distance, particles 2 3)"
};

struct DaeSettings {
  double rtol = 1e-8;         // relative tolerance (IDA), > 0
  double atol = 1e-10;        // absolute tolerance of q (m) and u (m/s), > 0. lambda and mu
                              // get atol times the largest dof mass over the step h (their
                              // units are N and kg m/s); they only enter the Newton
                              // convergence test
  long max_steps = 1000000;   // internal steps per advance(), >= 1
  int max_newton = 4;         // Newton iterations per step attempt (IDA's maxcor), >= 1
};

// Counters since construction (cumulative over restarts).
struct DaeCounters {
  long steps = 0;                 // internal IDA steps
  long newton_iterations = 0;
  long linear_setups = 0;         // Jacobian evaluations and KLU factorisations
  long linear_solves = 0;         // KLU solves
  long error_test_failures = 0;
  long convergence_failures = 0;  // failed Newton solves
  double time_linear = 0.0;       // s, wall clock in Jacobian assembly, factorisation and solves
};

class DaeIntegrator {
 public:
  // Keeps a reference to `system` (and copies the constraints and the callback). Throws
  // std::invalid_argument naming the constraint when one has no dof end, an out-of-range block,
  // a prescribed end without a point, or rest <= 0; or naming the setting when settings are out
  // of range. `prescribed` may be empty when no constraint has a prescribed end.
  DaeIntegrator(const MechanicalSystem& system, std::vector<RigidDistance> constraints,
                PrescribedMotion prescribed, DaeSettings settings);
  ~DaeIntegrator();
  DaeIntegrator(const DaeIntegrator&) = delete;
  DaeIntegrator& operator=(const DaeIntegrator&) = delete;

  // How far initial positions may be off the constraints: |C_j| <= kStartSlack (atol + rtol
  // rest_j). An output of this integrator is off by up to a few (atol + rtol |q|) (IDA's error
  // test bounds a weighted RMS norm, and outputs between steps are interpolated), so a state it
  // wrote is accepted back; anything further off is refused, not projected.
  static constexpr double kStartSlack = 10.0;

  // (Re)starts the integration at t0 from positions q0 (n, m) and velocities u0 (n, m/s).
  // Throws std::invalid_argument naming the constraint with the largest |C| when some |C_j|
  // exceeds the slack above, and when the rigid constraints are redundant (G M^-1 G^T
  // singular). Velocities that violate the velocity-level constraint are projected onto it,
  // M-orthogonally (the impulse a rigid constraint applies):
  // u0 - M^-1 G^T (G M^-1 G^T)^-1 (G u0 + dC/dt). lambda comes from the acceleration-level
  // constraint, mu = 0, q' = u, u' = M^-1 (f + G^T lambda): a consistent initial point.
  void start(double t0, const Eigen::VectorXd& q0, const Eigen::VectorXd& u0);
  bool started() const;

  // Integrates to tout > time() (IDASolve, IDA_NORMAL: IDA steps past tout as it likes and
  // interpolates the output there) without stepping past stop_time >= tout (IDASetStopTime;
  // +inf: no limit), so that a kink of a prescribed motion at stop_time is never inside a step.
  // Throws std::runtime_error with IDA's flag and message on failure, std::invalid_argument when
  // tout <= time(), stop_time < tout, or start() has not been called.
  void advance(double tout, double stop_time = std::numeric_limits<double>::infinity());

  double time() const;                   // s, the last output time
  const Eigen::VectorXd& q() const;      // (n) m, at time()
  const Eigen::VectorXd& u() const;      // (n) m/s
  const Eigen::VectorXd& lambda() const; // (m) N, force per unit of C, in constraint order, from
                                         // the acceleration-level constraint at (q(), u())
  const Eigen::VectorXd& mu() const;     // (m) kg m/s, zero along the exact solution
  // max_j |C_j(q(), time())| (m), 0 without constraints.
  double drift() const;
  // C_j(q, t) for every constraint (m).
  Eigen::VectorXd constraint_values(double t, const Eigen::VectorXd& q) const;

  DaeCounters counters() const;
  int dofs() const;
  int constraint_count() const;

  // What IDA sees, for the finite-difference tests: the residual F(t, y, y') (N) and the
  // iteration matrix dF/dy + cj dF/dy' (N x N, as a dense copy), y = (q, u, lambda, mu),
  // N = 2 dofs() + 2 constraint_count(). The first throws std::runtime_error where F is
  // undefined (a constraint of zero length, forces not finite).
  Eigen::VectorXd residual(double t, const Eigen::VectorXd& y, const Eigen::VectorXd& yp);
  Eigen::MatrixXd iteration_matrix(double t, double cj, const Eigen::VectorXd& y);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace pbdbench
