// A thin RAII layer over the SUNDIALS 6.4 C objects the reference integrators share (CVODE,
// ARKODE, IDA, KINSOL), and the one way they report a failure: check() turns a negative return
// flag into std::runtime_error naming the call and the flag ("CVode failed: CV_TOO_MUCH_WORK
// (-1): ..."). Every object here is move-only and frees what it owns; none is thread-safe.
//
//   sun::Context ctx;                                    // SUNContext
//   sun::Vector y(n, ctx);                               // owning serial N_Vector; y.map() is Eigen
//   sun::SparseMatrix J(pattern, ctx);                   // CSC, int64 indices, fixed pattern
//   sun::TimedKlu klu(y, J, ctx);                        // KLU, counting and timing its calls
//   sun::check(CVodeSetLinearSolver(mem, klu, J), "CVodeSetLinearSolver", sun::Flags::CvodeLs);
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sundials/sundials_linearsolver.h>
#include <sundials/sundials_matrix.h>
#include <sundials/sundials_nonlinearsolver.h>

namespace pbdbench::sun {

// ---------------------------------------------------------------------------------------------
// Return flags.

// Which table names a flag: each SUNDIALS package has its own (CV_MEM_NULL and CVLS_MEM_NULL are
// both -1), and its linear-solver interface another.
enum class Flags : std::uint8_t {
  Cvode,         // CVode*, CV_* flags
  CvodeLs,       // CVodeSetLinearSolver, CVodeSetJacFn, ...: CVLS_* flags
  Arkode,        // ARKStep*, ARK_* flags
  ArkodeLs,      // ARKStepSetLinearSolver, ARKStepSetJacFn, ...: ARKLS_* flags
  Ida,           // IDA*, IDA_* flags
  IdaLs,         // IDASetLinearSolver, IDASetJacFn, ...: IDALS_* flags
  Kinsol,        // KIN*, KIN_* flags
  KinsolLs,      // KINSetLinearSolver, KINSetJacFn, ...: KINLS_* flags
  LinearSolver,  // SUNLinSol*: SUNLS_* flags
  Matrix,        // SUNMat*: SUNMAT_* flags
  Plain,         // anything else: the number only
};

// The symbolic name of a flag ("CV_TOO_MUCH_WORK"), or "flag <n>" when the table has none.
std::string flag_name(long flag, Flags table);

// Collects the messages SUNDIALS would print to stderr, so that check() can put the last one in
// its exception and a failing test stays quiet. Install it with the package's
// *SetErrHandlerFn(mem, sun::ErrorLog::handler, &log).
struct ErrorLog {
  std::string last;   // the last error: "CVode: At t = ..., mxstep steps taken before reaching tout."
  long warnings = 0;  // warnings (error_code > 0) received, not kept
  static void handler(int error_code, const char* module, const char* function, char* msg,
                      void* log);  // log: an ErrorLog*
};

// Returns `flag` when flag >= 0 (positive flags are warnings or special returns such as
// CV_TSTOP_RETURN); else throws std::runtime_error("<call> failed: <NAME> (<flag>)", followed by
// ": <log->last>" when a log with a message is given).
int check(int flag, std::string_view call, Flags table, const ErrorLog* log = nullptr);

// Throws std::runtime_error("<call> returned null") when p is null; returns p.
[[noreturn]] void throw_null(std::string_view call);
template <class T>
T* check_ptr(T* p, std::string_view call) {
  if (p == nullptr) throw_null(call);
  return p;
}

// ---------------------------------------------------------------------------------------------
// Objects.

// A SUNContext (SUNContext_Create(nullptr, ...): no MPI communicator).
class Context {
 public:
  Context();
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  SUNContext get() const { return ctx_; }
  operator SUNContext() const { return ctx_; }  // NOLINT: passed to every constructor

