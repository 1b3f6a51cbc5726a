// The Newton systems of the ODE integrators (ref-bdf, ref-be, ref-sdirk2) on the first-order
// form y = [q; u] (reference/first_order_system.hpp), solved through the n x n Schur complement
// of their velocity block instead of the whole 2n x 2n matrix. docs/reference.md, "Linear
// solvers".
//
// The integrators hand their linear solver A = I - gamma J with J = [[0, I], [-M^-1 K, -M^-1 D]]:
//
//   A = [[ I,                -gamma I           ],      A x = b,  x = [x1; x2],  b = [b1; b2]
//        [ gamma M^-1 K,      I + gamma M^-1 D  ]]
//
//   first block row:               x1 = b1 + gamma x2
//   second block row times M, x1 substituted:
//       gamma K (b1 + gamma x2) + (M + gamma D) x2 = M b2
//       (M + gamma D + gamma^2 K) x2 = M b2 - gamma K b1 = M (b2 - G b1),   G = gamma M^-1 K
//
// so a setup factorises S = M + gamma D + gamma^2 K (n x n, symmetric, on
// MechanicalSystem::pattern()) and a solve is one sparse product G b1, one solve with S and one
// vector update. S is positive definite when K and D are positive semi-definite; compressed
// springs or buckling make K indefinite, and S with it once gamma^2 |lambda_min(K)| > m: then
// SparseFactor falls back from Cholesky (CHOLMOD) to LU (KLU); which one ran is counted.
//
// Where gamma, K and D come from: the matrix itself. The packages assemble A from their saved J
// (SUNMatCopy, then SUNMatScaleAddI(-gamma, A)) and pass it to SUNLinSolSetup, so the blocks of
// A give, exactly as the package formed them:
//   gamma     = -A(j, n + j)                       (the same for every j; checked)
//   G_ij      =  A(n + i, j)                        = gamma K_ij / m_i
//   H_ij      =  A(n + i, n + j)                    = delta_ij + gamma D_ij / m_i
//   S_ij      =  m_i (H_ij + gamma G_ij)
// This needs no access to the package's memory, works unchanged for CVODE (ref-bdf), ARKODE
// (ref-be, ref-sdirk2) and sun::FullNewton (which calls the package's own setup), and factorises
// exactly the matrix the package built, with the gamma of that setup. (Asking the package,
// CVodeGetCurrentGamma or ARKStepGetCurrentGamma, would give the same number at setup time, but
// K would then have to be evaluated again or shared with the Jacobian callback, and a reused J
// with a new gamma, which the packages do, would need the same bookkeeping the matrix already
// carries.) A setup checks that A has the first-order system's pattern, that its position block
// is the identity and that every entry of its -gamma I block is the same gamma > 0; anything
// else is refused (SUNLS_ILL_INPUT).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <sundials/sundials_linearsolver.h>
#include <sundials/sundials_matrix.h>

#include "reference/first_order_system.hpp"
#include "reference/sparse_factor.hpp"
#include "reference/sundials_support.hpp"

namespace pbdbench {

// Which linear solver the ODE integrators' Newton iterations use (solver.ref.linear_solver).
enum class LinearSolverKind : std::uint8_t {
  Reduced,  // ReducedLinearSolver: n x n S, Cholesky (CHOLMOD) with an LU (KLU) fallback
  Full,     // sun::TimedKlu on the whole 2n x 2n matrix A
};

const char* to_string(LinearSolverKind kind);  // "reduced", "full"
// Parses the names above; returns false when unknown.
bool parse_linear_solver_kind(const std::string& name, LinearSolverKind& out);

// A SUNLinearSolver (type DIRECT: matrix-based) for A = I - gamma J of a FirstOrderSystem.
class ReducedLinearSolver {
 public:
  // Keeps a reference to `fos`, which must outlive it (its pattern, masses and slot maps).
  ReducedLinearSolver(const FirstOrderSystem& fos, SUNContext ctx);
  ~ReducedLinearSolver();
  ReducedLinearSolver(const ReducedLinearSolver&) = delete;
  ReducedLinearSolver& operator=(const ReducedLinearSolver&) = delete;

