#include "reference/global_newton.hpp"

#include "core/cancel.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/Eigenvalues>
#include <Eigen/IterativeLinearSolvers>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace pbdbench {

namespace {

using Clock = std::chrono::steady_clock;
using Mat12 = Eigen::Matrix<double, 12, 12>;
using SpMat = Eigen::SparseMatrix<double>;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// A row of the augmented Lagrangian at the current positions.
struct RowTerm {
  RowEval e;
  double eps = 0.0;       // kg^-1 (units of C^2 / (kg m^2)): 1 / penalty; 0 = inert row
  double l_eff = 0.0;     // lambda - C / eps, the multiplier the row pushes with now
  bool active = false;    // rigid, or a contact with l_eff > 0
  Mat12 block = Mat12::Zero();  // [grad C grad C^T / eps - l_eff hess C]_+ over the stencil
};

// psi of the header of global_newton.hpp: the row's term of L_A.
double row_potential(const GlobalRow& row, double C, double lambda, double eps) {
  if (!(eps > 0.0)) return 0.0;
  if (!row.inequality || C < eps * lambda) return -lambda * C + C * C / (2.0 * eps);
  return -0.5 * eps * lambda * lambda;
}

// Projection of a symmetric K x K block onto the positive semi-definite cone, in fixed-size
// matrices (no heap allocation).
template <int K>
void project_psd_fixed(Mat12& H) {
  using M = Eigen::Matrix<double, K, K>;
  const M sub = H.template topLeftCorner<K, K>();
  const Eigen::SelfAdjointEigenSolver<M> eig(sub);
  H.template topLeftCorner<K, K>() =
      eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
}

// Projection of a symmetric block onto the positive semi-definite cone (its leading k x k, k = 3
// times the row's particles).
void project_psd(Mat12& H, int k) {
  switch (k) {
    case 3: project_psd_fixed<3>(H); return;
    case 6: project_psd_fixed<6>(H); return;
    case 9: project_psd_fixed<9>(H); return;
    case 12: project_psd_fixed<12>(H); return;
    default: break;
  }
  const Eigen::MatrixXd sub = H.topLeftCorner(k, k);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(sub);
  H.topLeftCorner(k, k) = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
                          eig.eigenvectors().transpose();
}

}  // namespace

struct GlobalNewton::Impl {
  SolverOptions options;
  GlobalLinearSolver kind;
  // CHOLMOD: the factorisation object keeps its symbolic analysis while the pattern stays.
  Eigen::CholmodSupernodalLLT<SpMat, Eigen::Lower> cholmod;
  std::vector<int> pattern_outer, pattern_inner;  // of the last analysed matrix
  bool analysed = false;

  // Terms of the rows at x (eps fixed for the solve).
  void row_terms(const GlobalProblem& problem, const Points& x, const std::vector<double>& lambda,
                 const std::vector<double>& eps, std::vector<RowTerm>& terms) const {
    const auto& rows = problem.rows();
    terms.resize(rows.size());
    for (size_t r = 0; r < rows.size(); ++r) {
      RowTerm& t = terms[r];
      t.e = problem.eval_row(static_cast<int>(r), x);
      t.eps = eps[r];
      t.block.setZero();
      t.active = false;
      if (!(t.eps > 0.0) || !t.e.valid) continue;
      t.l_eff = lambda[r] - t.e.C / t.eps;
      t.active = !rows[r].inequality || t.l_eff > 0.0;
      if (!t.active) continue;
      const int k = 3 * t.e.count;
      Eigen::Matrix<double, 12, 1> g = Eigen::Matrix<double, 12, 1>::Zero();
      for (int i = 0; i < t.e.count; ++i) g.segment<3>(3 * i) = t.e.grad[static_cast<size_t>(i)];
      t.block.topLeftCorner(k, k) = (g.head(k) * g.head(k).transpose()) / t.eps;
      if (t.l_eff != 0.0)
        t.block.topLeftCorner(k, k) -= t.l_eff * problem.row_hessian(static_cast<int>(r), x).topLeftCorner(k, k);
      project_psd(t.block, k);
    }
  }