 private:
  SUNContext ctx_ = nullptr;
};

// A serial N_Vector. Either owning its n values (zeroed), or wrapping memory owned by someone
// else (an Eigen vector, which must outlive it and must not be resized meanwhile).
class Vector {
 public:
  Vector(sunindextype n, SUNContext ctx);               // owning
  Vector(Eigen::VectorXd& data, SUNContext ctx);        // wrapping data.data(), no copy
  ~Vector();
  Vector(Vector&& other) noexcept;
  Vector& operator=(Vector&& other) noexcept;
  Vector(const Vector&) = delete;
  Vector& operator=(const Vector&) = delete;

  N_Vector get() const { return v_; }
  operator N_Vector() const { return v_; }  // NOLINT
  sunindextype size() const;
  Eigen::Map<Eigen::VectorXd> map() const;

 private:
  N_Vector v_ = nullptr;
};

// Eigen views of any serial N_Vector (the vectors SUNDIALS hands to callbacks).
Eigen::Map<Eigen::VectorXd> view(N_Vector v);
Eigen::Map<const Eigen::VectorXd> cview(N_Vector v);

// A compressed sparse column pattern of a rows x cols matrix, row indices sorted in each column.
struct CscPattern {
  sunindextype rows = 0, cols = 0;
  std::vector<sunindextype> column_start;  // (cols + 1)
  std::vector<sunindextype> row;           // (nnz)
  sunindextype nnz() const { return static_cast<sunindextype>(row.size()); }
  // Position of entry (r, c) in `row` (and in a values array of this pattern), or -1.
  sunindextype find(sunindextype r, sunindextype c) const;
  // True when (i, i) is present for every i < min(rows, cols).
  bool has_full_diagonal() const;
};

// A SUNSparseMatrix in CSC form with a pattern's nnz slots, the pattern written in and the
// values zeroed.
class SparseMatrix {
 public:
  SparseMatrix(const CscPattern& pattern, SUNContext ctx);
  ~SparseMatrix();
  SparseMatrix(const SparseMatrix&) = delete;
  SparseMatrix& operator=(const SparseMatrix&) = delete;

  SUNMatrix get() const { return A_; }
  operator SUNMatrix() const { return A_; }  // NOLINT
  double* values() const;

 private:
  SUNMatrix A_ = nullptr;
};

// Writes the pattern into a sparse CSC matrix of at least pattern.nnz() slots. The Jacobian
// callbacks call this every time: the packages clear a matrix with SUNMatZero before handing it
// to them, and SUNMatZero_Sparse also clears the index arrays. Throws std::invalid_argument
// when A is not a CSC matrix of the pattern's shape with room for it.
void write_pattern(SUNMatrix A, const CscPattern& pattern);

// What a TimedKlu (or a ReducedLinearSolver, reference/reduced_linear_solver.hpp) did since it
// was built (cumulative).
struct LinearSolverStats {
  long setups = 0;       // numeric factorisations (the first is also the symbolic analysis)
  long solves = 0;       // triangular solves with a factorisation
  double seconds = 0.0;  // wall-clock time in setup and solve, plus whatever the owner adds
                         // with a ScopedTimer (its Jacobian callbacks)
};

// The KLU direct solver behind a thin SUNLinearSolver of its own that counts and times setup
// and solve and forwards every operation to KLU. Pass get() to *SetLinearSolver.
class TimedKlu {
 public:
  TimedKlu(N_Vector y, SUNMatrix A, SUNContext ctx);
  ~TimedKlu();
  TimedKlu(const TimedKlu&) = delete;
  TimedKlu& operator=(const TimedKlu&) = delete;

  SUNLinearSolver get() const { return outer_; }
  operator SUNLinearSolver() const { return outer_; }  // NOLINT
  const LinearSolverStats& stats() const { return stats_; }
  LinearSolverStats& stats() { return stats_; }

 private:
  static SUNLinearSolver_Type type(SUNLinearSolver);
  static SUNLinearSolver_ID id(SUNLinearSolver);
  static int initialize(SUNLinearSolver s);
  static int setup(SUNLinearSolver s, SUNMatrix A);
  static int solve(SUNLinearSolver s, SUNMatrix A, N_Vector x, N_Vector b, sunrealtype tol);
  static sunindextype last_flag(SUNLinearSolver s);
  static int space(SUNLinearSolver s, long* lrw, long* liw);

