// global-ceres: the global step (reference/global_problem.hpp) as a sequence of nonlinear least
// squares problems, one per round of the method of multipliers (reference/global_ceres.hpp).
//
// Half the sum of squares of the residual blocks below is, up to a constant,
//   L_A(x; lambda) = E(x) + sum_rigid (C_r^2 / (2 eps_r) - lambda_r C_r)
//                         + sum_contacts psi(C_k, lambda_k)
// (global_newton.hpp), and its gradient is
//   grad L_A = grad E - sum_r grad C_r^T lhat_r,  lhat_r = lambda_r - C_r / eps_r
// (contacts: lhat_k = max(lambda_k - C_k / eps_k, 0)): the stationarity residual g of
// global_problem.hpp at the first-order multiplier estimate lhat (Nocedal and Wright 2006,
// eq. 17.39; sec. 17.4 for the inequalities). Each round minimises L_A for fixed lambda with a
// trust-region Gauss-Newton method (Levenberg-Marquardt, More 1978, or Powell's dogleg; Nocedal
// and Wright 2006, sec. 10.3 and 4.1) and then sets lambda <- lhat.
//
// Gauss-Newton leaves out the curvature of the residuals, sum_i r_i hess r_i, here
// -sum_j lambda_j hess C_j over the compliant terms and the rows: where those forces are small
// against the masses (a simulation step) it converges fast, otherwise only linearly, at a rate of
// about |lambda_j| |hess C_j| / m (Nocedal and Wright 2006, sec. 10.3).
//
// What is measured and when it stops. After every trust-region iteration the current point is
// scored as GlobalProblem::residuals(x, lhat(x)).position: where the solve would be if it stopped
// there and took the multiplier update. That is the history's entry, and the solve stops as soon
// as it is within solver.global.tolerance (the round is ended from the iteration callback). A
// round that cannot get there for fixed lambda (the rows still violated by about
// eps_r |lambda_r - lhat_r|) ends when |grad L_A|_inf <= tolerance min_i m_i, which bounds every
// |g_i| / m_i by the tolerance: the part of the residual the round controls.
//
// The trust region accepts a step by the change of the cost, which is a sum of squares that does
// not vanish at the solution (the mass residuals are m |x - x~|^2 / 2 there): it resolves changes
// down to about 1e-16 of itself, i.e. positions down to about 1e-8 |x* - x~| (sqrt(2e-16 E / m)),
// and a prediction that the step moves by decimetres cannot be taken to 1e-9 m. So the relative
// cost-change test is off (function_tolerance 0: it would also discard the step that trips it,
// often the last useful one); a round also ends after kMaxRejections rejected steps in a row (the
// cost can no longer tell the candidates apart), and the solve after kMaxIdleRounds rounds in a
// row that do not lower the residual (updating lambda from x that no longer moves only walks it
// away). x and lambda are then the last iterate, unconverged.
#include "reference/global_ceres.hpp"

#include "core/cancel.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace pbdbench {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Positions the residual blocks evaluate at: every particle, the non-dynamic ones where the
// caller's x has them, the dynamic ones of a stencil written from its parameter blocks just before
// that stencil is evaluated (GlobalProblem's eval_* read only the rows of their stencil). Ceres
// evaluates the blocks one at a time (num_threads = 1), so one copy serves them all.
struct Scratch {
  Points x;
};

// The distinct dynamic particles of a stencil (model indices), in stencil order: the parameter
// blocks of its residual block. A particle listed twice in a stencil is one block, its gradients
// summed (Ceres requires distinct blocks).
class Stencil {
 public:
  Stencil(const GlobalProblem& problem, const RowEval& e) {
    for (int i = 0; i < e.count; ++i) {
      const int p = e.particles[static_cast<size_t>(i)];
      if (p < 0 || problem.particle_dof(p) < 0 || find(p) >= 0) continue;
      particles_[static_cast<size_t>(count_++)] = p;
    }
  }
  int count() const { return count_; }
  int particle(int k) const { return particles_[static_cast<size_t>(k)]; }
  // The block of model particle p, or -1 when p is not one of them.
  int find(int p) const {
    for (int k = 0; k < count_; ++k)
      if (particles_[static_cast<size_t>(k)] == p) return k;
    return -1;
  }

 private:
  int count_ = 0;
  std::array<int, 4> particles_{-1, -1, -1, -1};
};

// A one-residual block over a stencil's dynamic particles, 3 parameters each.
class StencilCost : public ceres::CostFunction {
 public:
  StencilCost(const GlobalProblem& problem, const RowEval& layout, Scratch* scratch)
      : problem_(&problem), stencil_(problem, layout), scratch_(scratch) {
    set_num_residuals(1);
    for (int k = 0; k < stencil_.count(); ++k) mutable_parameter_block_sizes()->push_back(3);
  }
  const Stencil& stencil() const { return stencil_; }

