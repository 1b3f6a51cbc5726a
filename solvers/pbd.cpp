// pbd: Position Based Dynamics, Mueller et al. 2007, Algorithm 1, run in substeps.
//
// Per substep of h = dt / substeps (t_end = the time at its end):
//   kinematic particles: x_i = target(t_end), v_i = motion velocity           (attachments)
//   v_i += h g                                                   (dynamic particles, line 5)
//   damp velocities (sec. 3.5) when solver.pbd.velocity_damping > 0            (line 6)
//   p_i = x_i + h v_i                                                          (line 7)
//   contacts = find_contacts(p, t_end, contact_margin)                         (line 8)
//   `iterations` sweeps in the chosen order: each model constraint projected with its
//   stiffness k, each contact projected with k = 1 when C < 0                  (lines 9-11)
//   k comes from the scene's one material (solvers/pbd_material.hpp): derived from the
//   constraint's compliance for this h and `iterations` (solver.pbd.material = "compliance", the
//   default), or the explicit *_stiffness override (material = "stiffness"; k' = 1-(1-k)^(1/n)
//   with solver.pbd.stiffness_correction)
//   v_i = (p_i - x_i) / h,  x_i = p_i                                          (lines 12-15)
//   velocity pass: friction and restitution on the touching contacts           (line 16)
// The sweeps run compiled (solvers/compiled_projection.hpp) in the run's precision: with
// solver.precision = "float" the projections compute in float32, and x, v and p are stored as
// float32 (docs/solvers.md, "Precision"). The per-item path (ProjectionPath::PerItem: each item
// evaluated by core/constraint_functions.hpp and projected by solvers/kernels.hpp, in double with
// the projections' state rounded to float at every write) is the reference the compiled path is
// tested against. Prediction and velocity update compute in float too; friction and restitution
// compute in double and round what they write.
#include <algorithm>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "solvers/compiled_projection.hpp"
#include "solvers/kernels.hpp"
#include "solvers/ordering.hpp"
#include "solvers/pbd_material.hpp"
#include "solvers/step_common.hpp"
#include "solvers/substep.hpp"
#include "solver_api/velocity_pass.hpp"

namespace pbdbench {

namespace {

class PbdSolver final : public Solver {
 public:
  PbdSolver(const SolverOptions& options, const Model& model, ProjectionPath path)
      : options_(options),
        particles_(model.particle_count()),
        constraints_(model.constraint_count()),
        ordering_(model, options),
        work_(model.particle_count()) {
    if (path != ProjectionPath::PerItem)
      compiled_ = compile_projection(model, options, ProjectionRule::Pbd, ordering_,
                                     path == ProjectionPath::CompiledOneByOne);
    if (options.pbd_material == PbdMaterial::Compliance)
      inverse_mass_sums_ = pbd_inverse_mass_sums(model);
    else
      stiffness_ = pbd_stiffness(model, options, inverse_mass_sums_, 0.0);
    if (options.pbd_velocity_damping > 0.0) bodies_ = dynamic_bodies(model);
  }

  std::string name() const override { return "pbd"; }
  int threads() const override { return compiled_ ? compiled_->threads() : 1; }

  StepReport step(const Model& model, State& state, double dt) override {
    check_step(model, state, dt, particles_, constraints_);
    // PBD has no multipliers, hence no constraint forces (core/state.hpp): NaN.
    state.lambda.assign(model.constraints.size(), std::numeric_limits<double>::quiet_NaN());
    Points& x = state.x;
    Points& v = state.v;
    const bool single = options_.precision == Precision::Float;
    if (single) {
      round_to_float(x);
      round_to_float(v);
    }
    return run_substeps(model, state, dt, options_.substeps,
                        [&](const Substep& sub, PhaseTimer& timer, StepReport& report) {
      note_stop(report, StopReason::FixedWork);  // solver.iterations sweeps, no convergence test
      const double h = sub.h;
      const double t_end = sub.t_end;
      if (single)
        for (const Attachment& a : model.attachments) {
          round_row_to_float(x, a.particle);
          round_row_to_float(v, a.particle);
        }
      apply_gravity(model, h, v, options_.precision);
      damp_velocities(bodies_, model.inv_mass, x, v, options_.pbd_velocity_damping);
      if (single && options_.pbd_velocity_damping != 0.0) round_to_float(v);
      predict_positions(model, x, v, h, work_.p, options_.precision);
      work_.v_before = v;
      timer.lap(report.time_predict);

      find_substep_contacts(model, t_end, options_.contact_margin, x, ordering_, work_, report);
      timer.lap(report.time_contacts);

      if (compiled_) {
        compiled_->set_substep(model, h);
        compiled_->begin_substep(model, work_.p, x, work_.contacts, t_end, ordering_);
        compiled_->sweeps(options_.iterations, state.step, sub.index, ordering_, report);
        compiled_->end_substep(work_.p, nullptr, work_.contact_lambda, work_.contact_active);
        for (char a : work_.contact_active) report.active_contacts += a;
      } else {
        if (options_.pbd_material == PbdMaterial::Compliance && h != stiffness_h_) {
          stiffness_ = pbd_stiffness(model, options_, inverse_mass_sums_, h);
          stiffness_h_ = h;
        }
        run_sweeps(model, options_, ordering_, state.step, sub.index, nullptr, work_, report,
                   [&](int j, Stencil& st) { return project(model, j, t_end, st); });
      }
      timer.lap(report.time_project);

      finish_substep(model, t_end, h, work_, x, v, options_.precision);
      timer.lap(report.time_velocity);
    });
  }

 private:
  // The correction of item j of the constraint list (model constraint j < m, else contact
  // j - m) at the current predicted positions work_.p.
  Projection project(const Model& model, int j, double t_end, Stencil& st) {
    if (j < constraints_) {
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      const Weights w = constraint_stencil(model, c, st);
      const ConstraintEval e = eval_constraint(c, work_.p);
      return pbd_project(e, w, st.count, stiffness_[static_cast<size_t>(j)], st.correction);
    }
    Weights w;
    const ConstraintEval e =
        contact_stencil(model, static_cast<size_t>(j - constraints_), t_end, work_, st, w);
    return pbd_project_contact(e, w, st.count, st.correction);
  }

  SolverOptions options_;
  int particles_;
  int constraints_;
  Ordering ordering_;
  std::vector<double> stiffness_;         // (m) k of the per-item path (explicit, or derived
                                          // for the substep stiffness_h_)
  double stiffness_h_ = 0.0;
  std::vector<double> inverse_mass_sums_;  // (m) S of pbd_material.hpp, when derived
  std::vector<std::vector<int>> bodies_;  // for velocity damping
  SubstepScratch work_;                   // scratch, kept between steps
  std::unique_ptr<CompiledProjection> compiled_;  // null on the per-item path
};

}  // namespace

std::unique_ptr<Solver> make_pbd_solver(const SolverOptions& options, const Model& model,
                                        ProjectionPath path) {
  // A FEM element is a material (Pa) with no per-constraint stiffness k.
  if (const std::string problem = pbd_material_problem(model); !problem.empty())
    throw std::invalid_argument(problem);
  return std::make_unique<PbdSolver>(options, model, path);
}

}  // namespace pbdbench
