// ref-bdf: CVODE BDF on the scene's first-order system. docs/reference.md, "ref-bdf".
#include "reference/ref_bdf.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <stdexcept>
#include <string>

#include <cvode/cvode.h>
#include <cvode/cvode_ls.h>
#include <sunmatrix/sunmatrix_sparse.h>

#include "core/cancel.hpp"
#include "reference/first_order_system.hpp"
#include "reference/integrators.hpp"
#include "reference/ref_common.hpp"

namespace pbdbench {

using sun::check;
using sun::Flags;

struct BdfIntegrator::Impl {
  Impl(const MechanicalSystem& system, const BdfSettings& s, std::vector<double> breaks)
      : fos(system),
        settings(s),
        breakpoints(std::move(breaks)),
        y(fos.size(), ctx),
        J(fos.jacobian_pattern(), ctx),
        linear(s.linear_solver, fos, y, J, ctx),
        atol(fos.size(), ctx) {
    std::sort(breakpoints.begin(), breakpoints.end());
    auto a = atol.map();
    a.head(fos.dofs()).setConstant(settings.atol);
    a.tail(fos.dofs()).setConstant(settings.atol_velocity > 0.0 ? settings.atol_velocity
                                                                : settings.atol);
  }

  static int rhs(sunrealtype t, N_Vector yv, N_Vector ydot, void* data) {
    auto* self = static_cast<Impl*>(data);
    try {
      throw_if_cancelled("a CVODE step");
      self->fos.rhs(t, N_VGetArrayPointer(yv), N_VGetArrayPointer(ydot));
      // Recoverable: CVODE retries with a smaller step, and stops with CV_REPTD_RHSFUNC_ERR
      // if that does not help.
      return sun::cview(ydot).allFinite() ? 0 : 1;
    } catch (...) {
      self->error = std::current_exception();
      return -1;
    }
  }

  static int jac(sunrealtype t, N_Vector yv, N_Vector, SUNMatrix Jm, void* data, N_Vector,
                 N_Vector, N_Vector) {
    auto* self = static_cast<Impl*>(data);
    try {
      sun::ScopedTimer timer(self->linear.stats().seconds);
      sun::write_pattern(Jm, self->fos.jacobian_pattern());
      self->fos.jacobian(t, N_VGetArrayPointer(yv), SUNSparseMatrix_Data(Jm));
      return 0;
    } catch (...) {
      self->error = std::current_exception();
      return -1;
    }
  }

  // CVODE's own counters since the last CVodeInit/CVodeReInit.
  sun::Counters package_counters() const {
    sun::Counters c;
    if (mem.get() == nullptr) return c;
    long v = 0;
    check(CVodeGetNumSteps(mem, &c.steps), "CVodeGetNumSteps", Flags::Cvode);
    check(CVodeGetNumNonlinSolvIters(mem, &c.newton_iterations), "CVodeGetNumNonlinSolvIters",
          Flags::Cvode);
    check(CVodeGetNumLinSolvSetups(mem, &c.linear_setups), "CVodeGetNumLinSolvSetups",
          Flags::Cvode);
    check(CVodeGetNumErrTestFails(mem, &c.error_test_failures), "CVodeGetNumErrTestFails",
          Flags::Cvode);
    check(CVodeGetNumNonlinSolvConvFails(mem, &v), "CVodeGetNumNonlinSolvConvFails", Flags::Cvode);
    c.convergence_failures = v;
    return c;
  }

  void create(double t0) {
    mem = sun::Memory(sun::check_ptr(CVodeCreate(CV_BDF, ctx), "CVodeCreate"), &CVodeFree);
    check(CVodeSetErrHandlerFn(mem, &sun::ErrorLog::handler, &log), "CVodeSetErrHandlerFn",
          Flags::Cvode);
    check(CVodeInit(mem, &Impl::rhs, t0, y), "CVodeInit", Flags::Cvode);
    check(CVodeSVtolerances(mem, settings.rtol, atol), "CVodeSVtolerances", Flags::Cvode);
    check(CVodeSetUserData(mem, this), "CVodeSetUserData", Flags::Cvode);
    check(CVodeSetMaxNumSteps(mem, settings.max_steps), "CVodeSetMaxNumSteps", Flags::Cvode);
    check(CVodeSetMaxOrd(mem, settings.max_order), "CVodeSetMaxOrd", Flags::Cvode);
    check(CVodeSetLinearSolver(mem, linear.get(), J), "CVodeSetLinearSolver", Flags::CvodeLs);
    check(CVodeSetJacFn(mem, &Impl::jac), "CVodeSetJacFn", Flags::CvodeLs);
  }

  // Restart at (t, y): counters of the run that ends are kept in `before_restarts`.
  void restart(double t) {
    if (mem.get() == nullptr) {
      create(t);
    } else {
      before_restarts += package_counters();
      check(CVodeReInit(mem, t, y), "CVodeReInit", Flags::Cvode);
      // CVodeReInit keeps a stop time that CVode did not consume (it returns CV_SUCCESS rather
      // than CV_TSTOP_RETURN when its last step already ended on the stop time), and CVode then
      // refuses a stop time at the initial time. 6.4 has no CVodeClearStopTime: move it on.
      const double tb = next_breakpoint(t);
      check(CVodeSetStopTime(mem, std::isfinite(tb) ? tb : std::numeric_limits<double>::max()),
            "CVodeSetStopTime", Flags::Cvode);
    }
    t_now = t;
    started = true;
  }

  // The first breakpoint after t, or +inf.
  double next_breakpoint(double t) const {
    const auto it = std::upper_bound(breakpoints.begin(), breakpoints.end(), t);
    return it == breakpoints.end() ? HUGE_VAL : *it;
  }