  SUNLinearSolver inner_ = nullptr;  // SUNLinSol_KLU
  SUNLinearSolver outer_ = nullptr;  // ours, content = this
  LinearSolverStats stats_;
};

// Newton's method with a line search for the packages' implicit stage equations G(ycor) = 0: a
// SUNNonlinearSolver (ROOTFIND) to replace their own SUNNonlinSol_Newton, which keeps the
// Jacobian of the first iterate for the whole solve (a chord iteration), has no line search, and,
// when that fails, retries from the start with a Jacobian evaluated at the same predicted state.
// Where that Jacobian is far from the solution's (a cloth released flat has no transverse
// stiffness until it sags) it converges slowly or not at all, and with a fixed step that cannot
// be shortened a failure is final. Here:
//   - the first iteration sets up as the package advises (call_lsetup, jbad = false);
//   - after a damped step, or a step that shrank by less than a factor 4, the Jacobian is
//     evaluated at the new iterate (setup with jbad = true): Newton where the chord iteration is
//     slow, the chord iteration where it is fast;
//   - each Newton step d is halved (up to 30 times) until the weighted RMS norm of the residual
//     drops: |G(ycor + a d)| <= (1 - 1e-4 a) |G| (a step already within the tolerance is taken
//     whole: the residual is then at its round-off floor); with no decrease and a Jacobian not
//     evaluated at the iterate, the Jacobian is evaluated there and the iteration retried;
//   - a full step (a = 1) is handed to the package's convergence test; a damped one is not (the
//     iterate is not converged when Newton's step had to be cut).
// A failure (max iterations, no decrease with a current Jacobian, a failed solve) is returned as
// recoverable (SUN_NLS_CONV_RECVR). Counts per solve, as the packages expect. Pass get() to
// *SetNonlinearSolver; it must outlive the package's memory. The package's divergence test
// (rdiv) should be switched off: the line search keeps the residual decreasing, while a full
// step may be longer than the one before it.
class FullNewton {
 public:
  // An optional merit function for the line search, for a root that minimises an energy E
  // (a conservative system's implicit stage: reference/ref_fixed_step.cpp). With one set, each
  // iterate is first projected (project(): e.g. onto the stage's linear equations), and a step
  // d is accepted when E(ycor + a d, projected) <= E(ycor) + 1e-4 a slope, slope = grad E . d;
  // a direction with slope >= 0 (not a descent direction) falls back to the residual norm for
  // that iteration. Each returns 0 on success, > 0 recoverable, < 0 unrecoverable.
  class Merit {
   public:
    virtual ~Merit() = default;
    virtual int project(N_Vector ycor) = 0;
    virtual int value(N_Vector ycor, double& energy) = 0;
    virtual int slope(N_Vector ycor, N_Vector d, double& slope) = 0;
  };

  FullNewton(N_Vector y_template, SUNContext ctx);
  ~FullNewton();
  FullNewton(const FullNewton&) = delete;
  FullNewton& operator=(const FullNewton&) = delete;

  SUNNonlinearSolver get() const { return nls_; }
  operator SUNNonlinearSolver() const { return nls_; }  // NOLINT
  long iterations() const { return iterations_; }        // cumulative
  long convergence_failures() const { return failures_; }  // cumulative
  // nullptr: the residual norm alone. The merit must outlive the solves.
  void set_merit(Merit* merit) { merit_ = merit; }
  long merit_steps() const { return merit_steps_; }  // steps accepted on the merit (cumulative)