 protected:
  // Writes the parameter blocks into the scratch positions.
  void load(double const* const* parameters) const {
    for (int k = 0; k < stencil_.count(); ++k)
      scratch_->x.row(stencil_.particle(k)) = Eigen::Map<const Vec3>(parameters[k]).transpose();
  }
  // jacobians[k] (1 x 3) = scale dC/dx of the k-th block. Where the gradient is undefined
  // (RowEval::valid false: coincident particles, a degenerate triangle) it is zero, as in
  // GlobalProblem's own gradient: the step leaves the term as it is.
  void write_jacobians(const RowEval& e, double scale, double** jacobians) const {
    for (int k = 0; k < stencil_.count(); ++k)
      if (jacobians[k] != nullptr) std::fill_n(jacobians[k], 3, 0.0);
    if (scale == 0.0 || !e.valid) return;
    for (int i = 0; i < e.count; ++i) {
      const int k = stencil_.find(e.particles[static_cast<size_t>(i)]);
      if (k < 0 || jacobians[k] == nullptr) continue;
      for (int a = 0; a < 3; ++a) jacobians[k][a] += scale * e.grad[static_cast<size_t>(i)][a];
    }
  }

  const GlobalProblem* problem_;
  Stencil stencil_;
  Scratch* scratch_;
};

// sqrt(m_i) (x_i - x~_i): half its square is particle i's part of 1/2 |x - x~|_M^2.
class MassCost final : public ceres::SizedCostFunction<3, 3> {
 public:
  MassCost(const Vec3& sqrt_mass, const Vec3& target) : sqrt_mass_(sqrt_mass), target_(target) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    for (int a = 0; a < 3; ++a) residuals[a] = sqrt_mass_[a] * (parameters[0][a] - target_[a]);
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      std::fill_n(jacobians[0], 9, 0.0);  // row-major 3 x 3
      for (int a = 0; a < 3; ++a) jacobians[0][4 * a] = sqrt_mass_[a];
    }
    return true;
  }

 private:
  Vec3 sqrt_mass_;
  Vec3 target_;
};

// C_j(x) / sqrt(alpha~_j): half its square is the constraint's energy C^2 / (2 alpha~).
class CompliantCost final : public StencilCost {
 public:
  CompliantCost(const GlobalProblem& problem, int constraint, const RowEval& layout,
                Scratch* scratch)
      : StencilCost(problem, layout, scratch),
        constraint_(constraint),
        scale_(1.0 / std::sqrt(problem.alpha_tilde(constraint))) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    load(parameters);
    const RowEval e = problem_->eval_compliant(constraint_, scratch_->x);
    if (!std::isfinite(e.C)) return false;  // a trial point the step must not take
    residuals[0] = scale_ * e.C;
    if (jacobians != nullptr) write_jacobians(e, scale_, jacobians);
    return true;
  }

 private:
  int constraint_;
  double scale_;
};

// sqrt(h beta_j) grad C_j(x_n) . (x - x_n), linear in x: half its square is the constraint's part
// of h/2 (x - x_n)^T D (x - x_n) with the gradient frozen at the start of the step (Macklin et al.
// 2016, eq. 26). Only the dynamic particles enter (D is over the dofs).
class DampingCost final : public StencilCost {
 public:
  DampingCost(const GlobalProblem& problem, const RowEval& at_start, double scale)
      : StencilCost(problem, at_start, nullptr), scale_(scale) {
    for (int k = 0; k < stencil_.count(); ++k) {
      grad_[static_cast<size_t>(k)].setZero();
      origin_[static_cast<size_t>(k)] = problem.x_start().row(stencil_.particle(k)).transpose();
    }
    if (!at_start.valid) return;  // no gradient at x_n: no damping for this constraint
    for (int i = 0; i < at_start.count; ++i) {
      const int k = stencil_.find(at_start.particles[static_cast<size_t>(i)]);
      if (k >= 0) grad_[static_cast<size_t>(k)] += at_start.grad[static_cast<size_t>(i)];
    }
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    double r = 0.0;
    for (int k = 0; k < stencil_.count(); ++k)
      r += grad_[static_cast<size_t>(k)].dot(Eigen::Map<const Vec3>(parameters[k]) -
                                             origin_[static_cast<size_t>(k)]);
    residuals[0] = scale_ * r;
    if (jacobians != nullptr)
      for (int k = 0; k < stencil_.count(); ++k)
        if (jacobians[k] != nullptr)
          for (int a = 0; a < 3; ++a) jacobians[k][a] = scale_ * grad_[static_cast<size_t>(k)][a];
    return true;
  }

