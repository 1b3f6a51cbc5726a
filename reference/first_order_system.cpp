#include "reference/first_order_system.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace pbdbench {

FirstOrderSystem::FirstOrderSystem(const MechanicalSystem& system)
    : system_(system), n_(system.dofs()) {
  const SparsityPattern& sp = system.pattern();
  if (n_ < 0 || sp.n != n_ || static_cast<int>(sp.column_start.size()) != n_ + 1)
    throw std::invalid_argument("FirstOrderSystem: the system's pattern is " +
                                std::to_string(sp.n) + " x " + std::to_string(sp.n) +
                                " but it has " + std::to_string(n_) + " dofs");
  const Eigen::VectorXd& m = system.mass();
  if (m.size() != n_ || !(m.array() > 0.0).all() || !m.allFinite())
    throw std::invalid_argument("FirstOrderSystem: every dof needs a finite mass > 0");
  inv_mass_ = m.cwiseInverse();
  const bool damped = system.has_damping();

  const auto nnz = static_cast<size_t>(sp.nnz());
  k_slot_.assign(nnz, -1);
  d_slot_.assign(nnz, -1);
  entry_row_.assign(nnz, -1);
  identity_slot_.assign(static_cast<size_t>(n_), -1);
  q_diag_slot_.assign(static_cast<size_t>(n_), -1);
  u_diag_slot_.assign(static_cast<size_t>(n_), -1);

  const sunindextype n = n_;
  pattern_.rows = pattern_.cols = 2 * n;
  pattern_.column_start.assign(static_cast<size_t>(2 * n + 1), 0);
  pattern_.row.clear();
  pattern_.row.reserve(static_cast<size_t>(2 * n) + 2 * nnz);
  // Columns 0..n-1: d/dq_j.
  for (sunindextype j = 0; j < n; ++j) {
    pattern_.column_start[static_cast<size_t>(j)] = pattern_.nnz();
    q_diag_slot_[static_cast<size_t>(j)] = pattern_.nnz();
    pattern_.row.push_back(j);  // (j, j): the zero block's diagonal
    for (auto p = sp.column_start[static_cast<size_t>(j)];
         p < sp.column_start[static_cast<size_t>(j) + 1]; ++p) {
      const auto i = sp.row[static_cast<size_t>(p)];
      entry_row_[static_cast<size_t>(p)] = static_cast<int>(i);
      k_slot_[static_cast<size_t>(p)] = pattern_.nnz();
      pattern_.row.push_back(n + i);
    }
  }
  // Columns n..2n-1: d/du_j.
  for (sunindextype j = 0; j < n; ++j) {
    pattern_.column_start[static_cast<size_t>(n + j)] = pattern_.nnz();
    identity_slot_[static_cast<size_t>(j)] = pattern_.nnz();
    pattern_.row.push_back(j);  // (j, n + j) = 1
    if (damped) {
      for (auto p = sp.column_start[static_cast<size_t>(j)];
           p < sp.column_start[static_cast<size_t>(j) + 1]; ++p) {
        d_slot_[static_cast<size_t>(p)] = pattern_.nnz();
        pattern_.row.push_back(n + sp.row[static_cast<size_t>(p)]);
      }
    } else {
      pattern_.row.push_back(n + j);  // (n + j, n + j): explicit zero
    }
  }
  pattern_.column_start[static_cast<size_t>(2 * n)] = pattern_.nnz();
  for (sunindextype j = 0; j < n; ++j) u_diag_slot_[static_cast<size_t>(j)] = pattern_.find(n + j, n + j);
  if (!pattern_.has_full_diagonal())
    throw std::invalid_argument(
        "FirstOrderSystem: the system's pattern lacks a diagonal entry (MechanicalSystem::pattern "
        "must hold every (i, i))");

  q_.resize(n_);
  u_.resize(n_);
  f_.resize(n_);
  k_values_.resize(nnz);
  d_values_.resize(nnz);
}

void FirstOrderSystem::load(const double* y) {
  q_ = Eigen::Map<const Eigen::VectorXd>(y, n_);
  u_ = Eigen::Map<const Eigen::VectorXd>(y + n_, n_);
}

void FirstOrderSystem::rhs(double t, const double* y, double* ydot) {
  load(y);
  system_.force(t, q_, u_, f_);
  Eigen::Map<Eigen::VectorXd>(ydot, n_) = u_;
  Eigen::Map<Eigen::VectorXd>(ydot + n_, n_) = inv_mass_.cwiseProduct(f_);
}

void FirstOrderSystem::jacobian(double t, const double* y, double* values) {
  load(y);
  std::fill(values, values + pattern_.nnz(), 0.0);
  for (int j = 0; j < n_; ++j) values[identity_slot_[static_cast<size_t>(j)]] = 1.0;
  system_.stiffness(t, q_, u_, k_values_);
  for (size_t p = 0; p < k_slot_.size(); ++p)
    values[k_slot_[p]] = -k_values_[p] * inv_mass_[entry_row_[p]];
  if (system_.has_damping()) {
    system_.damping(t, q_, u_, d_values_);
    for (size_t p = 0; p < d_slot_.size(); ++p)
      values[d_slot_[p]] = -d_values_[p] * inv_mass_[entry_row_[p]];
  }
}

void FirstOrderSystem::pack(const Eigen::VectorXd& q, const Eigen::VectorXd& u, double* y) const {
  Eigen::Map<Eigen::VectorXd>(y, n_) = q;
  Eigen::Map<Eigen::VectorXd>(y + n_, n_) = u;
}

void FirstOrderSystem::unpack(const double* y, Eigen::VectorXd& q, Eigen::VectorXd& u) const {
  q = Eigen::Map<const Eigen::VectorXd>(y, n_);
  u = Eigen::Map<const Eigen::VectorXd>(y + n_, n_);
}

}  // namespace pbdbench
