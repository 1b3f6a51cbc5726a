// The stop reasons of a step (solver_api/solver.hpp): their names, docs and whether a step that
// stopped so is trusted, declared once; the run file stores the value, `pbdbench summary` counts
// the names, the runner's health warns of the untrusted ones.
#include <stdexcept>

#include "solver_api/solver.hpp"

namespace pbdbench {

const std::vector<StopReasonInfo>& stop_reasons() {
  static const std::vector<StopReasonInfo> table = {
      {StopReason::None, "none", "no step (the initial row)", true},
      {StopReason::FixedWork, "fixed_work",
       "the fixed work ran out: solver.iterations sweeps per substep (pbd-seed, pbd, xpbd) or the "
       "explicit step (force-symplectic); no convergence test",
       true},
      {StopReason::Converged, "converged",
       "converged: the tolerance was met (ref-*: every error test and Newton solve; global-*: the "
       "KKT residual below solver.global.tolerance)",
       true},
      {StopReason::IterationLimit, "iteration_limit",
       "the iteration limit was spent above the tolerance (global-*: solver.global.max_iterations)",
       false},
      {StopReason::Stalled, "stalled",
       "no progress above the tolerance (global-ceres: rounds that stopped lowering the residual, "
       "or the trust region's gradient or step-size test)",
       false},
      {StopReason::LineSearchFailed, "line_search_failed",
       "the line search found no decrease (global-*: 40 halvings; ref-be with contact: the "
       "barrier energy at its round-off floor above the Newton tolerance)",
       false},
      {StopReason::LinearSolverFailed, "linear_solver_failed",
       "the Newton system could not be solved (factorisation not positive definite, "
       "conjugate-gradient breakdown, non-finite step)",
       false},
  };
  return table;
}

const StopReasonInfo& stop_reason_info(StopReason reason) {
  const auto i = static_cast<size_t>(reason);
  if (i >= stop_reasons().size()) throw std::out_of_range("unknown stop reason");
  return stop_reasons()[i];
}

}  // namespace pbdbench