  // L_A at x for the multipliers lambda.
  double merit(const GlobalProblem& problem, const Points& x, const std::vector<double>& lambda,
               const std::vector<double>& eps) const {
    double L = problem.objective(x);
    const auto& rows = problem.rows();
    for (size_t r = 0; r < rows.size(); ++r) {
      if (!(eps[r] > 0.0)) continue;
      const RowEval e = problem.eval_row(static_cast<int>(r), x);
      L += row_potential(rows[r], e.C, lambda[r], eps[r]);
    }
    return L;
  }

  // The rows' blocks as a sparse matrix over the dofs (every row's block, zero when inactive, so
  // that the pattern changes only with the set of rows).
  SpMat row_matrix(const GlobalProblem& problem, const std::vector<RowTerm>& terms) const {
    std::vector<Eigen::Triplet<double>> triplets;
    for (const RowTerm& t : terms)
      for (int a = 0; a < t.e.count; ++a) {
        const int da = problem.particle_dof(t.e.particles[static_cast<size_t>(a)]);
        if (da < 0) continue;
        for (int b = 0; b < t.e.count; ++b) {
          const int db = problem.particle_dof(t.e.particles[static_cast<size_t>(b)]);
          if (db < 0) continue;
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
              triplets.emplace_back(3 * da + i, 3 * db + j, t.block(3 * a + i, 3 * b + j));
        }
      }
    SpMat R(problem.dofs(), problem.dofs());
    R.setFromTriplets(triplets.begin(), triplets.end());
    return R;
  }

