// ref-static: static equilibrium at each output time by KINSOL. docs/reference.md, "ref-static".
#include "reference/ref_static.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <stdexcept>
#include <string>

#include <kinsol/kinsol.h>
#include <kinsol/kinsol_ls.h>
#include <sunmatrix/sunmatrix_sparse.h>

#include "core/cancel.hpp"
#include "reference/integrators.hpp"
#include "reference/ref_common.hpp"

namespace pbdbench {

using sun::check;
using sun::Flags;

namespace {

constexpr double kForceTestFraction = 1e-2;  // fnormtol, see ref_static.hpp
constexpr double kStiffnessFloor = 1e-8;     // k_i >= this times max_j K_jj

sun::CscPattern csc_of(const SparsityPattern& p) {
  sun::CscPattern c;
  c.rows = c.cols = p.n;
  c.column_start.assign(p.column_start.begin(), p.column_start.end());
  c.row.assign(p.row.begin(), p.row.end());
  return c;
}

}  // namespace

struct StaticSolver::Impl {
  Impl(const MechanicalSystem& sys, const StaticSettings& s, ProjectedStiffness proj)
      : system(sys),
        settings(s),
        projected(std::move(proj)),
        n(sys.dofs()),
        pattern(csc_of(sys.pattern())),
        u(n, ctx),
        uscale(n, ctx),
        fscale(n, ctx),
        K(pattern, ctx),
        klu(u, K, ctx),
        B(pattern, ctx),
        b(n, ctx),
        p(n, ctx),
        fallback_klu(p, B, ctx) {
    q_buf.resize(n);
    zero_u = Eigen::VectorXd::Zero(n);
    f_buf.resize(n);
    k_values.resize(static_cast<size_t>(pattern.nnz()));
    diag_slot.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) diag_slot[static_cast<size_t>(i)] = pattern.find(i, i);

    mem = sun::Memory(sun::check_ptr(KINCreate(ctx), "KINCreate"), &KINFree);
    check(KINSetErrHandlerFn(mem, &sun::ErrorLog::handler, &log), "KINSetErrHandlerFn",
          Flags::Kinsol);
    check(KINInit(mem, &Impl::residual, u), "KINInit", Flags::Kinsol);
    check(KINSetUserData(mem, this), "KINSetUserData", Flags::Kinsol);
    check(KINSetLinearSolver(mem, klu, K), "KINSetLinearSolver", Flags::KinsolLs);
    check(KINSetJacFn(mem, &Impl::jacobian), "KINSetJacFn", Flags::KinsolLs);
    check(KINSetMaxSetupCalls(mem, 1), "KINSetMaxSetupCalls", Flags::Kinsol);
    check(KINSetNumMaxIters(mem, settings.max_newton), "KINSetNumMaxIters", Flags::Kinsol);
    check(KINSetScaledStepTol(mem, settings.rtol), "KINSetScaledStepTol", Flags::Kinsol);
    check(KINSetFuncNormTol(mem, kForceTestFraction), "KINSetFuncNormTol", Flags::Kinsol);
  }

  // F(q) = -f(t, q, 0).
  void eval_residual(const double* q, double* F) {
    q_buf = Eigen::Map<const Eigen::VectorXd>(q, n);
    system.force(t, q_buf, zero_u, f_buf);
    Eigen::Map<Eigen::VectorXd>(F, n) = -f_buf;
  }

  void eval_stiffness(const double* q, std::vector<double>& values) {
    q_buf = Eigen::Map<const Eigen::VectorXd>(q, n);
    system.stiffness(t, q_buf, zero_u, values);
  }

  static int residual(N_Vector uv, N_Vector Fv, void* data) {
    auto* self = static_cast<Impl*>(data);
    try {
      throw_if_cancelled("a KINSOL iteration");
      self->eval_residual(N_VGetArrayPointer(uv), N_VGetArrayPointer(Fv));
      return sun::cview(Fv).allFinite() ? 0 : 1;  // recoverable: KINSOL shortens the step
    } catch (...) {
      self->error = std::current_exception();
      return -1;
    }
  }

