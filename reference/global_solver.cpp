// global-cholmod, global-cg, global-ceres: the simulation whose every (sub)step is the global
// projection solved to convergence (reference/global_problem.hpp, docs/global.md). The substep
// around it is pbd's and xpbd's (solver_api/substep_driver.hpp, solver_api/velocity_pass.hpp), so that only the projection differs:
//   kinematic particles on their targets at t_end;  v += h g;  x~ = x + h v
//   contacts = find_contacts(x~, t_end, contact_margin)
//   x* = the global step from (x, x~) with those contacts, to solver.global.tolerance
//   v = (x* - x) / h;  x = x*;  velocity pass (friction, restitution) with the contacts' lambda
// State::lambda: -C/alpha for the compliant constraints, lambda_r / h^2 for the rigid ones
// (forces per unit of C, as every solver leaves them). The rigid rows' multipliers are carried
// from one substep to the next as the starting guess.
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/contacts.hpp"
#include "reference/global_ceres.hpp"
#include "reference/global_newton.hpp"
#include "reference/global_problem.hpp"
#include "reference/global_solver.hpp"
#include "solver_api/substep_driver.hpp"
#include "solver_api/velocity_pass.hpp"

namespace pbdbench {

namespace {

class GlobalSolver final : public Solver {
 public:
  GlobalSolver(const SolverOptions& options, const Model& model)
      : options_(options), problem_(model) {
    if (options.name == "global-cholmod")
      newton_ = std::make_unique<GlobalNewton>(options, GlobalLinearSolver::Cholmod);
    else if (options.name == "global-cg")
      newton_ = std::make_unique<GlobalNewton>(options, GlobalLinearSolver::ConjugateGradient);
    else if (options.name != "global-ceres")
      throw std::invalid_argument("solver.name = '" + options.name + "' is not a global solver");
  }

  std::string name() const override { return options_.name; }

  StepReport step(const Model& model, State& state, double dt) override {
    check_step(model, state, dt, model.particle_count(), model.constraint_count());
    if (&model != &problem_.model())
      throw std::invalid_argument(name() + ": step() was given another model than it was built for");
    Points& x = state.x;
    Points& v = state.v;
    StepReport report = run_substeps(model, state, dt, options_.substeps,
                                     [&](const Substep& sub, PhaseTimer& timer, StepReport& report) {
      const double h = sub.h;
      const double t_end = sub.t_end;
      apply_gravity(model, h, v);
      predict_positions(model, x, v, h, p_);
      v_before_ = v;
      timer.lap(report.time_predict);

      contacts_ = find_contacts(model, p_, t_end, options_.contact_margin);
      report.contacts += static_cast<int>(contacts_.size());
      problem_.begin_step(x, p_, h, t_end, contacts_);
      timer.lap(report.time_contacts);

      // Rigid rows first, in a fixed order: their multipliers carry over; contacts start at 0.
      const size_t rigid = problem_.rows().size() - contacts_.size();
      row_lambda_.resize(rigid);
      row_lambda_.resize(problem_.rows().size(), 0.0);
      const GlobalResult r = newton_ ? newton_->solve(problem_, p_, row_lambda_)
                               : solve_global_ceres(problem_, options_, p_, row_lambda_);
      report.newton_iterations += r.iterations;
      report.linear_iterations += r.inner_iterations;
      report.linear_setups += r.factorizations;
      report.cholesky_factorizations += r.factorizations;
      report.linear_solves += r.linear_solves;
      report.time_linear += r.time_linear;
      if (!r.converged) ++report.convergence_failures;
      note_stop(report, r.stop);
      report.residual_g = r.residual_g;
      report.residual_h = r.residual_h;
      report.residual_position = r.residual;
      report.factor_cost_ratio = r.factor_cost_ratio;
      timer.lap(report.time_project);

      contact_lambda_.assign(row_lambda_.begin() + static_cast<std::ptrdiff_t>(rigid),
                             row_lambda_.end());
      for (double l : contact_lambda_) report.active_contacts += l > 0.0 ? 1 : 0;
      update_from_positions(model, h, p_, x, v);
      velocity_pass(model, contacts_, contact_lambda_, x, v_before_, v, t_end, h);
      timer.lap(report.time_velocity);
    });
    // The constraint forces at the end of the step; state.time has advanced, which they do not read.
    problem_.constraint_forces(x, row_lambda_, state.lambda);
    return report;
  }

 private:
  SolverOptions options_;
  GlobalProblem problem_;
  std::unique_ptr<GlobalNewton> newton_;  // null for global-ceres
  // Scratch, kept between steps to avoid reallocation.
  Points p_;                             // (n x 3) m, predicted, then solved positions
  Points v_before_;                      // (n x 3) m/s, velocities before the solve
  std::vector<Contact> contacts_;        // this substep's contacts
  std::vector<double> contact_lambda_;   // (contacts) kg m, their multipliers after the solve
  std::vector<double> row_lambda_;
};

}  // namespace

std::unique_ptr<Solver> make_global_solver(const SolverOptions& options, const Model& model) {
  return std::make_unique<GlobalSolver>(options, model);
}

}  // namespace pbdbench