 private:
  double scale_;
  std::array<Vec3, 4> grad_{};
  std::array<Vec3, 4> origin_{};
};

// A row of the constrained set in the augmented Lagrangian, lambda_r read from the solve's
// multipliers (fixed during a round):
//   rigid:   sqrt(1/eps) (C - eps lambda)
//   contact: sqrt(1/eps) min(C - eps lambda, 0), zero with a zero Jacobian when the contact does
//            not push (its half square is then the constant eps lambda^2 / 2 of psi).
class RowCost final : public StencilCost {
 public:
  RowCost(const GlobalProblem& problem, int row, const RowEval& layout, Scratch* scratch,
          double eps, const double* lambda)
      : StencilCost(problem, layout, scratch),
        row_(row),
        inequality_(problem.rows()[static_cast<size_t>(row)].inequality),
        eps_(eps),
        scale_(1.0 / std::sqrt(eps)),
        lambda_(lambda) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    load(parameters);
    const RowEval e = problem_->eval_row(row_, scratch_->x);
    if (!std::isfinite(e.C)) return false;
    const double v = e.C - eps_ * (*lambda_);
    const bool pushes = !inequality_ || v < 0.0;
    residuals[0] = pushes ? scale_ * v : 0.0;
    if (jacobians != nullptr) write_jacobians(e, pushes ? scale_ : 0.0, jacobians);
    return true;
  }

 private:
  int row_;
  bool inequality_;
  double eps_;
  double scale_;
  const double* lambda_;
};

// Consecutive rejected trust-region steps after which a round is over. Levenberg-Marquardt
// divides its radius by 2, 4, 8, ... on successive rejections (2^66 after 11 of them), dogleg
// halves it: either way the model has stopped predicting the cost long before.
constexpr int kMaxRejections = 12;

// Rounds in a row that do not lower the residual after which the solve stops.
constexpr int kMaxIdleRounds = 3;

// The solve's state shared by the rounds and the iteration callback.
class CeresSolve final : public ceres::IterationCallback {
 public:
  CeresSolve(const GlobalProblem& problem, const SolverOptions& options, Points& x,
             std::vector<double>& row_lambda, GlobalResult& result)
      : problem_(problem),
        tolerance_(options.global_tolerance),
        start_(Clock::now()),
        lambda_(row_lambda),
        result_(result),
        current_(x),
        estimate_(row_lambda) {
    // Penalties eps_r = eta w_r from the generalised inverse masses at the starting point; a row
    // with w_r = 0 (no dynamic particle, or a zero gradient) cannot be moved and is left out.
    const double eta = options.global_regularization;
    eps_.assign(problem.rows().size(), 0.0);
    for (size_t r = 0; r < eps_.size(); ++r) {
      const double w = problem.generalized_inverse_mass(problem.eval_row(static_cast<int>(r), x));
      if (w > 0.0 && std::isfinite(w)) eps_[r] = eta * w;
    }
  }

  const std::vector<double>& eps() const { return eps_; }
  bool has_rows() const {
    return std::any_of(eps_.begin(), eps_.end(), [](double e) { return e > 0.0; });
  }
  double elapsed() const { return seconds_since(start_); }
  long lm_iterations() const { return lm_iterations_; }

  // The first-order multiplier estimate lhat at positions y for the current lambda; rows left out
  // keep theirs.
  void estimate(const Points& y, std::vector<double>& out) const {
    out = lambda_;
    for (size_t r = 0; r < eps_.size(); ++r) {
      if (eps_[r] <= 0.0) continue;
      const double C = problem_.eval_row(static_cast<int>(r), y).C;
      double l = lambda_[r] - C / eps_[r];
      if (problem_.rows()[r].inequality) l = std::max(l, 0.0);
      out[r] = l;
    }
  }

  // Points the callback at the parameter vector Ceres updates in place.
  void watch(const std::vector<double>* q) { q_ = q; }