 private:
  static SUNNonlinearSolver_Type type(SUNNonlinearSolver);
  static int initialize(SUNNonlinearSolver);
  static int solve(SUNNonlinearSolver s, N_Vector y0, N_Vector ycor, N_Vector w, sunrealtype tol,
                   sunbooleantype call_lsetup, void* mem);
  static int set_sys(SUNNonlinearSolver s, SUNNonlinSolSysFn f);
  static int set_lsetup(SUNNonlinearSolver s, SUNNonlinSolLSetupFn f);
  static int set_lsolve(SUNNonlinearSolver s, SUNNonlinSolLSolveFn f);
  static int set_ctest(SUNNonlinearSolver s, SUNNonlinSolConvTestFn f, void* data);
  static int set_max_iters(SUNNonlinearSolver s, int n);
  static int num_iters(SUNNonlinearSolver s, long* n);
  static int cur_iter(SUNNonlinearSolver s, int* n);
  static int num_fails(SUNNonlinearSolver s, long* n);

  static constexpr int kMaxHalvings = 30;

  SUNNonlinearSolver nls_ = nullptr;
  N_Vector delta_ = nullptr, residual_ = nullptr, trial_ = nullptr, trial_residual_ = nullptr;
  SUNNonlinSolSysFn sys_ = nullptr;
  SUNNonlinSolLSetupFn lsetup_ = nullptr;
  SUNNonlinSolLSolveFn lsolve_ = nullptr;
  SUNNonlinSolConvTestFn ctest_ = nullptr;
  void* ctest_data_ = nullptr;
  Merit* merit_ = nullptr;
  long merit_steps_ = 0;
  int max_iters_ = 3;
  int cur_iter_ = 0;
  long iterations_ = 0;        // all solves
  long failures_ = 0;
  long solve_iterations_ = 0;  // the last solve (what SUNNonlinSolGetNumIters reports)
  long solve_failures_ = 0;
};

// Adds the wall-clock time of its scope to a seconds counter (a Jacobian callback's time to
// LinearSolverStats::seconds).
class ScopedTimer {
 public:
  explicit ScopedTimer(double& seconds)
      : seconds_(seconds), start_(std::chrono::steady_clock::now()) {}
  ~ScopedTimer() {
    seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

 private:
  double& seconds_;
  std::chrono::steady_clock::time_point start_;
};

// A package's memory block (CVodeCreate, ARKStepCreate, IDACreate, KINCreate) with the function
// that frees it (CVodeFree, ARKStepFree, IDAFree, KINFree).
class Memory {
 public:
  using FreeFn = void (*)(void**);
  Memory() = default;
  Memory(void* mem, FreeFn free_fn) : mem_(mem), free_(free_fn) {}
  ~Memory() { reset(); }
  Memory(Memory&& other) noexcept;
  Memory& operator=(Memory&& other) noexcept;
  Memory(const Memory&) = delete;
  Memory& operator=(const Memory&) = delete;

  void* get() const { return mem_; }
  operator void*() const { return mem_; }  // NOLINT
  void reset();

 private:
  void* mem_ = nullptr;
  FreeFn free_ = nullptr;
};

// ---------------------------------------------------------------------------------------------
// Counters of an integrator, cumulative; what a step did is the difference of two readings.
struct Counters {
  long steps = 0;                 // internal steps
  long newton_iterations = 0;     // nonlinear iterations
  long linear_setups = 0;         // Jacobian evaluations with a factorisation
  long linear_solves = 0;         // solves with a factorisation
  long error_test_failures = 0;   // steps rejected by the local error test
  long convergence_failures = 0;  // nonlinear solves that failed to converge
  double time_linear = 0.0;       // s, Jacobian callbacks, factorisations and solves
  // Which factorisation the linear setups used (SparseFactor, reference/sparse_factor.hpp): the
  // reduced n x n matrices and the static solve's stiffness. Cholesky attempts that met a pivot
  // <= 0 are counted in not_positive_definite, whether LU then followed or not. The full-system
  // KLU path (TimedKlu) counts none of these.
  long cholesky_factorizations = 0;
  long lu_factorizations = 0;
  long not_positive_definite = 0;

  Counters& operator+=(const Counters& o);
  Counters operator-(const Counters& o) const;
};

}  // namespace pbdbench::sun
