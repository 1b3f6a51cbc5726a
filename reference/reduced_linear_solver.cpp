// The Schur-complement linear solver of the first-order system's Newton matrix.
// reduced_linear_solver.hpp.
#include "reference/reduced_linear_solver.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <sunmatrix/sunmatrix_sparse.h>

namespace pbdbench {

const char* to_string(LinearSolverKind kind) {
  switch (kind) {
    case LinearSolverKind::Reduced: return "reduced";
    case LinearSolverKind::Full: return "full";
  }
  return "reduced";
}

bool parse_linear_solver_kind(const std::string& name, LinearSolverKind& out) {
  if (name == "reduced") {
    out = LinearSolverKind::Reduced;
    return true;
  }
  if (name == "full") {
    out = LinearSolverKind::Full;
    return true;
  }
  return false;
}

// ---------------------------------------------------------------------------------------------

ReducedLinearSolver::ReducedLinearSolver(const FirstOrderSystem& fos, SUNContext ctx)
    : fos_(fos), n_(fos.dofs()), factor_(fos.system().pattern()) {
  const SparsityPattern& sp = fos.system().pattern();
  const auto nnz = static_cast<size_t>(sp.nnz());
  s_values_.assign(nnz, 0.0);
  g_values_.assign(nnz, 0.0);
  entry_row_.resize(nnz);
  for (size_t p = 0; p < nnz; ++p) entry_row_[p] = static_cast<int>(sp.row[p]);
  diag_slot_.resize(static_cast<size_t>(n_));
  for (int i = 0; i < n_; ++i) diag_slot_[static_cast<size_t>(i)] = sp.find(i, i);
  rhs_.assign(static_cast<size_t>(n_), 0.0);
  b1_.assign(static_cast<size_t>(n_), 0.0);

  ls_ = sun::check_ptr(SUNLinSolNewEmpty(ctx), "SUNLinSolNewEmpty");
  ls_->content = this;
  ls_->ops->gettype = &ReducedLinearSolver::type;
  ls_->ops->getid = &ReducedLinearSolver::id;
  ls_->ops->initialize = &ReducedLinearSolver::initialize;
  ls_->ops->setup = &ReducedLinearSolver::setup;
  ls_->ops->solve = &ReducedLinearSolver::solve;
  ls_->ops->lastflag = &ReducedLinearSolver::last_flag;
  ls_->ops->space = &ReducedLinearSolver::space;
  ls_->ops->free = nullptr;  // freed here, not by SUNLinSolFree
}

ReducedLinearSolver::~ReducedLinearSolver() {
  if (ls_ != nullptr) SUNLinSolFreeEmpty(ls_);
}

SUNLinearSolver_Type ReducedLinearSolver::type(SUNLinearSolver) { return SUNLINEARSOLVER_DIRECT; }

SUNLinearSolver_ID ReducedLinearSolver::id(SUNLinearSolver) { return SUNLINEARSOLVER_CUSTOM; }

int ReducedLinearSolver::initialize(SUNLinearSolver s) {
  auto* self = static_cast<ReducedLinearSolver*>(s->content);
  self->factored_ = false;
  self->last_flag_ = SUNLS_SUCCESS;
  return SUNLS_SUCCESS;
}

int ReducedLinearSolver::setup(SUNLinearSolver s, SUNMatrix A) {
  auto* self = static_cast<ReducedLinearSolver*>(s->content);
  sun::ScopedTimer timer(self->stats_.seconds);
  ++self->stats_.setups;
  self->last_flag_ = self->do_setup(A);
  return static_cast<int>(self->last_flag_);
}

int ReducedLinearSolver::solve(SUNLinearSolver s, SUNMatrix, N_Vector x, N_Vector b, sunrealtype) {
  auto* self = static_cast<ReducedLinearSolver*>(s->content);
  sun::ScopedTimer timer(self->stats_.seconds);
  ++self->stats_.solves;
  self->last_flag_ = self->do_solve(x, b);
  return static_cast<int>(self->last_flag_);
}

sunindextype ReducedLinearSolver::last_flag(SUNLinearSolver s) {
  return static_cast<ReducedLinearSolver*>(s->content)->last_flag_;
}

int ReducedLinearSolver::space(SUNLinearSolver s, long* lrw, long* liw) {
  auto* self = static_cast<ReducedLinearSolver*>(s->content);
  // The values this object keeps (the factorisations' own storage is not counted).
  *lrw = static_cast<long>(self->s_values_.size() + self->g_values_.size() + 2 * self->n_);
  *liw = static_cast<long>(self->entry_row_.size());
  return SUNLS_SUCCESS;
}

bool ReducedLinearSolver::matches_pattern(SUNMatrix A) const {
  const sun::CscPattern& p = fos_.jacobian_pattern();
  if (SUNMatGetID(A) != SUNMATRIX_SPARSE || SUNSparseMatrix_SparseType(A) != CSC_MAT ||
      SUNSparseMatrix_Rows(A) != p.rows || SUNSparseMatrix_Columns(A) != p.cols ||
      SUNSparseMatrix_NNZ(A) < p.nnz())
    return false;
  const sunindextype* start = SUNSparseMatrix_IndexPointers(A);
  const sunindextype* row = SUNSparseMatrix_IndexValues(A);
  return std::memcmp(start, p.column_start.data(), p.column_start.size() * sizeof(sunindextype)) == 0 &&
         std::memcmp(row, p.row.data(), p.row.size() * sizeof(sunindextype)) == 0;
}

int ReducedLinearSolver::do_setup(SUNMatrix A) {
  factored_ = false;
  if (!matches_pattern(A)) return SUNLS_ILL_INPUT;
  const double* a = SUNSparseMatrix_Data(A);
  const auto& identity = fos_.identity_slots();
  const auto& q_diag = fos_.position_diagonal_slots();
  // gamma from the -gamma I block; the position block must be the identity.
  const double gamma = n_ > 0 ? -a[identity[0]] : 0.0;
  if (n_ > 0 && !(gamma > 0.0 && std::isfinite(gamma))) return SUNLS_ILL_INPUT;
  for (int j = 0; j < n_; ++j) {
    if (a[identity[static_cast<size_t>(j)]] != -gamma) return SUNLS_ILL_INPUT;
    if (a[q_diag[static_cast<size_t>(j)]] != 1.0) return SUNLS_ILL_INPUT;
  }
  gamma_ = gamma;
  // S_ij = m_i (H_ij + gamma G_ij), G = A's (n + i, j) block, H = A's (n + i, n + j) block.
  const Eigen::VectorXd& m = fos_.system().mass();
  const auto& k_slot = fos_.stiffness_slots();
  const auto& d_slot = fos_.damping_slots();
  const auto& u_diag = fos_.velocity_diagonal_slots();
  const bool damped = fos_.system().has_damping();
  const SparsityPattern& sp = fos_.system().pattern();
  for (int j = 0; j < n_; ++j) {
    for (auto p = sp.column_start[static_cast<size_t>(j)];
         p < sp.column_start[static_cast<size_t>(j) + 1]; ++p) {
      const auto k = static_cast<size_t>(p);
      const int i = entry_row_[k];
      const double g = a[k_slot[k]];
      const double h = damped ? a[d_slot[k]] : (i == j ? a[u_diag[static_cast<size_t>(j)]] : 0.0);
      g_values_[k] = g;
      s_values_[k] = m[i] * (h + gamma * g);
    }
  }
  if (factor_.factorize(s_values_.data(), !shift_indefinite_) != SparseFactor::Method::None) {
    factored_ = true;
    return SUNLS_SUCCESS;
  }
  if (shift_indefinite_) {
    shifted_values_ = s_values_;
    for (double mu = 1e-4; mu <= 1e4 * 1.000001; mu *= 10.0) {
      for (int i = 0; i < n_; ++i) {
        const auto k = static_cast<size_t>(diag_slot_[static_cast<size_t>(i)]);
        shifted_values_[k] = s_values_[k] + mu * m[i];
      }
      if (factor_.factorize(shifted_values_.data(), false) == SparseFactor::Method::Cholesky) {
        ++shifted_;
        factored_ = true;
        return SUNLS_SUCCESS;
      }
    }
    if (factor_.factorize(s_values_.data(), true) != SparseFactor::Method::None) {
      factored_ = true;
      return SUNLS_SUCCESS;
    }
  }
  return SUNLS_PACKAGE_FAIL_REC;  // singular (or not finite): the package may retry smaller
}

int ReducedLinearSolver::do_solve(N_Vector x, N_Vector b) {
  if (!factored_) return SUNLS_PACKAGE_FAIL_UNREC;
  const double* bv = N_VGetArrayPointer(b);
  double* xv = N_VGetArrayPointer(x);
  const Eigen::VectorXd& m = fos_.system().mass();
  const SparsityPattern& sp = fos_.system().pattern();
  // rhs = M (b2 - G b1); b1 is kept aside, x may be b.
  std::copy(bv, bv + n_, b1_.begin());
  for (int i = 0; i < n_; ++i) rhs_[static_cast<size_t>(i)] = bv[n_ + i];
  for (int j = 0; j < n_; ++j) {
    const double bj = b1_[static_cast<size_t>(j)];
    if (bj == 0.0) continue;
    for (auto p = sp.column_start[static_cast<size_t>(j)];
         p < sp.column_start[static_cast<size_t>(j) + 1]; ++p)
      rhs_[static_cast<size_t>(entry_row_[static_cast<size_t>(p)])] -= g_values_[static_cast<size_t>(p)] * bj;
  }
  for (int i = 0; i < n_; ++i) rhs_[static_cast<size_t>(i)] *= m[i];
  // x2 = S^-1 rhs, x1 = b1 + gamma x2.
  if (!factor_.solve(rhs_.data(), xv + n_)) return SUNLS_PACKAGE_FAIL_UNREC;
  for (int j = 0; j < n_; ++j) xv[j] = b1_[static_cast<size_t>(j)] + gamma_ * xv[n_ + j];
  return SUNLS_SUCCESS;
}

// ---------------------------------------------------------------------------------------------

NewtonLinearSolver::NewtonLinearSolver(LinearSolverKind kind, const FirstOrderSystem& fos,
                                       N_Vector y, SUNMatrix J, SUNContext ctx)
    : kind_(kind) {
  if (kind == LinearSolverKind::Full)
    klu_ = std::make_unique<sun::TimedKlu>(y, J, ctx);
  else
    reduced_ = std::make_unique<ReducedLinearSolver>(fos, ctx);
}

NewtonLinearSolver::~NewtonLinearSolver() = default;

SUNLinearSolver NewtonLinearSolver::get() const { return klu_ ? klu_->get() : reduced_->get(); }

sun::LinearSolverStats& NewtonLinearSolver::stats() { return klu_ ? klu_->stats() : reduced_->stats(); }

const sun::LinearSolverStats& NewtonLinearSolver::stats() const {
  return klu_ ? klu_->stats() : reduced_->stats();
}

void NewtonLinearSolver::set_shift_indefinite(bool shift) {
  if (reduced_) reduced_->set_shift_indefinite(shift);
}

void NewtonLinearSolver::write_counters(sun::Counters& c) const {
  c.linear_solves = stats().solves;
  c.time_linear = stats().seconds;
  if (reduced_) {
    const SparseFactor::Stats& f = reduced_->factor_stats();
    c.cholesky_factorizations = f.cholesky;
    c.lu_factorizations = f.lu;
    c.not_positive_definite = f.not_positive_definite;
  }
}

}  // namespace pbdbench
