// ref-be and ref-sdirk2: ARKODE ARKStep with a fixed step. docs/reference.md.
#include "reference/ref_fixed_step.hpp"

#include <cmath>
#include <exception>
#include <stdexcept>
#include <string>

#include <arkode/arkode_arkstep.h>
#include <arkode/arkode_butcher.h>
#include <arkode/arkode_butcher_dirk.h>
#include <sunmatrix/sunmatrix_sparse.h>

#include "core/cancel.hpp"
#include "reference/first_order_system.hpp"
#include "reference/integrators.hpp"
#include "reference/ref_common.hpp"
#include "reference/ref_contact.hpp"

namespace pbdbench {

using sun::check;
using sun::Flags;

struct FixedStepIntegrator::Impl {
  Impl(const MechanicalSystem& system, const FixedStepSettings& s)
      : fos(system), settings(s), y(fos.size(), ctx), J(fos.jacobian_pattern(), ctx),
        linear(s.linear_solver, fos, y, J, ctx), newton(y, ctx), atol(fos.size(), ctx),
        merit(*this) {
    // A conservative system's stage is the minimiser of an energy: line search on it, with
    // definite (shifted) Newton matrices, so every step is a descent step (StageMerit).
    if (!fos.system().has_damping()) {
      newton.set_merit(&merit);
      linear.set_shift_indefinite(true);
    }
  }

  // The energy whose minimiser is a stage of the implicit method, for a force f = -grad U (no
  // damping). ARKODE writes the stage z = [q; u] = zpred + zcor as the root of
  //   G(zcor) = zcor - gamma F(z) - sdata,  i.e.  z - gamma F(z) = a,  a = zpred + sdata
  // (gamma = h A_ii; a holds y_n and the earlier stages). Its first block, q - gamma u = a_q, is
  // linear; on it, u = (q - a_q) / gamma, and the second block, u - gamma M^-1 f(q) = a_u,
  // becomes M (q - c) / gamma^2 - f(q) = 0 with c = a_q + gamma a_u: the stationarity of
  //   E(q) = |q - c|_M^2 / (2 gamma^2) + U(t, q),
  // the implicit stage's incremental potential. project() puts an iterate on the linear block
  // (u from q); on it, G = [0; gamma M^-1 grad E], and the Newton step from the reduced matrix
  // S = M + gamma^2 K has d_q = -gamma^2 S^-1 grad E: a descent direction for E when S is
  // definite, which the shifted factorisation ensures (ReducedLinearSolver). A minimiser of E
  // is the stage that converged XPBD also seeks (Macklin et al. 2016, eq. 6-8 for backward
  // Euler).
  struct StageMerit final : sun::FullNewton::Merit {
    explicit StageMerit(Impl& owner) : self(owner) {}

    int data(double& t, double*& zpred, double*& sdata, double& gamma) const {
      N_Vector zp = nullptr, z = nullptr, Fi = nullptr, sd = nullptr;
      void* user = nullptr;
      if (ARKStepGetNonlinearSystemData(self.mem, &t, &zp, &z, &Fi, &gamma, &sd, &user) != 0)
        return -1;
      zpred = N_VGetArrayPointer(zp);
      sdata = N_VGetArrayPointer(sd);
      return gamma > 0.0 ? 0 : -1;
    }

    int project(N_Vector ycor) override {
      double t, gamma;
      double *zp, *sd;
      if (data(t, zp, sd, gamma) != 0) return -1;
      const int n = self.fos.dofs();
      double* yc = N_VGetArrayPointer(ycor);
      for (int i = 0; i < n; ++i) {
        const double q = zp[i] + yc[i], aq = zp[i] + sd[i];
        yc[n + i] = (q - aq) / gamma - zp[n + i];
      }
      return 0;
    }

