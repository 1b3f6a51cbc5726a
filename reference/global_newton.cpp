#include "reference/global_newton.hpp"

#include "core/cancel.hpp"
#include "core/psd_projection.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/IterativeLinearSolvers>
#include <omp.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

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

// Projection of a row's block onto the positive semi-definite cone (its leading k x k, k = 3
// times the row's particles; core/psd_projection.hpp). A four-particle row (a rigid volume) does
// not see translations: its projection goes through the 9 x 9 restriction.
template <int K>
void project_corner(Mat12& H) {
  Eigen::Matrix<double, K, K> sub = H.topLeftCorner<K, K>();
  psd::project_psd<K>(sub);
  H.topLeftCorner<K, K>() = sub;
}

void project_row_block(Mat12& H, int k) {
  switch (k) {
    case 3: project_corner<3>(H); return;
    case 6: project_corner<6>(H); return;
    case 9: project_corner<9>(H); return;
    case 12: psd::project_psd_translation_free(H); return;
    default: break;
  }
  throw std::logic_error("project_row_block: a row of " + std::to_string(k / 3) + " particles");
}

// solver.global.factor_reuse preconditions with an earlier factorisation only where a
// factorisation costs at least this many iterations of the preconditioned solve (two triangular
// solves through L and a product with A), in flops: the cost of an iteration that converges
// slowly or not at all is then small against the factorisation it may save. The ratio is every
// step's factor_cost_ratio series: 0.34 to 1.91 on balls_in_bowl (with its contacts) and 0.67 on
// hanging_chain (a factorisation is about as cheap as one iteration: reuse made balls_in_bowl
// slower), 4.9 on cantilever_fem, 10.5 on cantilever_beam, 12 on soft_cube_drop and 54 on the
// 64 x 64 hanging_cloth (each global-cholmod run file's factor_cost_ratio series).
constexpr double kReuseCostRatio = 2.0;

// Debian's CHOLMOD is built with num_threads(4) on its OpenMP regions (CHOLMOD_OMP_NUM_THREADS),
// whatever the machine: on a 2-core machine shared with other runs its four threads spin between
// regions and take the cores from the step. The global solvers step on one thread (their BLAS,
// ATLAS, is serial, and the regions are copies and scatters of the factor), so CHOLMOD's calls run
// with max-active-levels 0: every region on the calling thread alone, the same bits as with four
// (the frames of cantilever_beam with and without OMP_THREAD_LIMIT=1). The setting is an ICV of the calling thread, restored on leaving.
class SerialOpenMp {
 public:
  SerialOpenMp() : saved_(omp_get_max_active_levels()) { omp_set_max_active_levels(0); }
  ~SerialOpenMp() { omp_set_max_active_levels(saved_); }
  SerialOpenMp(const SerialOpenMp&) = delete;
  SerialOpenMp& operator=(const SerialOpenMp&) = delete;

 private:
  int saved_;
};

}  // namespace

struct GlobalNewton::Impl {
  SolverOptions options;
  GlobalLinearSolver kind;
  // CHOLMOD: the factorisation object keeps its symbolic analysis while the pattern stays. A is
  // handed over as its upper triangle (stype 1): cholmod_factorize then forms the permuted lower
  // triangle it factorises, tril(P A P^T), with one transpose; from the lower triangle (stype -1)
  // it takes two (triu(P A P^T), then its transpose). The same matrix either way.
  Eigen::CholmodSupernodalLLT<SpMat, Eigen::Upper> cholmod;
  bool analysed = false;  // cholmod holds the analysis of A's pattern
  // cholmod holds a factorisation of an earlier Newton matrix on this pattern, good enough to
  // precondition the next solve (solver.global.factor_reuse; false: factorise the next one).
  bool factor_usable = false;
  // The flops of a factorisation over those of one iteration of the preconditioned solve
  // (4 nnz(L) for the two triangular solves, 2 nnz(A) for the product), from CHOLMOD's analysis
  // of this pattern (set with it; reported in the step's factor_cost_ratio). Reusing pays where
  // it is at least kReuseCostRatio.
  double cost_ratio = std::numeric_limits<double>::quiet_NaN();
  bool reuse_pays = false;
  Eigen::VectorXd pcg_r, pcg_z, pcg_p, pcg_ap;  // the preconditioned solve's vectors

  // The Newton matrix, both triangles, in a pattern kept between iterations and steps: the
  // energy's (fixed) and every row's blocks (zero when inactive), rebuilt only when the rows'
  // stencils change (contacts come and go); its values are filled in place.
  SpMat A;
  bool have_pattern = false;
  std::vector<int> row_dofs;                 // the dof blocks of each row's stencil (-1: none)
  std::vector<std::int64_t> energy_slot;     // energy pattern position -> index into A's values
  std::vector<std::int64_t> row_slot;        // per row, (a, b) of its stencil: column offset of
                                             // entry (3 dof_a, 3 dof_b) in A, -1 for none
  std::vector<double> hessian_values, row_sum;  // scratch (energy pattern; A's pattern)

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
      project_row_block(t.block, k);
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