  // After every trust-region iteration (iteration 0 is the round's starting point, already
  // recorded): score the current point; end the round once the whole solve is converged, or once
  // the trust region has been shrunk kMaxRejections times in a row (the cost can no longer tell
  // the candidate steps apart; the best point is kept).
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    if (cancel_requested()) return ceres::SOLVER_ABORT;  // Solve() returns; the caller throws
    if (summary.iteration == 0) {
      rejections_ = 0;
      return ceres::SOLVER_CONTINUE;
    }
    ++lm_iterations_;
    rejections_ = summary.step_is_successful ? 0 : rejections_ + 1;
    const std::vector<int>& dynamic = problem_.energy().dynamic_particles();
    for (size_t b = 0; b < dynamic.size(); ++b)
      for (int a = 0; a < 3; ++a) current_(dynamic[b], a) = (*q_)[3 * b + static_cast<size_t>(a)];
    estimate(current_, estimate_);
    const double residual = problem_.residuals(current_, estimate_).position;
    result_.history.push_back({static_cast<int>(result_.history.size()), residual, elapsed(),
                               lm_iterations_});
    return residual <= tolerance_ || rejections_ >= kMaxRejections
               ? ceres::SOLVER_TERMINATE_SUCCESSFULLY
               : ceres::SOLVER_CONTINUE;
  }

 private:
  const GlobalProblem& problem_;
  double tolerance_;
  Clock::time_point start_;
  std::vector<double>& lambda_;
  GlobalResult& result_;
  std::vector<double> eps_;  // (rows) eps_r, 0 for a row left out
  Points current_;           // every particle at the current iterate
  std::vector<double> estimate_;
  const std::vector<double>* q_ = nullptr;
  long lm_iterations_ = 0;
  int rejections_ = 0;  // consecutive unsuccessful iterations of the current round
};

ceres::TrustRegionStrategyType strategy_of(const std::string& method) {
  if (method == "levenberg_marquardt") return ceres::LEVENBERG_MARQUARDT;
  if (method == "dogleg") return ceres::DOGLEG;
  throw std::invalid_argument("solver.global.ceres_method = \"" + method +
                              "\" is not \"levenberg_marquardt\" or \"dogleg\"");
}

}  // namespace

