// ref-bdf's integrator: CVODE's variable-order, variable-step BDF method (orders 1 to
// max_order) on the first-order form of a MechanicalSystem (reference/first_order_system.hpp),
// Newton iterations on the analytic sparse Jacobian, solved through the n x n reduced matrix
// M + gamma D + gamma^2 K (reference/reduced_linear_solver.hpp) or with KLU on the whole 2n x 2n
// matrix. docs/reference.md, "ref-bdf".
//
//   BdfIntegrator bdf(system, settings);
//   bdf.reset(t0, q, u);               // CVodeInit / CVodeReInit
//   bdf.advance(t0 + dt, q, u);        // CVode(..., t0 + dt, CV_NORMAL): output interpolated
//
// Breakpoints: times where f(t, q, u) is not smooth in t (a scripted motion starting or
// stopping: the kinematic particle's velocity jumps there, so f has a kink, or a jump when a
// damped constraint sees that velocity). The integrator never steps across one: CVodeSetStopTime
// holds each internal step at or before the next breakpoint, and at the breakpoint the method
// restarts (CVodeReInit, order 1), so that no BDF history spans the kink.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>

#include "reference/mechanical_system.hpp"
#include "reference/reduced_linear_solver.hpp"
#include "reference/sundials_support.hpp"

namespace pbdbench {

struct BdfSettings {
  double rtol = 1e-8;        // relative tolerance (CVodeSVtolerances), > 0
  double atol = 1e-10;       // absolute tolerance of the positions q, m, > 0
  long max_steps = 1000000;  // internal steps per call to CVode (CVodeSetMaxNumSteps), >= 1
  int max_order = 5;         // highest BDF order (CVodeSetMaxOrd), 1 to 5
  double atol_velocity = 0.0;  // absolute tolerance of the velocities u, m/s, >= 0; 0: atol
                               // (one scalar for both, as with CVodeSStolerances)
  LinearSolverKind linear_solver = LinearSolverKind::Reduced;  // the Newton systems' solver
};

class BdfIntegrator {
 public:
  // Keeps a reference to `system` (which must outlive it). `breakpoints`: see above, any order.
  // Throws std::invalid_argument for settings out of range.
  BdfIntegrator(const MechanicalSystem& system, const BdfSettings& settings,
                std::vector<double> breakpoints = {});
  ~BdfIntegrator();
  BdfIntegrator(const BdfIntegrator&) = delete;
  BdfIntegrator& operator=(const BdfIntegrator&) = delete;

  // (Re)starts the integration at (t, q, u): the first step is order 1 with CVODE's estimated
  // initial step.
  void reset(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u);
  // Integrates from time() to t_out > time() and writes q, u at t_out (interpolated from the
  // internal steps, which may end past t_out but never past the next breakpoint). Throws
  // std::runtime_error naming the CVODE flag when CVODE fails; the integrator then needs a
  // reset().
  void advance(double t_out, Eigen::VectorXd& q, Eigen::VectorXd& u);

  bool started() const;  // reset() was called and no failure since
  double time() const;   // time of the last output (or of the reset)
  // Cumulative since construction (across resets).
  sun::Counters counters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pbdbench