  // The rows' stencils as dof blocks, 4 entries a row (-1 past its count or where a particle is
  // not dynamic).
  static void stencil_dofs(const GlobalProblem& problem, const std::vector<RowTerm>& terms,
                           std::vector<int>& out) {
    out.assign(4 * terms.size(), -1);
    for (size_t r = 0; r < terms.size(); ++r)
      for (int a = 0; a < terms[r].e.count; ++a)
        out[4 * r + static_cast<size_t>(a)] =
            problem.particle_dof(terms[r].e.particles[static_cast<size_t>(a)]);
  }

  // A's pattern, the energy's entries and the rows' blocks, and the slots that fill it. Returns
  // true when the pattern was (re)built, so that CHOLMOD analyses it again.
  bool build_pattern(const GlobalProblem& problem, const std::vector<RowTerm>& terms) {
    std::vector<int> dofs;
    stencil_dofs(problem, terms, dofs);
    if (have_pattern && dofs == row_dofs) return false;
    row_dofs = std::move(dofs);
    const SparsityPattern& p = problem.energy().hessian_pattern();
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(static_cast<size_t>(p.nnz()));
    for (int c = 0; c < p.n; ++c)
      for (std::int64_t k = p.column_start[static_cast<size_t>(c)];
           k < p.column_start[static_cast<size_t>(c) + 1]; ++k)
        triplets.emplace_back(static_cast<int>(p.row[static_cast<size_t>(k)]), c, 0.0);
    for (size_t r = 0; r < terms.size(); ++r)
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const int da = row_dofs[4 * r + static_cast<size_t>(a)];
          const int db = row_dofs[4 * r + static_cast<size_t>(b)];
          if (da < 0 || db < 0) continue;
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) triplets.emplace_back(3 * da + i, 3 * db + j, 0.0);
        }
    A.resize(problem.dofs(), problem.dofs());
    A.setFromTriplets(triplets.begin(), triplets.end());
    A.makeCompressed();
    const int* outer = A.outerIndexPtr();
    const int* inner = A.innerIndexPtr();
    auto position = [&](int row, int col) -> std::int64_t {
      const int* begin = inner + outer[col];
      const int* end = inner + outer[col + 1];
      return static_cast<std::int64_t>(std::lower_bound(begin, end, row) - inner);
    };
    energy_slot.resize(static_cast<size_t>(p.nnz()));
    for (int c = 0; c < p.n; ++c)
      for (std::int64_t k = p.column_start[static_cast<size_t>(c)];
           k < p.column_start[static_cast<size_t>(c) + 1]; ++k)
        energy_slot[static_cast<size_t>(k)] = position(static_cast<int>(p.row[static_cast<size_t>(k)]), c);
    // Every block of A is whole (3 x 3) and the three columns of a dof block share their rows,
    // so one offset within the column serves the block's nine entries.
    row_slot.assign(16 * terms.size(), -1);
    for (size_t r = 0; r < terms.size(); ++r)
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const int da = row_dofs[4 * r + static_cast<size_t>(a)];
          const int db = row_dofs[4 * r + static_cast<size_t>(b)];
          if (da >= 0 && db >= 0)
            row_slot[16 * r + static_cast<size_t>(4 * a + b)] = position(3 * da, 3 * db) - outer[3 * db];
        }
    have_pattern = true;
    analysed = false;
    factor_usable = false;
    return true;
  }

  // A = the energy's Hessian (projected) + the rows' blocks, in place.
  void assemble(const GlobalProblem& problem, const Points& x, const std::vector<RowTerm>& terms) {
    build_pattern(problem, terms);
    problem.hessian_values(x, hessian_values);
    double* values = A.valuePtr();
    const int* outer = A.outerIndexPtr();
    std::fill(values, values + A.nonZeros(), 0.0);
    for (size_t k = 0; k < hessian_values.size(); ++k) values[energy_slot[k]] = hessian_values[k];
    if (terms.empty()) return;
    // The rows' sums first, row by row, then added to the energy's: the order of the sparse sum
    // H + R this replaces.
    row_sum.assign(static_cast<size_t>(A.nonZeros()), 0.0);
    for (size_t r = 0; r < terms.size(); ++r)
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const std::int64_t off = row_slot[16 * r + static_cast<size_t>(4 * a + b)];
          if (off < 0) continue;
          const int db = row_dofs[4 * r + static_cast<size_t>(b)];
          for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i)
              row_sum[static_cast<size_t>(outer[3 * db + j] + off + i)] += terms[r].block(3 * a + i, 3 * b + j);
        }
    for (size_t k = 0; k < row_sum.size(); ++k) values[k] += row_sum[k];
  }

  // Solves A dq = b; returns false when the solver failed. Counts into result.
  bool solve_cholmod(const SpMat& A, const Eigen::VectorXd& b, Eigen::VectorXd& dq,
                     GlobalResult& result) {
    const SerialOpenMp serial;
    if (!analysed) {
      cholmod.setShift(0.0);
      // The fill-reducing ordering: CHOLMOD tries AMD, METIS and its own nested dissection
      // (NESDIS: METIS's node separators, then constrained minimum degree on the whole graph) and
      // keeps the one with the fewest nonzeros in L (its default tries METIS only when AMD's fill
      // is poor, and keeps AMD on the 64 x 64 cloth: 6.7e8 flops a factorisation against METIS's
      // 4.5e8). On the cloth NESDIS wins: 1.880 M nonzeros against METIS's 1.897 M, as many flops
      // (4.55e8), and a factorisation faster with ATLAS (global/* of bench_reference). All three are
      // deterministic.
      cholmod.cholmod().nmethods = 3;
      cholmod.cholmod().method[0].ordering = CHOLMOD_AMD;
      cholmod.cholmod().method[1].ordering = CHOLMOD_METIS;
      cholmod.cholmod().method[2].ordering = CHOLMOD_NESDIS;
      cholmod.analyzePattern(A);
      analysed = true;
      const cholmod_common& c = cholmod.cholmod();
      cost_ratio = c.fl / (4.0 * c.lnz + 2.0 * static_cast<double>(A.nonZeros()));
      reuse_pays = cost_ratio >= kReuseCostRatio;
    }
    result.factor_cost_ratio = cost_ratio;
    if (options.global_factor_reuse && reuse_pays && factor_usable &&
        solve_with_last_factor(A, b, dq, result))
      return true;
    factor_usable = false;
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
    factor_usable = cholmod.info() == Eigen::Success;
    return cholmod.info() == Eigen::Success && dq.allFinite();
  }

  // A dq = b by conjugate gradients preconditioned with the factorisation cholmod holds, M = L L^T
  // of an earlier Newton matrix on the same pattern (Saad 2003, alg. 9.1, from dq = 0), to
  // |b - A dq| <= reuse_tolerance |b|. On a large pattern a factorisation costs as much as tens
  // of such iterations (a 64 x 64 cloth: 4.5e8 flops against two triangular solves through
  // 1.9e6 nonzeros and a product with A), and the Newton matrices of consecutive iterations are
  // close, so a few iterations replace it. A solve that needed more than reuse_iterations marks
  // the factor stale (the next system is factorised); one not converged at 4 times that, one
  // whose matrix showed a direction of non-positive curvature, or one that is not finite returns
  // false and this system is factorised. Every decision counts iterations only: the same inputs
  // give the same bits. The Newton steps are those of a direct solve to the tolerance (the same
  // Newton iterations, positions within 4e-14 m on the 64 x 64 cloth, the cantilever beam,
  // cantilever_fem and soft_cube_drop, against solver.global.factor_reuse = false).
  bool solve_with_last_factor(const SpMat& A, const Eigen::VectorXd& b, Eigen::VectorXd& dq,
                              GlobalResult& result) {
    const int stale_after = options.global_reuse_iterations;
    const int give_up = 4 * stale_after;
    const double stop = options.global_reuse_tolerance * b.norm();
    dq.setZero(b.size());
    pcg_r = b;
    if (!(pcg_r.norm() > stop)) {
      ++result.linear_solves;
      return true;
    }
    pcg_z = cholmod.solve(pcg_r);
    if (cholmod.info() != Eigen::Success) return false;
    pcg_p = pcg_z;
    double rz = pcg_r.dot(pcg_z);
    for (int it = 1; it <= give_up; ++it) {
      pcg_ap.noalias() = A * pcg_p;  // A holds both triangles
      const double pap = pcg_p.dot(pcg_ap);
      if (!(pap > 0.0) || !(rz > 0.0)) {
        result.inner_iterations += it;
        return false;
      }
      const double a = rz / pap;
      dq += a * pcg_p;
      pcg_r -= a * pcg_ap;
      if (pcg_r.norm() <= stop) {
        result.inner_iterations += it;
        if (!dq.allFinite()) return false;
        ++result.linear_solves;
        if (it > stale_after) factor_usable = false;
        return true;
      }
      pcg_z = cholmod.solve(pcg_r);
      const double rz_next = pcg_r.dot(pcg_z);
      pcg_p = pcg_z + (rz_next / rz) * pcg_p;
      rz = rz_next;
    }
    result.inner_iterations += give_up;
    return false;
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

void GlobalNewton::forget_factorisation() { impl_->factor_usable = false; }

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
      im.assemble(problem, x, terms);
      solved = im.kind == GlobalLinearSolver::Cholmod ? im.solve_cholmod(im.A, b, dq, result)
                                                      : im.solve_cg_assembled(im.A, b, dq, result);
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
