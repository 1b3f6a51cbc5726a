#include "reference/sundials_support.hpp"

#include "core/cancel.hpp"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <utility>

#include <arkode/arkode_arkstep.h>
#include <cvode/cvode.h>
#include <cvode/cvode_ls.h>
#include <ida/ida.h>
#include <ida/ida_ls.h>
#include <kinsol/kinsol.h>
#include <kinsol/kinsol_ls.h>
#include <sunlinsol/sunlinsol_klu.h>
#include <sunmatrix/sunmatrix_sparse.h>

namespace pbdbench::sun {

namespace {

// The packages' *GetReturnFlagName functions return a malloc'ed string the caller frees.
std::string take(char* name) {
  if (name == nullptr) return {};
  std::string s(name);
  std::free(name);  // NOLINT: allocated by SUNDIALS with malloc
  return s;
}

std::string linear_solver_flag(long flag) {
  switch (flag) {
    case SUNLS_SUCCESS: return "SUNLS_SUCCESS";
    case SUNLS_MEM_NULL: return "SUNLS_MEM_NULL";
    case SUNLS_ILL_INPUT: return "SUNLS_ILL_INPUT";
    case SUNLS_MEM_FAIL: return "SUNLS_MEM_FAIL";
    case SUNLS_ATIMES_NULL: return "SUNLS_ATIMES_NULL";
    case SUNLS_ATIMES_FAIL_UNREC: return "SUNLS_ATIMES_FAIL_UNREC";
    case SUNLS_PSET_FAIL_UNREC: return "SUNLS_PSET_FAIL_UNREC";
    case SUNLS_PSOLVE_NULL: return "SUNLS_PSOLVE_NULL";
    case SUNLS_PSOLVE_FAIL_UNREC: return "SUNLS_PSOLVE_FAIL_UNREC";
    case SUNLS_PACKAGE_FAIL_UNREC: return "SUNLS_PACKAGE_FAIL_UNREC";
    case SUNLS_GS_FAIL: return "SUNLS_GS_FAIL";
    case SUNLS_QRSOL_FAIL: return "SUNLS_QRSOL_FAIL";
    case SUNLS_VECTOROP_ERR: return "SUNLS_VECTOROP_ERR";
    case SUNLS_RES_REDUCED: return "SUNLS_RES_REDUCED";
    case SUNLS_CONV_FAIL: return "SUNLS_CONV_FAIL";
    case SUNLS_ATIMES_FAIL_REC: return "SUNLS_ATIMES_FAIL_REC";
    case SUNLS_PSET_FAIL_REC: return "SUNLS_PSET_FAIL_REC";
    case SUNLS_PSOLVE_FAIL_REC: return "SUNLS_PSOLVE_FAIL_REC";
    case SUNLS_PACKAGE_FAIL_REC: return "SUNLS_PACKAGE_FAIL_REC";
    case SUNLS_QRFACT_FAIL: return "SUNLS_QRFACT_FAIL";
    case SUNLS_LUFACT_FAIL: return "SUNLS_LUFACT_FAIL";
    default: return {};
  }
}

std::string matrix_flag(long flag) {
  switch (flag) {
    case SUNMAT_SUCCESS: return "SUNMAT_SUCCESS";
    case SUNMAT_ILL_INPUT: return "SUNMAT_ILL_INPUT";
    case SUNMAT_MEM_FAIL: return "SUNMAT_MEM_FAIL";
    case SUNMAT_OPERATION_FAIL: return "SUNMAT_OPERATION_FAIL";
    case SUNMAT_MATVEC_SETUP_REQUIRED: return "SUNMAT_MATVEC_SETUP_REQUIRED";
    default: return {};
  }
}

}  // namespace

std::string flag_name(long flag, Flags table) {
  std::string name;
  switch (table) {
    case Flags::Cvode: name = take(CVodeGetReturnFlagName(flag)); break;
    case Flags::CvodeLs: name = take(CVodeGetLinReturnFlagName(flag)); break;
    case Flags::Arkode: name = take(ARKStepGetReturnFlagName(flag)); break;
    case Flags::ArkodeLs: name = take(ARKStepGetLinReturnFlagName(flag)); break;
    case Flags::Ida: name = take(IDAGetReturnFlagName(flag)); break;
    case Flags::IdaLs: name = take(IDAGetLinReturnFlagName(flag)); break;
    case Flags::Kinsol: name = take(KINGetReturnFlagName(flag)); break;
    case Flags::KinsolLs: name = take(KINGetLinReturnFlagName(flag)); break;
    case Flags::LinearSolver: name = linear_solver_flag(flag); break;
    case Flags::Matrix: name = matrix_flag(flag); break;
    case Flags::Plain: break;
  }
  if (name.empty() || name == "NONE") return "flag " + std::to_string(flag);
  return name;
}

void ErrorLog::handler(int error_code, const char* module, const char* function, char* msg,
                       void* log) {
  auto* self = static_cast<ErrorLog*>(log);
  if (self == nullptr) return;
  if (error_code > 0) {
    ++self->warnings;
    return;
  }
  self->last = std::string(module ? module : "") + " " + (function ? function : "") + ": " +
               (msg ? msg : "");
}

int check(int flag, std::string_view call, Flags table, const ErrorLog* log) {
  if (flag >= 0) return flag;
  std::string what = std::string(call) + " failed: " + flag_name(flag, table) + " (" +
                     std::to_string(flag) + ")";
  if (log != nullptr && !log->last.empty()) what += ": " + log->last;
  throw std::runtime_error(what);
}

void throw_null(std::string_view call) {
  throw std::runtime_error(std::string(call) + " returned null");
}

// ---------------------------------------------------------------------------------------------

Context::Context() {
  check(SUNContext_Create(nullptr, &ctx_), "SUNContext_Create", Flags::Plain);
}

Context::~Context() {
  if (ctx_ != nullptr) SUNContext_Free(&ctx_);
}

Vector::Vector(sunindextype n, SUNContext ctx) {
  v_ = check_ptr(N_VNew_Serial(n, ctx), "N_VNew_Serial");
  N_VConst(0.0, v_);
}

Vector::Vector(Eigen::VectorXd& data, SUNContext ctx) {
  v_ = check_ptr(N_VMake_Serial(static_cast<sunindextype>(data.size()), data.data(), ctx),
                 "N_VMake_Serial");
}

Vector::~Vector() {
  if (v_ != nullptr) N_VDestroy(v_);
}

Vector::Vector(Vector&& other) noexcept : v_(std::exchange(other.v_, nullptr)) {}

Vector& Vector::operator=(Vector&& other) noexcept {
  if (this != &other) {
    if (v_ != nullptr) N_VDestroy(v_);
    v_ = std::exchange(other.v_, nullptr);
  }
  return *this;
}

sunindextype Vector::size() const { return N_VGetLength_Serial(v_); }

Eigen::Map<Eigen::VectorXd> Vector::map() const { return view(v_); }

Eigen::Map<Eigen::VectorXd> view(N_Vector v) {
  return {N_VGetArrayPointer(v), static_cast<Eigen::Index>(N_VGetLength_Serial(v))};
}

Eigen::Map<const Eigen::VectorXd> cview(N_Vector v) {
  return {N_VGetArrayPointer(v), static_cast<Eigen::Index>(N_VGetLength_Serial(v))};
}

// ---------------------------------------------------------------------------------------------

sunindextype CscPattern::find(sunindextype r, sunindextype c) const {
  if (c < 0 || c >= cols) return -1;
  for (sunindextype k = column_start[static_cast<size_t>(c)];
       k < column_start[static_cast<size_t>(c) + 1]; ++k)
    if (row[static_cast<size_t>(k)] == r) return k;
  return -1;
}

bool CscPattern::has_full_diagonal() const {
  const sunindextype m = rows < cols ? rows : cols;
  for (sunindextype i = 0; i < m; ++i)
    if (find(i, i) < 0) return false;
  return true;
}

SparseMatrix::SparseMatrix(const CscPattern& pattern, SUNContext ctx) {
  // SUNSparseMatrix refuses nnz = 0; an empty pattern still gets one (unused) slot.
  const sunindextype slots = pattern.nnz() > 0 ? pattern.nnz() : 1;
  A_ = check_ptr(SUNSparseMatrix(pattern.rows, pattern.cols, slots, CSC_MAT, ctx),
                 "SUNSparseMatrix");
  write_pattern(A_, pattern);
  std::fill(values(), values() + slots, 0.0);
}

SparseMatrix::~SparseMatrix() {
  if (A_ != nullptr) SUNMatDestroy(A_);
}

double* SparseMatrix::values() const { return SUNSparseMatrix_Data(A_); }

void write_pattern(SUNMatrix A, const CscPattern& pattern) {
  if (SUNMatGetID(A) != SUNMATRIX_SPARSE || SUNSparseMatrix_SparseType(A) != CSC_MAT ||
      SUNSparseMatrix_Rows(A) != pattern.rows || SUNSparseMatrix_Columns(A) != pattern.cols ||
      SUNSparseMatrix_NNZ(A) < pattern.nnz())
    throw std::invalid_argument("write_pattern: the matrix is not a CSC matrix of the pattern's "
                                "shape with room for its entries");
  sunindextype* start = SUNSparseMatrix_IndexPointers(A);
  sunindextype* row = SUNSparseMatrix_IndexValues(A);
  std::copy(pattern.column_start.begin(), pattern.column_start.end(), start);
  std::copy(pattern.row.begin(), pattern.row.end(), row);
}

// ---------------------------------------------------------------------------------------------

TimedKlu::TimedKlu(N_Vector y, SUNMatrix A, SUNContext ctx) {
  inner_ = check_ptr(SUNLinSol_KLU(y, A, ctx), "SUNLinSol_KLU");
  outer_ = SUNLinSolNewEmpty(ctx);
  if (outer_ == nullptr) {
    SUNLinSolFree(inner_);
    throw_null("SUNLinSolNewEmpty");
  }
  outer_->content = this;
  outer_->ops->gettype = &TimedKlu::type;
  outer_->ops->getid = &TimedKlu::id;
  outer_->ops->initialize = &TimedKlu::initialize;
  outer_->ops->setup = &TimedKlu::setup;
  outer_->ops->solve = &TimedKlu::solve;
  outer_->ops->lastflag = &TimedKlu::last_flag;
  outer_->ops->space = &TimedKlu::space;
  outer_->ops->free = nullptr;  // freed here, not by SUNLinSolFree
}

TimedKlu::~TimedKlu() {
  if (outer_ != nullptr) SUNLinSolFreeEmpty(outer_);
  if (inner_ != nullptr) SUNLinSolFree(inner_);
}

SUNLinearSolver_Type TimedKlu::type(SUNLinearSolver) { return SUNLINEARSOLVER_DIRECT; }

SUNLinearSolver_ID TimedKlu::id(SUNLinearSolver) { return SUNLINEARSOLVER_CUSTOM; }

int TimedKlu::initialize(SUNLinearSolver s) {
  return SUNLinSolInitialize(static_cast<TimedKlu*>(s->content)->inner_);
}

int TimedKlu::setup(SUNLinearSolver s, SUNMatrix A) {
  auto* self = static_cast<TimedKlu*>(s->content);
  ScopedTimer timer(self->stats_.seconds);
  ++self->stats_.setups;
  return SUNLinSolSetup(self->inner_, A);
}

int TimedKlu::solve(SUNLinearSolver s, SUNMatrix A, N_Vector x, N_Vector b, sunrealtype tol) {
  auto* self = static_cast<TimedKlu*>(s->content);
  ScopedTimer timer(self->stats_.seconds);
  ++self->stats_.solves;
  return SUNLinSolSolve(self->inner_, A, x, b, tol);
}

sunindextype TimedKlu::last_flag(SUNLinearSolver s) {
  return SUNLinSolLastFlag(static_cast<TimedKlu*>(s->content)->inner_);
}

int TimedKlu::space(SUNLinearSolver s, long* lrw, long* liw) {
  return SUNLinSolSpace(static_cast<TimedKlu*>(s->content)->inner_, lrw, liw);
}

// ---------------------------------------------------------------------------------------------

FullNewton::FullNewton(N_Vector y_template, SUNContext ctx) {
  nls_ = check_ptr(SUNNonlinSolNewEmpty(ctx), "SUNNonlinSolNewEmpty");
  delta_ = N_VClone(y_template);
  residual_ = N_VClone(y_template);
  trial_ = N_VClone(y_template);
  trial_residual_ = N_VClone(y_template);
  if (!delta_ || !residual_ || !trial_ || !trial_residual_) {
    for (N_Vector v : {delta_, residual_, trial_, trial_residual_})
      if (v) N_VDestroy(v);
    SUNNonlinSolFreeEmpty(nls_);
    throw_null("N_VClone");
  }
  nls_->content = this;
  nls_->ops->gettype = &FullNewton::type;
  nls_->ops->initialize = &FullNewton::initialize;
  nls_->ops->solve = &FullNewton::solve;
  nls_->ops->free = nullptr;  // freed here
  nls_->ops->setsysfn = &FullNewton::set_sys;
  nls_->ops->setlsetupfn = &FullNewton::set_lsetup;
  nls_->ops->setlsolvefn = &FullNewton::set_lsolve;
  nls_->ops->setctestfn = &FullNewton::set_ctest;
  nls_->ops->setmaxiters = &FullNewton::set_max_iters;
  nls_->ops->getnumiters = &FullNewton::num_iters;
  nls_->ops->getcuriter = &FullNewton::cur_iter;
  nls_->ops->getnumconvfails = &FullNewton::num_fails;
}

FullNewton::~FullNewton() {
  for (N_Vector v : {delta_, residual_, trial_, trial_residual_})
    if (v != nullptr) N_VDestroy(v);
  if (nls_ != nullptr) SUNNonlinSolFreeEmpty(nls_);
}

SUNNonlinearSolver_Type FullNewton::type(SUNNonlinearSolver) { return SUNNONLINEARSOLVER_ROOTFIND; }

int FullNewton::initialize(SUNNonlinearSolver s) {
  auto* self = static_cast<FullNewton*>(s->content);
  if (self->sys_ == nullptr || self->lsolve_ == nullptr || self->ctest_ == nullptr)
    return SUN_NLS_MEM_NULL;
  return SUN_NLS_SUCCESS;
}

// y0 is the predicted state (left alone); ycor holds the initial guess of the correction to it
// on input (the package sets it, usually to zero) and the converged correction on output.
int FullNewton::solve(SUNNonlinearSolver s, N_Vector, N_Vector ycor, N_Vector w,
                      sunrealtype tol, sunbooleantype call_lsetup, void* mem) {
  auto* self = static_cast<FullNewton*>(s->content);
  N_Vector G = self->residual_, d = self->delta_, trial = self->trial_, Gt = self->trial_residual_;
  self->cur_iter_ = 0;
  self->solve_iterations_ = 0;
  self->solve_failures_ = 0;
  Merit* merit = self->merit_;
  int flag = merit != nullptr ? merit->project(ycor) : 0;
  if (flag == 0) flag = self->sys_(ycor, G, mem);  // residual at the initial iterate
  double phi = flag == 0 ? N_VWrmsNorm(G, w) : 0.0;
  double energy = 0.0;
  if (flag == 0 && merit != nullptr) flag = merit->value(ycor, energy);
  bool setup = call_lsetup != SUNFALSE;  // the package's advice for the first iteration
  bool jbad = false;   // force the Jacobian's evaluation at the next setup
  bool fresh = false;  // the Jacobian in use was evaluated at the current iterate
  double previous = -1.0;  // weighted norm of the previous accepted step
  while (flag == 0) {
    if (cancel_requested()) {  // called from SUNDIALS: fail the solve, the runner sees why
      flag = -1;
      break;
    }
    if (setup && self->lsetup_ != nullptr) {
      sunbooleantype jcur = SUNFALSE;
      flag = self->lsetup_(jbad ? SUNTRUE : SUNFALSE, &jcur, mem);
      if (flag != 0) break;
      fresh = jcur != SUNFALSE;
      setup = false;
    }
    ++self->iterations_;
    ++self->solve_iterations_;
    N_VScale(-1.0, G, d);
    flag = self->lsolve_(d, mem);
    if (flag != 0) break;
    // Backtracking on the weighted RMS norm of the residual; the last residual evaluated is
    // the accepted iterate's, which the package keeps (its stage right-hand side). A step
    // already within the tolerance is taken whole: the residual is then at its round-off floor
    // and cannot be relied on to decrease.
    const double length = N_VWrmsNorm(d, w);
    const bool small = length <= tol;
    // With a merit: the energy's slope along d; not a descent direction: the residual norm.
    double slope = 0.0;
    if (merit != nullptr && (flag = merit->slope(ycor, d, slope)) < 0) break;
    flag = 0;
    const bool on_merit = merit != nullptr && slope < 0.0;
    double alpha = 1.0, phit = 0.0, energy_t = 0.0;
    bool accepted = false;
    for (int k = 0; k <= kMaxHalvings; ++k, alpha *= 0.5) {
      N_VLinearSum(1.0, ycor, alpha, d, trial);
      int f = on_merit ? merit->project(trial) : 0;
      if (f == 0) f = self->sys_(trial, Gt, mem);
      if (f == 0 && merit != nullptr) f = merit->value(trial, energy_t);
      if (f < 0) {
        flag = f;
        break;
      }
      if (f > 0) continue;  // recoverable: a shorter step
      phit = N_VWrmsNorm(Gt, w);
      // On the merit, a lower residual also passes: near the root the energy's decrease
      // (~ slope) falls below the round-off of the energy itself.
      const bool decrease = phit <= (1.0 - 1e-4 * alpha) * phi ||
                            (on_merit && energy_t <= energy + 1e-4 * alpha * slope);
      if (small || decrease) {
        accepted = true;
        break;
      }
    }
    if (flag < 0) break;
    if (!accepted) {
      if (!fresh && self->lsetup_ != nullptr) {  // retry with the Jacobian at this iterate
        setup = jbad = true;
        flag = self->sys_(ycor, G, mem);  // the package's state back at the iterate
        if (flag == 0 && merit != nullptr) flag = merit->value(ycor, energy);
        continue;
      }
      flag = SUN_NLS_CONV_RECVR;
      break;
    }
    if (on_merit) {
      ++self->merit_steps_;
      N_VLinearSum(1.0, trial, -1.0, ycor, d);  // the step taken, projection included
    }
    N_VScale(1.0, trial, ycor);
    N_VScale(1.0, Gt, G);
    phi = phit;
    energy = energy_t;
    fresh = false;
    if (alpha == 1.0) {  // a full Newton step: the package judges convergence
      flag = self->ctest_(s, ycor, d, tol, w, self->ctest_data_);
      if (flag == SUN_NLS_SUCCESS) return SUN_NLS_SUCCESS;
      if (flag != SUN_NLS_CONTINUE) break;
      flag = 0;
    }
    // A damped step, or one that shrank by less than a factor 4: the Jacobian in use is no
    // longer good enough; evaluate it at the new iterate.
    const double step = alpha * length;
    if (alpha < 1.0 || (previous > 0.0 && step > 0.25 * previous)) setup = jbad = true;
    previous = step;
    if (++self->cur_iter_ >= self->max_iters_) {
      flag = SUN_NLS_CONV_RECVR;
      break;
    }
  }
  ++self->failures_;
  ++self->solve_failures_;
  return flag;
}

int FullNewton::set_sys(SUNNonlinearSolver s, SUNNonlinSolSysFn f) {
  static_cast<FullNewton*>(s->content)->sys_ = f;
  return SUN_NLS_SUCCESS;
}

int FullNewton::set_lsetup(SUNNonlinearSolver s, SUNNonlinSolLSetupFn f) {
  static_cast<FullNewton*>(s->content)->lsetup_ = f;
  return SUN_NLS_SUCCESS;
}

int FullNewton::set_lsolve(SUNNonlinearSolver s, SUNNonlinSolLSolveFn f) {
  static_cast<FullNewton*>(s->content)->lsolve_ = f;
  return SUN_NLS_SUCCESS;
}

int FullNewton::set_ctest(SUNNonlinearSolver s, SUNNonlinSolConvTestFn f, void* data) {
  auto* self = static_cast<FullNewton*>(s->content);
  self->ctest_ = f;
  self->ctest_data_ = data;
  return SUN_NLS_SUCCESS;
}

int FullNewton::set_max_iters(SUNNonlinearSolver s, int n) {
  if (n < 1) return SUN_NLS_ILL_INPUT;
  static_cast<FullNewton*>(s->content)->max_iters_ = n;
  return SUN_NLS_SUCCESS;
}

int FullNewton::num_iters(SUNNonlinearSolver s, long* n) {
  *n = static_cast<FullNewton*>(s->content)->solve_iterations_;
  return SUN_NLS_SUCCESS;
}

int FullNewton::cur_iter(SUNNonlinearSolver s, int* n) {
  *n = static_cast<FullNewton*>(s->content)->cur_iter_;
  return SUN_NLS_SUCCESS;
}

int FullNewton::num_fails(SUNNonlinearSolver s, long* n) {
  *n = static_cast<FullNewton*>(s->content)->solve_failures_;
  return SUN_NLS_SUCCESS;
}

// ---------------------------------------------------------------------------------------------

Memory::Memory(Memory&& other) noexcept
    : mem_(std::exchange(other.mem_, nullptr)), free_(std::exchange(other.free_, nullptr)) {}

Memory& Memory::operator=(Memory&& other) noexcept {
  if (this != &other) {
    reset();
    mem_ = std::exchange(other.mem_, nullptr);
    free_ = std::exchange(other.free_, nullptr);
  }
  return *this;
}

void Memory::reset() {
  if (mem_ != nullptr && free_ != nullptr) free_(&mem_);
  mem_ = nullptr;
}

// ---------------------------------------------------------------------------------------------

Counters& Counters::operator+=(const Counters& o) {
  steps += o.steps;
  newton_iterations += o.newton_iterations;
  linear_setups += o.linear_setups;
  linear_solves += o.linear_solves;
  error_test_failures += o.error_test_failures;
  convergence_failures += o.convergence_failures;
  time_linear += o.time_linear;
  cholesky_factorizations += o.cholesky_factorizations;
  lu_factorizations += o.lu_factorizations;
  not_positive_definite += o.not_positive_definite;
  return *this;
}

Counters Counters::operator-(const Counters& o) const {
  Counters d;
  d.steps = steps - o.steps;
  d.newton_iterations = newton_iterations - o.newton_iterations;
  d.linear_setups = linear_setups - o.linear_setups;
  d.linear_solves = linear_solves - o.linear_solves;
  d.error_test_failures = error_test_failures - o.error_test_failures;
  d.convergence_failures = convergence_failures - o.convergence_failures;
  d.time_linear = time_linear - o.time_linear;
  d.cholesky_factorizations = cholesky_factorizations - o.cholesky_factorizations;
  d.lu_factorizations = lu_factorizations - o.lu_factorizations;
  d.not_positive_definite = not_positive_definite - o.not_positive_definite;
  return d;
}

}  // namespace pbdbench::sun