  // CVode to `target`; rethrows an exception from a callback, else turns a failure into
  // std::runtime_error. Returns the flag (CV_SUCCESS or CV_TSTOP_RETURN).
  int run_to(double target) {
    sunrealtype t_ret = t_now;
    error = nullptr;
    log.last.clear();
    const int flag = CVode(mem, target, y, &t_ret, CV_NORMAL);
    if (flag < 0) {
      started = false;
      if (error) std::rethrow_exception(error);
      check(flag, "CVode", Flags::Cvode, &log);
    }
    return flag;
  }

  sun::Context ctx;
  FirstOrderSystem fos;
  BdfSettings settings;
  std::vector<double> breakpoints;
  sun::Vector y;
  sun::SparseMatrix J;
  NewtonLinearSolver linear;
  sun::Vector atol;  // (2n) absolute tolerances: positions (atol), velocities (atol_velocity)
  sun::Memory mem;
  sun::ErrorLog log;
  std::exception_ptr error;
  sun::Counters before_restarts;  // CVODE's counters of the runs before the last (re)start
  double t_now = 0.0;
  bool started = false;
};

BdfIntegrator::BdfIntegrator(const MechanicalSystem& system, const BdfSettings& settings,
                             std::vector<double> breakpoints) {
  if (!(settings.rtol > 0.0) || !(settings.atol > 0.0))
    throw std::invalid_argument("BdfIntegrator: rtol and atol must be > 0");
  if (!(settings.atol_velocity >= 0.0) || !std::isfinite(settings.atol_velocity))
    throw std::invalid_argument("BdfIntegrator: atol_velocity must be >= 0 (0: atol)");
  if (settings.max_steps < 1)
    throw std::invalid_argument("BdfIntegrator: max_steps must be >= 1");
  if (settings.max_order < 1 || settings.max_order > 5)
    throw std::invalid_argument("BdfIntegrator: max_order must be in [1, 5]");
  impl_ = std::make_unique<Impl>(system, settings, std::move(breakpoints));
}

BdfIntegrator::~BdfIntegrator() = default;

void BdfIntegrator::reset(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u) {
  Impl& m = *impl_;
  if (q.size() != m.fos.dofs() || u.size() != m.fos.dofs())
    throw std::invalid_argument("BdfIntegrator::reset: q and u need " +
                                std::to_string(m.fos.dofs()) + " entries");
  m.fos.pack(q, u, N_VGetArrayPointer(m.y));
  m.restart(t);
}

void BdfIntegrator::advance(double t_out, Eigen::VectorXd& q, Eigen::VectorXd& u) {
  Impl& m = *impl_;
  if (!m.started) throw std::logic_error("BdfIntegrator::advance before reset");
  if (!(t_out > m.t_now))
    throw std::invalid_argument("BdfIntegrator::advance: t_out must be after time()");
  for (;;) {
    const double tb = m.next_breakpoint(m.t_now);
    if (tb <= t_out) {
      // Land on the breakpoint exactly and restart there.
      check(CVodeSetStopTime(m.mem, tb), "CVodeSetStopTime", Flags::Cvode);
      m.run_to(tb);
      m.restart(tb);  // y holds the solution at tb
      if (tb == t_out) break;
      continue;
    }
    // Keep every internal step at or before the next breakpoint.
    if (std::isfinite(tb)) check(CVodeSetStopTime(m.mem, tb), "CVodeSetStopTime", Flags::Cvode);
    m.run_to(t_out);
    m.t_now = t_out;
    break;
  }
  m.fos.unpack(N_VGetArrayPointer(m.y), q, u);
}

bool BdfIntegrator::started() const { return impl_->started; }

double BdfIntegrator::time() const { return impl_->t_now; }

sun::Counters BdfIntegrator::counters() const {
  const Impl& m = *impl_;
  sun::Counters c = m.before_restarts;
  c += m.package_counters();
  m.linear.write_counters(c);
  return c;
}

// ---------------------------------------------------------------------------------------------
// The Solver.

namespace {

class RefBdf final : public Solver {
 public:
  RefBdf(const SolverOptions& options, const Model& model)
      : scene_(model) {
    if (scene_.dofs() > 0)
      bdf_ = std::make_unique<BdfIntegrator>(
          scene_.system(),
          BdfSettings{options.ref_rtol, options.ref_atol, options.ref_max_steps, 5,
                      options.ref_atol_velocity, linear_solver_kind(options)},
          motion_breakpoints(model));
  }

  std::string name() const override { return "ref-bdf"; }

  StepReport step(const Model& model, State& state, double dt) override {
    scene_.check_step(model, state, dt);
    StepReport report;
    report.substeps = 1;
    report.stop = StopReason::Converged;  // CVODE's failures stop the run (they throw)
    const double t_out = state.time + dt;
    if (bdf_) {
      if (!bdf_->started() || !scene_.continues(state)) {
        scene_.gather(state, q_, u_);
        bdf_->reset(state.time, q_, u_);
      }
      const sun::Counters before = bdf_->counters();
      bdf_->advance(t_out, q_, u_);
      add_counters(report, bdf_->counters() - before);
    }
    scene_.finish(state, t_out, q_, u_);
    return report;
  }

 private:
  SceneStepper scene_;
  std::unique_ptr<BdfIntegrator> bdf_;  // null when the scene has no dynamic particle
  Eigen::VectorXd q_, u_;
};

}  // namespace

std::unique_ptr<Solver> make_ref_bdf(const SolverOptions& options, const Model& model) {
  check_reference_model("ref-bdf", model, options);
  return std::make_unique<RefBdf>(options, model);
}

}  // namespace pbdbench