  // Solves A dq = b; returns false when the solver failed. Counts into result.
  bool solve_cholmod(const SpMat& A, const Eigen::VectorXd& b, Eigen::VectorXd& dq,
                     GlobalResult& result) {
    const std::vector<int> outer(A.outerIndexPtr(), A.outerIndexPtr() + A.outerSize() + 1);
    const std::vector<int> inner(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
    if (!analysed || outer != pattern_outer || inner != pattern_inner) {
      cholmod.setShift(0.0);
      cholmod.analyzePattern(A);
      pattern_outer = outer;
      pattern_inner = inner;
      analysed = true;
    }
    cholmod.setShift(0.0);
    cholmod.factorize(A);
    ++result.factorizations;
    if (cholmod.info() != Eigen::Success) {
      // Not positive definite after the projections: only rounding can do this. Shift it.
      double top = 0.0;
      for (int k = 0; k < A.outerSize(); ++k) top = std::max(top, std::abs(A.coeff(k, k)));
      cholmod.setShift(1e-12 * top);
      cholmod.factorize(A);
      ++result.factorizations;
      if (cholmod.info() != Eigen::Success) return false;
    }
    dq = cholmod.solve(b);
    ++result.linear_solves;
    return cholmod.info() == Eigen::Success && dq.allFinite();
  }

  bool solve_cg_assembled(const SpMat& A, const Eigen::VectorXd& b, Eigen::VectorXd& dq,
                          GlobalResult& result) const {
    auto run = [&](auto& cg) {
      cg.setTolerance(options.global_cg_tolerance);
      cg.setMaxIterations(options.global_cg_max_iterations);
      cg.compute(A);
      if (cg.info() != Eigen::Success) return false;
      dq = cg.solve(b);
      result.inner_iterations += cg.iterations();
      ++result.linear_solves;
      // A solve that used up solver.global.cg_max_iterations is kept (an inexact Newton step:
      // CG's iterates from 0 are descent directions on an SPD matrix, and the line search below
      // guards the step), so that a fixed CG budget a step, as Macklin et al. 2019 ran backward
      // Euler (100 Jacobi-preconditioned iterations), is what runs.
      const bool budget_spent = cg.info() == Eigen::NoConvergence && cg.iterations() >= cg.maxIterations();
      return (cg.info() == Eigen::Success || budget_spent) && dq.allFinite();
    };
    if (options.global_cg_preconditioner == "jacobi") {
      Eigen::ConjugateGradient<SpMat, Eigen::Lower | Eigen::Upper, Eigen::DiagonalPreconditioner<double>> cg;
      return run(cg);
    }
    Eigen::ConjugateGradient<SpMat, Eigen::Lower | Eigen::Upper, Eigen::IncompleteCholesky<double>> cg;
    return run(cg);
  }

  // Preconditioned conjugate gradients with the matrix applied term by term (Saad 2003, alg.
  // 9.1), the Jacobi preconditioner, and the same stopping rule as the assembled one:
  // |r| <= tol |b|.
  bool solve_cg_matrix_free(const GlobalProblem& problem, const Points& x,
                            const std::vector<RowTerm>& terms, const Eigen::VectorXd& b,
                            Eigen::VectorXd& dq, GlobalResult& result) const {
    const Eigen::Index n = b.size();
    auto apply = [&](const Eigen::VectorXd& v, Eigen::VectorXd& out) {
      problem.hessian_product(x, v, out);
      for (const RowTerm& t : terms) {
        if (!t.active) continue;
        Eigen::Matrix<double, 12, 1> local = Eigen::Matrix<double, 12, 1>::Zero();
        int dof[4];
        for (int a = 0; a < t.e.count; ++a) {
          dof[a] = problem.particle_dof(t.e.particles[static_cast<size_t>(a)]);
          if (dof[a] >= 0) local.segment<3>(3 * a) = v.segment<3>(3 * dof[a]);
        }
        const Eigen::Matrix<double, 12, 1> y = t.block * local;
        for (int a = 0; a < t.e.count; ++a)
          if (dof[a] >= 0) out.segment<3>(3 * dof[a]) += y.segment<3>(3 * a);
      }
    };
    Eigen::VectorXd diag = problem.hessian_diagonal(x);
    for (const RowTerm& t : terms) {
      if (!t.active) continue;
      for (int a = 0; a < t.e.count; ++a) {
        const int d = problem.particle_dof(t.e.particles[static_cast<size_t>(a)]);
        if (d >= 0)
          for (int i = 0; i < 3; ++i) diag(3 * d + i) += t.block(3 * a + i, 3 * a + i);
      }
    }
    const Eigen::VectorXd inv_diag = diag.cwiseInverse();
    dq.setZero(n);
    Eigen::VectorXd r = b, z = inv_diag.cwiseProduct(r), p = z, Ap(n);
    double rz = r.dot(z);
    const double stop = options.global_cg_tolerance * b.norm();
    ++result.linear_solves;
    if (r.norm() <= stop) return true;
    for (int it = 0; it < options.global_cg_max_iterations; ++it) {
      if (it % 64 == 0) throw_if_cancelled("a conjugate-gradient iteration");
      apply(p, Ap);
      const double pAp = p.dot(Ap);
      if (!(pAp > 0.0)) return false;
      const double a = rz / pAp;
      dq += a * p;
      r -= a * Ap;
      ++result.inner_iterations;
      if (r.norm() <= stop) return dq.allFinite();
      z = inv_diag.cwiseProduct(r);
      const double rz_next = r.dot(z);
      p = z + (rz_next / rz) * p;
      rz = rz_next;
    }
    return dq.allFinite();  // the budget is spent: an inexact Newton step (as assembled above)
  }
};

GlobalNewton::GlobalNewton(const SolverOptions& options, GlobalLinearSolver linear_solver)
    : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->kind = linear_solver;
}

GlobalNewton::~GlobalNewton() = default;