  static int jacobian(N_Vector uv, N_Vector, SUNMatrix Jm, void* data, N_Vector, N_Vector) {
    auto* self = static_cast<Impl*>(data);
    try {
      sun::ScopedTimer timer(self->klu.stats().seconds);
      self->eval_stiffness(N_VGetArrayPointer(uv), self->k_values);
      sun::write_pattern(Jm, self->pattern);
      std::copy(self->k_values.begin(), self->k_values.end(), SUNSparseMatrix_Data(Jm));
      return 0;
    } catch (...) {
      self->error = std::current_exception();
      return -1;
    }
  }

  // True when every |p_i| <= rtol |q_i| + atol.
  bool within_tolerance(const Eigen::VectorXd& step, const Eigen::VectorXd& q) const {
    for (int i = 0; i < n; ++i)
      if (!(std::abs(step[i]) <= settings.rtol * std::abs(q[i]) + settings.atol)) return false;
    return true;
  }

  // Solves (values + mu M) p = -F into p (the fallback's matrix and KLU); false when the
  // factorisation or the solve fails or p is not finite.
  bool shifted_step(const std::vector<double>& values, double mu, const Eigen::VectorXd& F) {
    const Eigen::VectorXd& m = system.mass();
    double* Bv = B.values();
    std::copy(values.begin(), values.end(), Bv);
    if (mu != 0.0)
      for (int i = 0; i < n; ++i) Bv[diag_slot[static_cast<size_t>(i)]] += mu * m[i];
    b.map() = -F;
    int flag = SUNLinSolSetup(fallback_klu, B);
    if (flag == 0) flag = SUNLinSolSolve(fallback_klu, B, p, b, 0.0);
    return flag == 0 && p.map().allFinite();
  }

  // One exact Newton step from q when it is within tolerance (then q takes it): the step test,
  // for an iterate where KINSOL stopped before its own tests passed.
  bool newton_step_converged(Eigen::VectorXd& q) {
    Eigen::VectorXd F(n);
    eval_residual(q.data(), F.data());
    eval_stiffness(q.data(), k_values);
    ++totals.newton_iterations;
    if (!shifted_step(k_values, 0.0, F)) return false;
    if (!within_tolerance(p.map(), q)) return false;
    q += p.map();
    return true;
  }

  // One KINSOL attempt from q; returns its flag (negative on failure; q unchanged then) and
  // adds its counters. KINSOL's line search fails once |F| is at its round-off floor if its force
  // test has not passed by then (the full Newton step no longer lowers |F|^2, and any shorter one
  // is below its step tolerance); such an iterate is accepted when one more Newton step from it
  // is within tolerance.
  int run_kinsol(Eigen::VectorXd& q) {
    // Scalings from the start point (see ref_static.hpp).
    eval_stiffness(q.data(), k_values);
    double kmax = 0.0;
    for (int i = 0; i < n; ++i)
      kmax = std::max(kmax, std::abs(k_values[static_cast<size_t>(diag_slot[static_cast<size_t>(i)])]));
    const double floor = kmax > 0.0 ? kStiffnessFloor * kmax : 1.0;
    auto us = uscale.map();
    auto fs = fscale.map();
    for (int i = 0; i < n; ++i) {
      const double kii = std::abs(k_values[static_cast<size_t>(diag_slot[static_cast<size_t>(i)])]);
      us[i] = settings.rtol / settings.atol;
      fs[i] = 1.0 / (std::max(kii, floor) * (settings.rtol * std::abs(q[i]) + settings.atol));
    }
    u.map() = q;
    error = nullptr;
    log.last.clear();
    const int flag = KINSol(mem, u, settings.line_search ? KIN_LINESEARCH : KIN_NONE, uscale, fscale);
    long nni = 0;
    KINGetNumNonlinSolvIters(mem, &nni);
    totals.newton_iterations += nni;
    if (error) std::rethrow_exception(error);
    if (flag >= 0) {
      q = u.map();
      return flag;
    }
    Eigen::VectorXd last = u.map();  // KINSOL's last accepted iterate
    if (last.allFinite() && newton_step_converged(last)) {
      q = last;
      return KIN_STEP_LT_STPTOL;
    }
    return flag;
  }