GlobalResult solve_global_ceres(const GlobalProblem& problem, const SolverOptions& options,
                                Points& x, std::vector<double>& row_lambda) {
  const Model& model = problem.model();
  if (x.rows() != model.particle_count())
    throw std::invalid_argument("global-ceres: x has " + std::to_string(x.rows()) +
                                " rows, the model " + std::to_string(model.particle_count()) +
                                " particles");
  if (row_lambda.size() != problem.rows().size())
    throw std::invalid_argument("global-ceres: row_lambda has " +
                                std::to_string(row_lambda.size()) + " entries, the step " +
                                std::to_string(problem.rows().size()) + " rows");
  if (!(options.global_regularization > 0.0))
    throw std::invalid_argument("global-ceres: solver.global.regularization must be > 0");
  for (const int j : problem.compliant())
    if (is_strain_kind(model.constraints[static_cast<size_t>(j)].kind))
      throw std::invalid_argument(
          "global-ceres cannot solve " + std::string(to_string(model.constraints[static_cast<size_t>(j)].kind)) +
          " constraint " + std::to_string(j) +
          " (a strain vector of a stvk or linear element): its least-squares costs are scalar; "
          "use global-cholmod or global-cg");
  const ceres::TrustRegionStrategyType strategy = strategy_of(options.global_ceres_method);
  if (!ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE))
    throw std::runtime_error("global-ceres: this Ceres has no SuiteSparse");

  GlobalResult result;
  CeresSolve solve(problem, options, x, row_lambda, result);
  const double tolerance = options.global_tolerance;
  const auto finish = [&]() {
    const GlobalProblem::Residuals res = problem.residuals(x, row_lambda);
    result.residual_g = res.g_norm;
    result.residual_h = res.h_norm;
    result.residual = res.position;
    result.converged = res.position <= tolerance;
    if (result.converged) result.stop = StopReason::Converged;
    result.inner_iterations = solve.lm_iterations();
    return result;
  };

  result.history.push_back({0, problem.residuals(x, row_lambda).position, solve.elapsed(), 0});
  if (result.history[0].residual <= tolerance || problem.dofs() == 0) return finish();

  // The parameters: one block of 3 per dynamic particle, in dof order.
  const std::vector<int>& dynamic = problem.energy().dynamic_particles();
  std::vector<double> q(static_cast<size_t>(problem.dofs()));
  for (size_t b = 0; b < dynamic.size(); ++b)
    for (int a = 0; a < 3; ++a) q[3 * b + static_cast<size_t>(a)] = x(dynamic[b], a);
  const auto block = [&](int particle) {
    return q.data() + 3 * static_cast<ptrdiff_t>(problem.particle_dof(particle));
  };
  solve.watch(&q);
  Scratch scratch{x};

  ceres::Problem least_squares;  // owns the cost functions
  for (const int p : dynamic) least_squares.AddParameterBlock(block(p), 3);
  const auto add = [&](StencilCost* cost) {
    const Stencil& s = cost->stencil();
    if (s.count() == 0) {  // nothing dynamic: a constant, not part of the minimisation
      delete cost;
      return;
    }
    std::vector<double*> blocks;
    for (int k = 0; k < s.count(); ++k) blocks.push_back(block(s.particle(k)));
    least_squares.AddResidualBlock(cost, nullptr, blocks);
  };

  const Eigen::VectorXd& mass = problem.mass();
  double min_mass = std::numeric_limits<double>::infinity();
  for (const int p : dynamic) {
    const Eigen::Index d = 3 * static_cast<Eigen::Index>(problem.particle_dof(p));
    const Vec3 m = mass.segment<3>(d);
    min_mass = std::min(min_mass, m.minCoeff());
    least_squares.AddResidualBlock(
        new MassCost(m.cwiseSqrt(), problem.x_pred().row(p).transpose()), nullptr, block(p));
  }
  for (const int j : problem.compliant())
    add(new CompliantCost(problem, j, problem.eval_compliant(j, x), &scratch));
  for (const int j : problem.damped()) {
    const double beta = model.constraints[static_cast<size_t>(j)].damping;
    if (!(beta > 0.0)) continue;
    add(new DampingCost(problem, problem.eval_compliant(j, problem.x_start()),
                        std::sqrt(problem.h() * beta)));
  }
  for (size_t r = 0; r < solve.eps().size(); ++r) {
    if (solve.eps()[r] <= 0.0) continue;
    add(new RowCost(problem, static_cast<int>(r), problem.eval_row(static_cast<int>(r), x),
                    &scratch, solve.eps()[r], &row_lambda[r]));
  }

  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = strategy;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  so.num_threads = 1;  // one evaluation order: the same bits every run
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.max_num_iterations = options.global_max_iterations;
  so.function_tolerance = 0.0;  // off (see the top of this file)
  // |grad L_A|_inf <= tolerance min_i m_i bounds every |g_i| / m_i by the tolerance at lhat.
  so.gradient_tolerance = tolerance * min_mass;
  so.parameter_tolerance = 1e-14;  // a step of 1e-14 |x| is rounding
  so.update_state_every_iteration = true;
  so.callbacks.push_back(&solve);
  std::string message;
  if (!so.IsValid(&message)) throw std::invalid_argument("global-ceres: " + message);

  // Rounds of the method of multipliers; a single one without rows. kMaxIdleRounds rounds in a
  // row that end no lower than the best residual so far end the solve (see the top of this file).
  const int max_rounds = std::max(1, options.global_max_iterations);
  double best = result.history[0].residual;
  int idle = 0;
  result.stop = StopReason::IterationLimit;  // the rounds ran out, unless one of the ends below
  for (int round = 1; round <= max_rounds; ++round) {
    ceres::Solver::Summary summary;
    ceres::Solve(so, &least_squares, &summary);
    throw_if_cancelled("a Levenberg-Marquardt iteration");
    result.iterations = round;
    // SPARSE_NORMAL_CHOLESKY factorises J^T J + mu D afresh for every linear solve (the symbolic
    // analysis once per Solve call), so factorisations and linear solves are the same count.
    result.linear_solves += std::max(0, summary.num_linear_solves);
    result.factorizations += std::max(0, summary.num_linear_solves);
    result.time_linear += std::max(0.0, summary.linear_solver_time_in_seconds);
    for (size_t b = 0; b < dynamic.size(); ++b)
      for (int a = 0; a < 3; ++a) x(dynamic[b], a) = q[3 * b + static_cast<size_t>(a)];
    if (solve.has_rows()) {
      std::vector<double> updated;
      solve.estimate(x, updated);
      // Copied in place: the RowCosts point into row_lambda's storage.
      std::copy(updated.begin(), updated.end(), row_lambda.begin());
    }
    const double residual = problem.residuals(x, row_lambda).position;
    if (summary.termination_type == ceres::FAILURE) result.stop = StopReason::LinearSolverFailed;
    else if (summary.termination_type == ceres::NO_CONVERGENCE) result.stop = StopReason::IterationLimit;
    else result.stop = StopReason::Stalled;  // the trust region's own tests ended the round
    if (residual <= tolerance || !solve.has_rows() || summary.termination_type == ceres::FAILURE)
      break;
    result.stop = StopReason::IterationLimit;
    if (residual < best) {
      best = residual;
      idle = 0;
    } else if (++idle >= kMaxIdleRounds) {
      result.stop = StopReason::Stalled;
      break;
    }
  }
  return finish();
}

}  // namespace pbdbench
