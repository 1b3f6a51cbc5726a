// The global step (reference/global_problem.hpp) solved by Newton's method on an augmented
// Lagrangian: global-cholmod (sparse Cholesky, CHOLMOD) and global-cg (conjugate gradients,
// assembled with an incomplete-Cholesky or Jacobi preconditioner, or matrix-free).
//
// The rigid rows and the contacts enter through the augmented Lagrangian (the method of
// multipliers; Nocedal and Wright 2006, sec. 17.3 and 17.4 for the inequalities) with the
// penalty 1/eps_r, eps_r = eta w_r (eta = solver.global.regularization, w_r the row's generalised
// inverse mass at the start of the solve, so that the penalty is eta^-1 times the row's own
// stiffness against the masses):
//   L_A(x; lambda) = E(x) + sum_rigid (-lambda_r C_r + C_r^2 / (2 eps_r))
//                         + sum_contacts psi(C_k, lambda_k),
//   psi(C, l) = -l C + C^2 / (2 eps) when C < eps l (the contact pushes), else -eps l^2 / 2.
// Each iteration takes one Newton step on L_A for the current lambda,
//   (hess E + sum_r [grad C_r grad C_r^T / eps_r - l_r hess C_r]_+) dx = -grad L_A,
// over the rows that push (every rigid row; a contact while C_k < eps_k lambda_k), with
// l_r = lambda_r - C_r / eps_r and [.]_+ the projection of each row's block onto the positive
// semi-definite cone, a backtracking line search on L_A (Armijo, halving), and then the
// multiplier update lambda_r <- lambda_r - C_r(x) / eps_r (contacts: max(0, .)) once the Newton
// steps have brought the stationarity part of the residual below the tolerance. The residual of
// an iterate is measured with those updated multipliers; the iteration stops when
// Residuals::position <= solver.global.tolerance. With the default eta = 1e-4 a rigid row's
// violation after the first round is ~1e-4 of what the masses alone would leave, and one or two
// rounds reach the tolerance. A smaller eta makes the penalty stiffer and the Newton steps across
// a pile of contacts much shorter (balls_in_bowl, 0.2 s, steps of 4 substeps: 74 Newton steps a
// step at eta = 1e-4; 217, with 7 of 12 steps unconverged, at 1e-6; 92 at 1e-2, where more
// rounds are needed).
//
// The Newton matrix keeps the sparsity of the scene's energy plus the rows' stencils. CHOLMOD's
// symbolic analysis is redone only when that pattern changes (contacts come and go); a matrix
// that is not positive definite after the projections (it cannot be, up to rounding) is shifted
// by 1e-12 times its largest diagonal entry and factorised again.
//
// The factorisation is reused (solver.global.factor_reuse, on by default): a Newton system is
// solved by conjugate gradients preconditioned with the last factorisation, to a relative
// residual of solver.global.reuse_tolerance (1e-14), and factorised only when that is slow (more
// than solver.global.reuse_iterations = 6 iterations: the next system is factorised; no
// convergence at 4 times that: this one is), and only on a pattern where a factorisation costs at
// least two such iterations in flops (CHOLMOD's analysis; not on balls_in_bowl or hanging_chain,
// where it costs less than one). Consecutive Newton matrices are close and on a large pattern a
// factorisation costs tens of such iterations, so most systems take a few iterations and no
// factorisation. The Newton iterates are those of a direct solve to that tolerance: on the
// 64 x 64 cloth, the cantilever beam, cantilever_fem and soft_cube_drop the same Newton
// iterations, positions within 4e-14 m (against solver.global.factor_reuse = false). At 1e-12 a pile of contacts
// (balls_in_bowl, chaotic) left the direct solve's path within 3 steps and hit the iteration
// limit once. cholesky_factorizations and linear_iterations count both kinds of solve.

#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "reference/global_problem.hpp"
#include "solver_api/options.hpp"

namespace pbdbench {

enum class GlobalLinearSolver : std::uint8_t {
  Cholmod,            // sparse Cholesky (CHOLMOD, supernodal), symbolic analysis reused
  ConjugateGradient,  // preconditioned CG (options: preconditioner, matrix-free, tolerance)
};

class GlobalNewton {
 public:
  GlobalNewton(const SolverOptions& options, GlobalLinearSolver linear_solver);
  ~GlobalNewton();
  GlobalNewton(const GlobalNewton&) = delete;
  GlobalNewton& operator=(const GlobalNewton&) = delete;

  // Solves the problem's current step from x (every particle; the dynamic ones are the starting
  // guess, usually x~) and row_lambda (rows().size() multipliers, kg m, a warm start or zeros).
  // On return x and row_lambda hold the last iterate, converged or not (GlobalResult says).
  GlobalResult solve(const GlobalProblem& problem, Points& x, std::vector<double>& row_lambda);

  // The next solve factorises its first Newton system instead of preconditioning with the last
  // factorisation (the symbolic analysis is kept): a solve repeated from the same start then
  // takes the same path, bit for bit (pbdbench converge records global-cholmod so).
  void forget_factorisation();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pbdbench