  // Projected Newton descent on U from q (see ref_static.hpp). Returns true when it converged:
  // a Newton step with a negligible shift was within tolerance (the energy line search cannot
  // judge steps that small: U is then at its round-off floor).
  bool descend(Eigen::VectorXd& q) {
    const Eigen::VectorXd& m = system.mass();
    std::vector<double> values(static_cast<size_t>(pattern.nnz()));
    Eigen::VectorXd F(n), trial(n);
    // Shift scale: mu in 1/s^2 against M, from the largest K_ii / m_i at the start.
    eval_stiffness(q.data(), values);
    double scale = 0.0;
    for (int i = 0; i < n; ++i)
      scale = std::max(scale, std::abs(values[static_cast<size_t>(diag_slot[static_cast<size_t>(i)])]) / m[i]);
    if (!(scale > 0.0)) scale = 1.0;
    const double mu_min = 1e-12 * scale, mu_max = 1e12 * scale, mu_negligible = 1e-6 * scale;
    double mu = 1e-6 * scale;
    for (int it = 0; it < settings.max_newton; ++it) {
      throw_if_cancelled("a Newton iteration");
      ++totals.newton_iterations;
      eval_residual(q.data(), F.data());
      const double U0 = system.potential(t, q);
      if (projected) {
        q_buf = q;
        projected(t, q_buf, values);
      } else {
        eval_stiffness(q.data(), values);
      }
      for (;;) {  // until a shift gives a factorisation and a descent direction
        if (mu > mu_max) return false;
        const bool solved = shifted_step(values, mu, F);
        const double slope = solved ? F.dot(p.map()) : 0.0;
        if (!solved || !(slope < 0.0)) {
          mu = std::max(10.0 * mu, mu_min);
          continue;
        }
        if (mu <= mu_negligible && within_tolerance(p.map(), q)) {
          q += p.map();
          return true;
        }
        // Armijo backtracking on U.
        double alpha = 1.0;
        int halvings = 0;
        bool accepted = false;
        for (; halvings < 60; ++halvings, alpha *= 0.5) {
          trial = q + alpha * p.map();
          const double U1 = system.potential(t, trial);
          if (std::isfinite(U1) && U1 <= U0 + 1e-4 * alpha * slope) {
            accepted = true;
            break;
          }
        }
        if (!accepted) {
          mu = std::max(10.0 * mu, mu_min);
          continue;
        }
        q = trial;
        // Full steps: towards Newton; long backtracking: towards gradient descent.
        mu = halvings == 0 ? mu / 10.0 : (halvings > 3 ? 10.0 * mu : mu);
        if (mu < mu_min) mu = 0.0;
        break;
      }
    }
    return false;
  }

  sun::Context ctx;
  const MechanicalSystem& system;
  StaticSettings settings;
  ProjectedStiffness projected;
  int n;
  sun::CscPattern pattern;
  sun::Vector u, uscale, fscale;
  sun::SparseMatrix K;
  sun::TimedKlu klu;
  sun::SparseMatrix B;  // the fallback's K+ + mu M
  sun::Vector b, p;
  sun::TimedKlu fallback_klu;
  sun::Memory mem;
  sun::ErrorLog log;
  std::exception_ptr error;
  double t = 0.0;
  Eigen::VectorXd q_buf, zero_u, f_buf;
  std::vector<double> k_values;
  std::vector<sunindextype> diag_slot;
  sun::Counters totals;  // steps, newton_iterations, convergence_failures
  int last_flag = 0;
  bool last_fallback = false;
};

StaticSolver::StaticSolver(const MechanicalSystem& system, const StaticSettings& settings,
                           ProjectedStiffness projected) {
  if (!(settings.rtol > 0.0) || !(settings.atol > 0.0))
    throw std::invalid_argument("StaticSolver: rtol and atol must be > 0");
  if (settings.max_newton < 1) throw std::invalid_argument("StaticSolver: max_newton must be >= 1");
  impl_ = std::make_unique<Impl>(system, settings, std::move(projected));
}

