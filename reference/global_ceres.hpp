// The global step (reference/global_problem.hpp) solved as a nonlinear least-squares problem by
// Ceres (global-ceres): the solver the other two are checked against, built independently of
// their Newton matrices (its Jacobians come from the constraint functions themselves).
//
// Residual blocks, each with an analytic Jacobian:
//   sqrt(m_i) (x_i - x~_i)                     one per dynamic particle (3 residuals)
//   C_j(x) / sqrt(alpha~_j)                    one per compliant constraint (GlobalProblem::
//                                              eval_compliant: bending smooth at flat, the
//                                              FEM-kind pair of each element)
//   sqrt(h beta_j) grad C_j(x_n) . (x - x_n)   one per damped constraint
// so that half the sum of squares is E(x). Rigid rows and contacts: an augmented Lagrangian, the
// same as global_newton.hpp's (penalty 1/eps_r, eps_r = eta w_r), written as residuals:
//   rigid:   sqrt(1/eps_r) (C_r(x) - eps_r lambda_r)
//   contact: sqrt(1/eps_k) min(C_k(x) - eps_k lambda_k, 0)
// whose half squares are L_A's row terms up to constants. Each round minimises L_A for fixed
// multipliers with Levenberg-Marquardt or dogleg (solver.global.ceres_method), the linear solver
// SPARSE_NORMAL_CHOLESKY on SuiteSparse, and then updates lambda_r <- lambda_r - C_r / eps_r
// (contacts: max(0, .)), until Residuals::position <= solver.global.tolerance. Without rows it is
// a single round.
#pragma once

#include <vector>

#include "reference/global_problem.hpp"
#include "solver_api/options.hpp"

namespace pbdbench {

// Solves the problem's current step from x (every particle; dynamic ones the starting guess) and
// row_lambda (rows().size() multipliers, kg m). On return x and row_lambda hold the last iterate.
// The history has the starting point and an entry after every Levenberg-Marquardt (or dogleg)
// iteration, its inner_iterations counting them across rounds.
GlobalResult solve_global_ceres(const GlobalProblem& problem, const SolverOptions& options,
                                Points& x, std::vector<double>& row_lambda);

}  // namespace pbdbench