    // q and c (see above) at ycor.
    int unpack(N_Vector ycor, double& t, double& gamma) {
      double *zp, *sd;
      if (data(t, zp, sd, gamma) != 0) return -1;
      const int n = self.fos.dofs();
      const double* yc = N_VGetArrayPointer(ycor);
      q.resize(n);
      u.resize(n);
      c.resize(n);
      for (int i = 0; i < n; ++i) {
        q[i] = zp[i] + yc[i];
        u[i] = zp[n + i] + yc[n + i];
        c[i] = zp[i] + sd[i] + gamma * (zp[n + i] + sd[n + i]);
      }
      return 0;
    }

    int value(N_Vector ycor, double& energy) override {
      double t, gamma;
      if (unpack(ycor, t, gamma) != 0) return -1;
      const Eigen::VectorXd& m = self.fos.system().mass();
      energy = 0.5 * (q - c).cwiseAbs2().dot(m) / (gamma * gamma) + self.fos.system().potential(t, q);
      return std::isfinite(energy) ? 0 : 1;
    }

    int slope(N_Vector ycor, N_Vector d, double& s) override {
      double t, gamma;
      if (unpack(ycor, t, gamma) != 0) return -1;
      const MechanicalSystem& sys = self.fos.system();
      sys.force(t, q, u, f);
      const int n = self.fos.dofs();
      const double* dv = N_VGetArrayPointer(d);
      s = 0.0;
      for (int i = 0; i < n; ++i)
        s += (sys.mass()[i] * (q[i] - c[i]) / (gamma * gamma) - f[i]) * dv[i];
      return std::isfinite(s) ? 0 : 1;
    }

    Impl& self;
    Eigen::VectorXd q, u, c, f;
  };