StaticSolver::~StaticSolver() = default;

void StaticSolver::solve(double t, Eigen::VectorXd& q) {
  Impl& m = *impl_;
  if (q.size() != m.n)
    throw std::invalid_argument("StaticSolver::solve: q needs " + std::to_string(m.n) + " entries");
  m.t = t;
  m.last_fallback = false;
  ++m.totals.steps;
  const Eigen::VectorXd start = q;
  int flag = m.run_kinsol(q);
  if (flag >= 0) {
    m.last_flag = flag;
    return;
  }
  ++m.totals.convergence_failures;
  const std::string first = sun::flag_name(flag, Flags::Kinsol);
  const std::string first_log = m.log.last;
  if (!m.settings.fallback)
    check(flag, "KINSol", Flags::Kinsol, &m.log);
  m.last_fallback = true;
  q = start;
  const bool descended = m.descend(q);
  const int second = m.run_kinsol(q);
  if (second < 0) {
    ++m.totals.convergence_failures;
    q = start;
    throw std::runtime_error(
        "KINSol failed: " + first + " (" + std::to_string(flag) + ")" +
        (first_log.empty() ? "" : ": " + first_log) + "; after the projected-Newton fallback (" +
        (descended ? "which converged" : "which did not converge") + "), KINSol failed again: " +
        sun::flag_name(second, Flags::Kinsol) + " (" + std::to_string(second) + ")" +
        (m.log.last.empty() ? "" : ": " + m.log.last));
  }
  m.last_flag = second;
}

sun::Counters StaticSolver::counters() const {
  const Impl& m = *impl_;
  sun::Counters c = m.totals;
  c.linear_setups = m.klu.stats().setups + m.fallback_klu.stats().setups;
  c.linear_solves = m.klu.stats().solves + m.fallback_klu.stats().solves;
  c.time_linear = m.klu.stats().seconds + m.fallback_klu.stats().seconds;
  return c;
}

int StaticSolver::last_flag() const { return impl_->last_flag; }

bool StaticSolver::last_used_fallback() const { return impl_->last_fallback; }

// ---------------------------------------------------------------------------------------------
// The Solver.

namespace {

class RefStatic final : public Solver {
 public:
  RefStatic(const SolverOptions& options, const Model& model) : scene_(model) {
    if (scene_.dofs() == 0) return;
    const SceneSystem& sys = scene_.system();
    ProjectedStiffness projected = [&sys, x = Points()](double t, const Eigen::VectorXd& q,
                                                        std::vector<double>& values) mutable {
      sys.energy().positions(q, t, x);
      sys.energy().hessian(x, values, true);
    };
    solver_ = std::make_unique<StaticSolver>(
        sys, StaticSettings{options.ref_rtol, options.ref_atol, options.ref_max_newton, true, true},
        std::move(projected));
  }

  std::string name() const override { return "ref-static"; }

  StepReport step(const Model& model, State& state, double dt) override {
    scene_.check_step(model, state, dt);
    StepReport report;
    report.substeps = 1;
    report.stop = StopReason::Converged;  // KINSOL's failures (after the fallback) throw
    const double t_out = state.time + dt;
    if (solver_) {
      scene_.gather(state, q_, u_);
      const sun::Counters before = solver_->counters();
      solver_->solve(t_out, q_);
      add_counters(report, solver_->counters() - before);  // ref_steps: 1, the one solve
      u_.setZero();
    }
    scene_.finish(state, t_out, q_, u_);
    return report;
  }

 private:
  SceneStepper scene_;
  std::unique_ptr<StaticSolver> solver_;  // null when nothing is dynamic
  Eigen::VectorXd q_, u_;
};

}  // namespace

std::unique_ptr<Solver> make_ref_static(const SolverOptions& options, const Model& model) {
  check_reference_model("ref-static", model, options);
  return std::make_unique<RefStatic>(options, model);
}

}  // namespace pbdbench