GlobalResult GlobalNewton::solve(const GlobalProblem& problem, Points& x,
                                 std::vector<double>& row_lambda) {
  Impl& im = *impl_;
  const SolverOptions& o = im.options;
  const Clock::time_point t0 = Clock::now();
  GlobalResult result;
  const size_t rows = problem.rows().size();
  row_lambda.resize(rows, 0.0);
  Eigen::VectorXd q = problem.gather(x);
  problem.positions(q, x);

  // eps_r = eta w_r at the start of the solve (0: a row no dynamic particle can move; inert).
  std::vector<double> eps(rows, 0.0);
  for (size_t r = 0; r < rows; ++r) {
    const RowEval e = problem.eval_row(static_cast<int>(r), x);
    eps[r] = o.global_regularization * problem.generalized_inverse_mass(e);
  }

  auto record = [&](int iteration) {
    const GlobalProblem::Residuals res = problem.residuals(x, row_lambda);
    result.residual_g = res.g_norm;
    result.residual_h = res.h_norm;
    result.residual = res.position;
    result.history.push_back({iteration, res.position, seconds_since(t0), result.inner_iterations});
    return res.position;
  };
  if (record(0) <= o.global_tolerance) {
    result.converged = true;
    result.stop = StopReason::Converged;
    return result;
  }

  std::vector<RowTerm> terms;
  std::vector<double> implied;
  Eigen::VectorXd grad, dq;
  Points x_trial;
  for (int it = 1; it <= o.global_max_iterations; ++it) {
    throw_if_cancelled("a Newton iteration");
    // The Newton system of L_A for the current multipliers.
    const Clock::time_point t_lin = Clock::now();
    im.row_terms(problem, x, row_lambda, eps, terms);
    problem.gradient(x, grad);
    for (const RowTerm& t : terms) {
      if (!t.active) continue;
      for (int a = 0; a < t.e.count; ++a) {
        const int d = problem.particle_dof(t.e.particles[static_cast<size_t>(a)]);
        if (d >= 0) grad.segment<3>(3 * d) -= t.l_eff * t.e.grad[static_cast<size_t>(a)];
      }
    }
    const Eigen::VectorXd b = -grad;
    bool solved = false;
    if (im.kind == GlobalLinearSolver::ConjugateGradient && o.global_matrix_free) {
      solved = im.solve_cg_matrix_free(problem, x, terms, b, dq, result);
    } else {
      const SpMat A = problem.hessian(x) + im.row_matrix(problem, terms);
      solved = im.kind == GlobalLinearSolver::Cholmod ? im.solve_cholmod(A, b, dq, result)
                                                      : im.solve_cg_assembled(A, b, dq, result);
    }
    result.time_linear += seconds_since(t_lin);
    if (!solved) {
      result.stop = StopReason::LinearSolverFailed;
      break;
    }

    // Backtracking line search on L_A (Armijo), with an allowance for the rounding of L_A itself
    // near the solution, where its decrease falls below the last digits of its value.
    const double L0 = im.merit(problem, x, row_lambda, eps);
    const double slope = grad.dot(dq);
    double step = 1.0;
    bool accepted = false;
    for (int k = 0; k < 40; ++k) {
      problem.positions(q + step * dq, x_trial);
      const double L = im.merit(problem, x_trial, row_lambda, eps);
      if (std::isfinite(L) &&
          L <= L0 + 1e-4 * step * std::min(slope, 0.0) + 1e-13 * std::abs(L0)) {
        accepted = true;
        break;
      }
      step *= 0.5;
    }
    if (!accepted) {
      result.stop = StopReason::LineSearchFailed;
      break;
    }
    q += step * dq;
    problem.positions(q, x);

    // The multipliers the rows push with at the new point, lambda_r - C_r / eps_r (contacts:
    // max(0, .)): the residual is measured with them, since grad L_A = g(x, those). They become
    // the multipliers (the update of the method of multipliers) once the Newton steps have
    // brought that g part below the tolerance, so that each round of L_A is minimised first.
    implied = row_lambda;
    for (size_t r = 0; r < rows; ++r) {
      if (!(eps[r] > 0.0)) continue;
      const double C = problem.eval_row(static_cast<int>(r), x).C;
      implied[r] = row_lambda[r] - C / eps[r];
      if (problem.rows()[r].inequality) implied[r] = std::max(implied[r], 0.0);
    }
    result.iterations = it;
    const GlobalProblem::Residuals res = problem.residuals(x, implied);
    result.residual_g = res.g_norm;
    result.residual_h = res.h_norm;
    result.residual = res.position;
    result.history.push_back({it, res.position, seconds_since(t0), result.inner_iterations});
    if (res.position <= o.global_tolerance) {
      row_lambda = implied;
      result.converged = true;
      result.stop = StopReason::Converged;
      break;
    }
    if (problem.stationarity_residual(x, implied) <= o.global_tolerance) row_lambda = implied;
  }
  return result;
}

}  // namespace pbdbench
