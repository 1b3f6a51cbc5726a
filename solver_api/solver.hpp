// The one interface every solver implements, the PBD family (solvers/) and the reference and
// global solvers (reference/) alike: the runner, the metrics and the run-file writer never ask
// which family they hold. The catalogue that names and builds them: catalog/solver_catalog.hpp.
//
//   auto solver = make_solver(options, model);      // precomputation (colourings, ...)
//   StepReport r = solver->step(model, state, dt);  // advance state by dt
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"
#include "solver_api/options.hpp"

namespace pbdbench {

// Why a step's solve stopped, in each family's terms; the worst of its substeps and solves (the
// larger value). A reason is trusted when the step did what the solver promises (its fixed work,
// or convergence to its tolerance); the others mark a step whose result is not what the solver
// claims: the run's warnings count them (metrics/health.hpp, solver_stop).
enum class StopReason : std::uint8_t {
  None = 0,            // no step taken (the run file's initial row)
  FixedWork = 1,       // pbd-seed, pbd, xpbd: the fixed sweeps (solver.iterations per substep)
                       // ran out; force-symplectic: its explicit step. No convergence test.
  Converged = 2,       // ref-*: every internal step passed its error test and every Newton solve
                       // converged (a failure of either stops the run); global-*: the KKT
                       // residual fell below solver.global.tolerance
  IterationLimit = 3,  // global-*: solver.global.max_iterations spent above the tolerance
  Stalled = 4,         // global-ceres: the rounds stopped lowering the residual, or the trust
                       // region's own tests (gradient, step size) ended above the tolerance
  LineSearchFailed = 5,    // global-*: no decrease of the merit function in 40 halvings of the
                           // Newton step; ref-be with contact: the barrier energy at its
                           // round-off floor above the Newton tolerance (60 halvings)
  LinearSolverFailed = 6,  // global-*: the Newton system's factorisation or conjugate-gradient
                           // solve failed (not positive definite, breakdown, non-finite step)
};
inline constexpr int kStopReasonCount = 7;

struct StopReasonInfo {
  StopReason reason = StopReason::None;
  const char* name = "";  // "fixed_work", "converged", "iteration_limit", ...
  const char* doc = "";   // one line
  bool trusted = true;    // false: the step's result is not what the solver claims
};
// Every reason, by value (index = the value stored in the run file's stop_reason series).
const std::vector<StopReasonInfo>& stop_reasons();
const StopReasonInfo& stop_reason_info(StopReason reason);

// What one step did. Every field is logged as a series of the run file (runfile/series.hpp).
struct StepReport {
  int substeps = 0;           // substeps taken in this step
  int iterations = 0;         // projection sweeps summed over substeps
  int contacts = 0;           // contact constraints built (summed over substeps)
  int active_contacts = 0;    // of those, the ones with C < 0 at some projection (summed)
  int skipped = 0;            // projections skipped because the gradient was undefined or the
                              // generalised mass was zero (summed over sweeps and substeps)
  StopReason stop = StopReason::None;  // why the step's solve stopped: the worst of its
                              // substeps (note_stop)
  // XPBD residuals at the end of the step's last substep (Macklin et al. 2016, eqs. 8 and 9);
  // NaN for solvers that do not define them.
  double residual_g = std::numeric_limits<double>::quiet_NaN();  // |M (x - x~) - grad C^T lambda|_2, kg m
  double residual_h = std::numeric_limits<double>::quiet_NaN();  // |C(x) + alpha~ lambda|_2, units of C
  // Reference integrators (reference/): their own account of the step; 0 (NaN for the drift)
  // for the PBD family.
  long ref_steps = 0;             // internal integrator steps taken to advance by dt
  long newton_iterations = 0;     // nonlinear (Newton) iterations
  long linear_setups = 0;         // Jacobian evaluations and factorisations
  long linear_solves = 0;         // linear solves with a factorisation
  long error_test_failures = 0;   // steps rejected by the local error test
  long convergence_failures = 0;  // nonlinear solves that failed to converge
  long cholesky_factorizations = 0;  // of the setups: Cholesky factorisations (reduced systems)
  long lu_factorizations = 0;        // of the setups: LU factorisations where Cholesky failed or
                                     // the matrix was not symmetric (reduced systems)
  double factor_cost_ratio = std::numeric_limits<double>::quiet_NaN();  // global-cholmod: the
                                  // flops of a factorisation over those of one CG iteration
                                  // preconditioned with it, CHOLMOD's analysis; the factorisation
                                  // is reused across Newton iterations where it is >= 2
  long linear_iterations = 0;     // global solvers: conjugate-gradient iterations (global-cg,
                                  // and global-cholmod's solves preconditioned with an earlier
                                  // factorisation), Levenberg-Marquardt iterations (global-ceres)
  double residual_position = std::numeric_limits<double>::quiet_NaN();  // global solvers: the
                                  // KKT residual of the last substep in position units, m
                                  // (reference/global_problem.hpp)
  double constraint_drift = std::numeric_limits<double>::quiet_NaN();  // max |C| of the rigid
                                  // constraints at the end of the step (ref-dae), units of C
  long line_search_cuts = 0;      // ref-be with contact: halvings of the Newton step in its line
                                  // search (after the collision check's bound), summed
  double barrier_energy = std::numeric_limits<double>::quiet_NaN();  // ref-be with contact: the
                                  // barrier potential kappa sum b(d) at the end of the step, J
  // Wall-clock time per phase, summed over substeps, in seconds.
  double time_predict = 0.0;   // prediction (external forces), kinematic targets
  double time_contacts = 0.0;  // contact generation
  double time_project = 0.0;   // constraint projection sweeps
  double time_residual = 0.0;  // xpbd: the residuals g and h (solver.xpbd.residuals)
  double time_velocity = 0.0;  // velocity update, damping, friction and restitution
  double time_linear = 0.0;    // reference integrators: Jacobian assembly, factorisation, solves
};

// Records one substep's (or solve's) stop reason: the report keeps the worst.
inline void note_stop(StepReport& report, StopReason reason) {
  if (reason > report.stop) report.stop = reason;
}

class Solver {
 public:
  virtual ~Solver() = default;
  // Advances `state` by dt seconds. Never changes the model. dt > 0.
  virtual StepReport step(const Model& model, State& state, double dt) = 0;
  // The registered name: "pbd-seed", "pbd", "xpbd", "ref-bdf", ...
  virtual std::string name() const = 0;
  // The most threads a step runs on (the run's logging takes a thread of its own only when the
  // run has a core beyond these: harness/step_logger.hpp).
  virtual int threads() const { return 1; }
};

}  // namespace pbdbench
