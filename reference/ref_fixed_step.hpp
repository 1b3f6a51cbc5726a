// The fixed-step implicit integrators of ref-be and ref-sdirk2: ARKODE's ARKStep, fully implicit
// (a diagonally implicit Runge-Kutta table), a fixed step h, Newton iterations on the analytic
// sparse Jacobian of the first-order system (reference/first_order_system.hpp), solved through
// the reduced matrix (reference/reduced_linear_solver.hpp) or with KLU on the whole system.
// docs/reference.md, "ref-be" and "ref-sdirk2".
//
//   BackwardEuler  the one-stage table A = [[1]], b = [1], c = [1] (a user Butcher table):
//                  y_{n+1} = y_n + h F(t_{n+1}, y_{n+1}), which for M q'' = f is
//                  q_{n+1} = q_n + h u_{n+1},  u_{n+1} = u_n + h M^-1 f(t_{n+1}, q_{n+1}, u_{n+1}):
//                  what converged XPBD is (Macklin et al. 2016).
//   Sdirk2         ARKODE_SDIRK_2_1_2: two stages, order 2 (its embedded order-1 solution is not
//                  used with a fixed step).
//
// Each stage is solved by sun::FullNewton (reference/sundials_support.hpp) instead of ARKODE's
// own Newton solver: the Jacobian is re-evaluated where the iteration is slow or had to be damped,
// and a line search keeps it from overshooting: on the stage's incremental potential when the
// system has no damping (StageMerit in ref_fixed_step.cpp), else on the residual norm. ARKODE's solver keeps the
// Jacobian of the predicted state: on a cloth released flat it needs 8 times more iterations
// (tests/reference/test_ref_fixed_step.cpp), and with a step that cannot be shortened it has
// no way out where that Jacobian is too far from the solution's.
//
// There is no error test with a fixed step: the tolerances only say when each stage's Newton
// iteration stops, which is when ARKODE's estimate of the remaining iteration error is at most
// nonlinear_coefficient in the weighted RMS norm with weights 1 / (rtol |y_i| + atol_i), where
// atol_i = atol for the positions and atol / h for the velocities (ARKStepSVtolerances): a
// velocity error of atol / h moves the next positions by atol. (With atol itself on the
// velocities, a stiff link's force round-off, h eps |x| / (alpha m) in velocity, already exceeds
// it: the catalog chain, alpha = 1e-8, could not converge.) A stage whose Newton iteration does
// not converge (max_newton iterations, or no decrease of the residual with a fresh Jacobian)
// cannot be retried with a smaller step: ARKODE returns ARK_CONV_FAILURE and advance() throws.
#pragma once

#include <memory>

#include <Eigen/Core>

#include "reference/mechanical_system.hpp"
#include "reference/reduced_linear_solver.hpp"
#include "reference/sundials_support.hpp"

namespace pbdbench {

enum class FixedStepMethod { BackwardEuler, Sdirk2 };

struct FixedStepSettings {
  FixedStepMethod method = FixedStepMethod::BackwardEuler;
  double rtol = 1e-8;                  // relative tolerance of the Newton iterations, > 0
  double atol = 1e-10;                 // absolute tolerance, m and m/s, > 0
  int max_newton = 50;                 // Newton iterations per stage (ARKStepSetMaxNonlinIters)
  double nonlinear_coefficient = 0.1;  // ARKStepSetNonlinConvCoef, in (0, 1]
  bool package_newton = false;         // ARKODE's own Newton solver instead of sun::FullNewton
                                       // (for comparison; it fails where the latter does not)
  LinearSolverKind linear_solver = LinearSolverKind::Reduced;  // the Newton systems' solver
};

class FixedStepIntegrator {
 public:
  // Keeps a reference to `system`, which must outlive it. Throws std::invalid_argument for
  // settings out of range.
  FixedStepIntegrator(const MechanicalSystem& system, const FixedStepSettings& settings);
  ~FixedStepIntegrator();
  FixedStepIntegrator(const FixedStepIntegrator&) = delete;
  FixedStepIntegrator& operator=(const FixedStepIntegrator&) = delete;

  // (Re)starts at (t, q, u) (ARKStepCreate, then ARKStepReset).
  void reset(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u);
  // Takes exactly `steps` steps of h (ARKStepEvolve in ARK_ONE_STEP mode: no interpolation) and
  // writes q, u at the end, time() + steps h. Throws std::runtime_error naming the ARKODE flag
  // on failure; the integrator then needs a reset().
  void advance(int steps, double h, Eigen::VectorXd& q, Eigen::VectorXd& u);

  bool started() const;
  double time() const;  // ARKODE's time after the last step (t of the reset plus the steps)
  sun::Counters counters() const;  // cumulative since construction

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pbdbench