  static int rhs(sunrealtype t, N_Vector yv, N_Vector ydot, void* data) {
    auto* self = static_cast<Impl*>(data);
    try {
      throw_if_cancelled("an ARKODE step");
      self->fos.rhs(t, N_VGetArrayPointer(yv), N_VGetArrayPointer(ydot));
      return sun::cview(ydot).allFinite() ? 0 : 1;  // recoverable: a fixed step still fails
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

  sun::Counters package_counters() const {
    sun::Counters c;
    if (mem.get() == nullptr) return c;
    check(ARKStepGetNumSteps(mem, &c.steps), "ARKStepGetNumSteps", Flags::Arkode);
    check(ARKStepGetNumNonlinSolvIters(mem, &c.newton_iterations), "ARKStepGetNumNonlinSolvIters",
          Flags::Arkode);
    check(ARKStepGetNumLinSolvSetups(mem, &c.linear_setups), "ARKStepGetNumLinSolvSetups",
          Flags::Arkode);
    check(ARKStepGetNumErrTestFails(mem, &c.error_test_failures), "ARKStepGetNumErrTestFails",
          Flags::Arkode);
    check(ARKStepGetNumNonlinSolvConvFails(mem, &c.convergence_failures),
          "ARKStepGetNumNonlinSolvConvFails", Flags::Arkode);
    return c;
  }

  void create(double t0, double h) {
    mem = sun::Memory(sun::check_ptr(ARKStepCreate(nullptr, &Impl::rhs, t0, y, ctx), "ARKStepCreate"),
                      &ARKStepFree);
    check(ARKStepSetErrHandlerFn(mem, &sun::ErrorLog::handler, &log), "ARKStepSetErrHandlerFn",
          Flags::Arkode);
    check(ARKStepSetUserData(mem, this), "ARKStepSetUserData", Flags::Arkode);
    set_step(h);
    if (settings.method == FixedStepMethod::BackwardEuler) {
      // Backward Euler as a one-stage DIRK: c = [1], A = [[1]], b = [1]; order 1, no embedding.
      const sunrealtype c[1] = {1.0}, A[1] = {1.0}, b[1] = {1.0};
      ARKodeButcherTable table = sun::check_ptr(
          ARKodeButcherTable_Create(1, 1, 0, const_cast<sunrealtype*>(c),
                                    const_cast<sunrealtype*>(A), const_cast<sunrealtype*>(b),
                                    nullptr),
          "ARKodeButcherTable_Create");
      const int flag = ARKStepSetTables(mem, 1, 0, table, nullptr);  // copies the table
      ARKodeButcherTable_Free(table);
      check(flag, "ARKStepSetTables", Flags::Arkode);
    } else {
      check(ARKStepSetTableNum(mem, ARKODE_SDIRK_2_1_2, ARKODE_ERK_NONE), "ARKStepSetTableNum",
            Flags::Arkode);
    }
    if (!settings.package_newton)
      check(ARKStepSetNonlinearSolver(mem, newton), "ARKStepSetNonlinearSolver", Flags::Arkode);
    check(ARKStepSetLinearSolver(mem, linear.get(), J), "ARKStepSetLinearSolver", Flags::ArkodeLs);
    check(ARKStepSetJacFn(mem, &Impl::jac), "ARKStepSetJacFn", Flags::ArkodeLs);
    check(ARKStepSetNonlinConvCoef(mem, settings.nonlinear_coefficient),
          "ARKStepSetNonlinConvCoef", Flags::Arkode);
    check(ARKStepSetMaxNonlinIters(mem, settings.max_newton), "ARKStepSetMaxNonlinIters",
          Flags::Arkode);
    // No divergence test: the line search of sun::FullNewton keeps the residual decreasing, and
    // a full step may still be longer than the one before it.
    if (!settings.package_newton)
      check(ARKStepSetNonlinRDiv(mem, 1e300), "ARKStepSetNonlinRDiv", Flags::Arkode);
  }

  // The fixed step h and the absolute tolerances that go with it: atol for the positions and
  // atol / h for the velocities (see ref_fixed_step.hpp).
  void set_step(double h) {
    auto a = atol.map();
    a.head(fos.dofs()).setConstant(settings.atol);
    a.tail(fos.dofs()).setConstant(settings.atol / h);
    check(ARKStepSVtolerances(mem, settings.rtol, atol), "ARKStepSVtolerances", Flags::Arkode);
    check(ARKStepSetFixedStep(mem, h), "ARKStepSetFixedStep", Flags::Arkode);
    h_now = h;
  }

  sun::Context ctx;
  FirstOrderSystem fos;
  FixedStepSettings settings;
  sun::Vector y;
  sun::SparseMatrix J;
  NewtonLinearSolver linear;
  sun::FullNewton newton;  // outlives mem
  sun::Vector atol;        // (2n) absolute tolerances: positions, then velocities
  StageMerit merit;        // used when the system has no damping
  sun::Memory mem;
  sun::ErrorLog log;
  std::exception_ptr error;
  sun::Counters dropped;  // counters a reset cleared
  double t_now = 0.0, h_now = 0.0;
  bool started = false;
};

FixedStepIntegrator::FixedStepIntegrator(const MechanicalSystem& system,
                                         const FixedStepSettings& settings) {
  if (!(settings.rtol > 0.0) || !(settings.atol > 0.0))
    throw std::invalid_argument("FixedStepIntegrator: rtol and atol must be > 0");
  if (settings.max_newton < 1)
    throw std::invalid_argument("FixedStepIntegrator: max_newton must be >= 1");
  if (!(settings.nonlinear_coefficient > 0.0) || settings.nonlinear_coefficient > 1.0)
    throw std::invalid_argument("FixedStepIntegrator: nonlinear_coefficient must be in (0, 1]");
  impl_ = std::make_unique<Impl>(system, settings);
}

FixedStepIntegrator::~FixedStepIntegrator() = default;

void FixedStepIntegrator::reset(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u) {
  Impl& m = *impl_;
  if (q.size() != m.fos.dofs() || u.size() != m.fos.dofs())
    throw std::invalid_argument("FixedStepIntegrator::reset: q and u need " +
                                std::to_string(m.fos.dofs()) + " entries");
  m.fos.pack(q, u, N_VGetArrayPointer(m.y));
  if (m.mem.get() != nullptr) {
    const sun::Counters before = m.package_counters();
    check(ARKStepReset(m.mem, t, m.y), "ARKStepReset", Flags::Arkode, &m.log);
    m.dropped += before - m.package_counters();  // whatever the reset cleared
  }
  m.t_now = t;
  m.started = true;
}

void FixedStepIntegrator::advance(int steps, double h, Eigen::VectorXd& q, Eigen::VectorXd& u) {
  Impl& m = *impl_;
  if (!m.started) throw std::logic_error("FixedStepIntegrator::advance before reset");
  if (steps < 1 || !(h > 0.0))
    throw std::invalid_argument("FixedStepIntegrator::advance: steps >= 1 and h > 0 needed");
  if (m.mem.get() == nullptr) {
    m.create(m.t_now, h);
  } else if (h != m.h_now) {
    m.set_step(h);
  }
  const double t_end = m.t_now + steps * h;
  for (int k = 0; k < steps; ++k) {
    sunrealtype t_ret = m.t_now;
    m.error = nullptr;
    m.log.last.clear();
    const int flag = ARKStepEvolve(m.mem, t_end, m.y, &t_ret, ARK_ONE_STEP);
    if (flag < 0) {
      m.started = false;
      if (m.error) std::rethrow_exception(m.error);
      check(flag, "ARKStepEvolve", Flags::Arkode, &m.log);
    }
    m.t_now = t_ret;
  }
  m.fos.unpack(N_VGetArrayPointer(m.y), q, u);
}

bool FixedStepIntegrator::started() const { return impl_->started; }

double FixedStepIntegrator::time() const { return impl_->t_now; }

sun::Counters FixedStepIntegrator::counters() const {
  const Impl& m = *impl_;
  sun::Counters c = m.dropped;
  c += m.package_counters();
  m.linear.write_counters(c);
  return c;
}

// ---------------------------------------------------------------------------------------------
// The Solvers.

namespace {

class RefFixedStep final : public Solver {
 public:
  RefFixedStep(std::string name, FixedStepMethod method, const SolverOptions& options,
               const Model& model)
      : name_(std::move(name)), substeps_(options.substeps), scene_(model) {
    if (scene_.dofs() > 0)
      integrator_ = std::make_unique<FixedStepIntegrator>(
          scene_.system(), FixedStepSettings{method, options.ref_rtol, options.ref_atol,
                                             options.ref_max_newton, 0.1, false,
                                             linear_solver_kind(options)});
  }

  std::string name() const override { return name_; }

  StepReport step(const Model& model, State& state, double dt) override {
    scene_.check_step(model, state, dt);
    StepReport report;
    report.substeps = substeps_;
    report.stop = StopReason::Converged;  // ARKODE's failures stop the run (they throw)
    const double t_out = state.time + dt;
    if (integrator_) {
      if (!integrator_->started() || !scene_.continues(state)) {
        scene_.gather(state, q_, u_);
        integrator_->reset(state.time, q_, u_);
      }
      const sun::Counters before = integrator_->counters();
      integrator_->advance(substeps_, dt / substeps_, q_, u_);
      add_counters(report, integrator_->counters() - before);
    }
    scene_.finish(state, t_out, q_, u_);
    return report;
  }

 private:
  std::string name_;
  int substeps_;
  SceneStepper scene_;
  std::unique_ptr<FixedStepIntegrator> integrator_;  // null when nothing is dynamic
  Eigen::VectorXd q_, u_;
};

}  // namespace

std::unique_ptr<Solver> make_ref_be(const SolverOptions& options, const Model& model) {
  // Contact (colliders, particle contact) is simulated by the incremental-potential form with
  // the IPC barrier (reference/ref_contact.hpp) unless the scene asks to ignore it.
  if (has_contact(model) && !options.ref_ignore_colliders) return make_ref_be_contact(options, model);
  check_reference_model("ref-be", model, options);
  return std::make_unique<RefFixedStep>("ref-be", FixedStepMethod::BackwardEuler, options, model);
}

std::unique_ptr<Solver> make_ref_sdirk2(const SolverOptions& options, const Model& model) {
  check_reference_model("ref-sdirk2", model, options);
  return std::make_unique<RefFixedStep>("ref-sdirk2", FixedStepMethod::Sdirk2, options, model);
}

}  // namespace pbdbench