  SUNLinearSolver get() const { return ls_; }
  operator SUNLinearSolver() const { return ls_; }  // NOLINT: passed to *SetLinearSolver
  const sun::LinearSolverStats& stats() const { return stats_; }
  sun::LinearSolverStats& stats() { return stats_; }
  const SparseFactor::Stats& factor_stats() const { return factor_.stats(); }
  double gamma() const { return gamma_; }  // of the last setup (0 before)

  // Where S is not positive definite (K indefinite: compressed links, buckling): false (the
  // default), LU on S itself, the exact Newton direction; true, Cholesky of S + mu M with the
  // smallest mu in 1e-4, 1e-3, ..., 1e4 that is definite (LU only when none is), a modified
  // Newton direction that is a descent direction for the energy of an implicit stage
  // (sun::FullNewton::Merit). The iteration's root is the same either way.
  void set_shift_indefinite(bool shift) { shift_indefinite_ = shift; }
  long shifted_setups() const { return shifted_; }  // setups that needed mu > 0 (cumulative)

 private:
  static SUNLinearSolver_Type type(SUNLinearSolver);
  static SUNLinearSolver_ID id(SUNLinearSolver);
  static int initialize(SUNLinearSolver);
  static int setup(SUNLinearSolver s, SUNMatrix A);
  static int solve(SUNLinearSolver s, SUNMatrix A, N_Vector x, N_Vector b, sunrealtype tol);
  static sunindextype last_flag(SUNLinearSolver s);
  static int space(SUNLinearSolver s, long* lrw, long* liw);

  int do_setup(SUNMatrix A);
  int do_solve(N_Vector x, N_Vector b);
  bool matches_pattern(SUNMatrix A) const;

  const FirstOrderSystem& fos_;
  int n_;
  SparseFactor factor_;
  std::vector<double> s_values_;  // S in system().pattern() order
  std::vector<double> g_values_;  // G = gamma M^-1 K in system().pattern() order
  std::vector<int> entry_row_;    // row i of each entry of system().pattern()
  std::vector<double> rhs_, b1_;  // (n) scratch
  std::vector<std::int64_t> diag_slot_;  // (n) slot of (i, i) in system().pattern()
  std::vector<double> shifted_values_;   // S + mu M
  double gamma_ = 0.0;
  bool factored_ = false;
  bool shift_indefinite_ = false;
  long shifted_ = 0;
  sunindextype last_flag_ = 0;
  sun::LinearSolverStats stats_;
  SUNLinearSolver ls_ = nullptr;
};

// The linear solver of an integrator's Newton iterations, either kind, with one interface for
// the integrators (ref_bdf.cpp, ref_fixed_step.cpp): the SUNLinearSolver to hand to the package,
// the stats its Jacobian callback adds its time to, and the counters it reports.
class NewtonLinearSolver {
 public:
  // `y` and `J` are the package's templates (J with fos.jacobian_pattern()); all must outlive it.
  NewtonLinearSolver(LinearSolverKind kind, const FirstOrderSystem& fos, N_Vector y, SUNMatrix J,
                     SUNContext ctx);
  ~NewtonLinearSolver();
  NewtonLinearSolver(const NewtonLinearSolver&) = delete;
  NewtonLinearSolver& operator=(const NewtonLinearSolver&) = delete;

  LinearSolverKind kind() const { return kind_; }
  SUNLinearSolver get() const;
  sun::LinearSolverStats& stats();
  const sun::LinearSolverStats& stats() const;
  // Sets linear_solves, time_linear, cholesky_factorizations, lu_factorizations and
  // not_positive_definite of c (cumulative; the other fields are the package's).
  void write_counters(sun::Counters& c) const;
  // The reduced solver's policy for an indefinite S (ReducedLinearSolver::set_shift_indefinite);
  // nothing for the full-system KLU.
  void set_shift_indefinite(bool shift);

 private:
  LinearSolverKind kind_;
  std::unique_ptr<sun::TimedKlu> klu_;
  std::unique_ptr<ReducedLinearSolver> reduced_;
};

}  // namespace pbdbench
