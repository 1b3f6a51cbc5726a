// xpbd: Extended Position Based Dynamics, Macklin et al. 2016, Algorithm 1, run in substeps
// (Macklin et al. 2019).
//
// Per substep of h = dt / substeps (t_end = the time at its end):
//   kinematic particles: x_i = target(t_end), v_i = motion velocity;  x_n = x
//   v_i += h g,  x~_i = x_i + h v_i                                  (dynamic particles)
//   lambda = 0;  contacts = find_contacts(x~, t_end, contact_margin)
//   `iterations` sweeps in the chosen order; for a model constraint j (eq. 26):
//     alpha~ = alpha / h^2,  beta~ = h^2 beta,  gamma = alpha~ beta~ / h
//     dlambda = (-C - alpha~ lambda - gamma grad C . (x - x_n)) / ((1 + gamma) sum w |grad C|^2 + alpha~)
//     x_i += w_i grad_i C dlambda,  lambda += dlambda
//   and for a contact (rigid, alpha = 0), when C < 0: the same with the accumulated lambda >= 0
//   v_i = (x_i - x_n,i) / h;  velocity pass (friction and restitution)
// With solver.xpbd.residuals, at the end of the step (last substep; eqs. 8 and 9):
//   g = M (x - x~) - sum_j grad C_j^T lambda_j   over the dynamic particles (constraints and
//       contacts),  h_j = C_j(x) + alpha~_j lambda_j (model constraints; contacts with lambda > 0),
// reported as their 2-norms residual_g and residual_h.
// After the last substep State::lambda is turned into forces: lambda_j / h^2 (N for a distance
// constraint), so that grad_i C_j lambda_j is the force of constraint j on particle i, as for
// every solver (core/state.hpp).
// The sweeps run compiled (solvers/compiled_projection.hpp) in the run's precision: with
// solver.precision = "float" the projections compute in float32 and x, v, x~ and the multipliers
// are stored as float32 (docs/solvers.md, "Precision"); the residuals and the final lambda / h^2
// are computed in double. The per-item path (ProjectionPath::PerItem: solvers/kernels.hpp in
// double, the state rounded to float at every write) is the reference the compiled path is tested
// against.
//
// FEM strain kinds (StVK and linear elements; Macklin et al. 2016, sec. 6.3) are vector
// constraints: each is updated as a block (fem::xpbd_strain_update, eq. 16 on its components), its
// multiplier vector kept in the solver (State::lambda holds 0 for them; the residuals include
// them). Under Jacobi the vector takes omega dlambda at once, which is what the deferred update of
// the scalar multipliers gives, since no other item reads it.
//
// Jacobi order: every dlambda_j and correction is computed from the positions at the start of the
// sweep; then x_i += omega (sum of corrections) / n_i (n_i with jacobi_averaging, else 1) and
// lambda_j += omega dlambda_j. With averaging the positions move by less than M^-1 grad C^T
// dlambda while lambda takes the full omega dlambda, so at the fixed point h = 0 but g != 0: the
// multipliers (forces) then overestimate the impulse that actually moved the particles.
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/contacts.hpp"
#include "solvers/compiled_projection.hpp"
#include "core/fem.hpp"
#include "solvers/kernels.hpp"
#include "solvers/ordering.hpp"
#include "solvers/step_common.hpp"
#include "solvers/substep.hpp"

namespace pbdbench {

namespace {

class XpbdSolver final : public Solver {
 public:
  XpbdSolver(const SolverOptions& options, const Model& model, ProjectionPath path)
      : options_(options),
        particles_(model.particle_count()),
        constraints_(model.constraint_count()),
        ordering_(model, options),
        work_(model.particle_count()) {
    strain_slot_.assign(model.constraints.size(), -1);
    for (size_t j = 0; j < model.constraints.size(); ++j) {
      const Constraint& c = model.constraints[j];
      if (!is_strain_kind(c.kind)) continue;
      strain_slot_[j] = static_cast<int>(strain_alpha_.size());
      strain_alpha_.push_back(fem::strain_compliance(model.elements[static_cast<size_t>(c.element)]));
    }
    strain_lambda_.assign(strain_alpha_.size(), fem::Vec6::Zero());
    // The compiled sweeps take the scalar kinds; a model with strain-vector constraints runs on
    // the per-item path.
    const bool strain = !strain_alpha_.empty();
    if (path != ProjectionPath::PerItem && !strain)
      compiled_ = compile_projection(model, options, ProjectionRule::Xpbd, ordering_,
                                     path == ProjectionPath::CompiledOneByOne);
  }

  std::string name() const override { return "xpbd"; }
  int threads() const override { return compiled_ ? compiled_->threads() : 1; }

  StepReport step(const Model& model, State& state, double dt) override {
    check_step(model, state, dt, particles_, constraints_);
    const int substeps = options_.substeps;
    const double h = dt / substeps;
    Points& x = state.x;
    Points& v = state.v;
    const bool single = options_.precision == Precision::Float;
    if (single) {
      round_to_float(x);
      round_to_float(v);
    }
    if (!compiled_) {  // the compiled sweeps keep their own, per substep length
      coefficients_.resize(model.constraints.size());
      for (size_t j = 0; j < model.constraints.size(); ++j)
        coefficients_[j] =
            xpbd_coefficients(model.constraints[j].compliance, model.constraints[j].damping, h);
    }
    state.lambda.assign(model.constraints.size(), 0.0);
    std::vector<double>& lambda = state.lambda;

    const StepReport report = run_substeps(
        model, state, dt, substeps, [&](const Substep& sub, PhaseTimer& timer, StepReport& report) {
      note_stop(report, StopReason::FixedWork);  // solver.iterations sweeps, no convergence test
      const int s = sub.index;
      const double t_end = sub.t_end;
      if (single)
        for (const Attachment& a : model.attachments) {
          round_row_to_float(x, a.particle);
          round_row_to_float(v, a.particle);
        }
      apply_gravity(model, h, v, options_.precision);
      predict_positions(model, x, v, h, x_pred_, options_.precision);
      work_.p = x_pred_;
      work_.v_before = v;
      std::fill(lambda.begin(), lambda.end(), 0.0);
      std::fill(strain_lambda_.begin(), strain_lambda_.end(), fem::Vec6::Zero());
      timer.lap(report.time_predict);

      find_substep_contacts(model, t_end, options_.contact_margin, x, ordering_, work_, report);
      timer.lap(report.time_contacts);

      if (compiled_) {
        compiled_->set_substep(model, h);
        compiled_->begin_substep(model, work_.p, x, work_.contacts, t_end, ordering_);
        compiled_->sweeps(options_.iterations, state.step, s, ordering_, report);
        compiled_->end_substep(work_.p, s == substeps - 1 ? &lambda : nullptr, work_.contact_lambda,
                               work_.contact_active);
        for (char a : work_.contact_active) report.active_contacts += a;
      } else {
        run_sweeps(model, options_, ordering_, state.step, s, &lambda, work_, report,
                   [&](int j, Stencil& st) { return project(model, j, t_end, h, x, lambda, st); });
      }
      timer.lap(report.time_project);
      if (options_.xpbd_residuals && s == substeps - 1) {
        residuals(model, t_end, h, lambda, report);
        timer.lap(report.time_residual);  // 0 in a step without them (the clock's call goes on)
      }

      finish_substep(model, t_end, h, work_, x, v, options_.precision);
      timer.lap(report.time_velocity);
    });
    // State::lambda holds forces (core/state.hpp): the last substep's accumulated multiplier is
    // an impulse times h, the force is lambda / h^2 (Macklin et al. 2016: f = grad C^T lambda /
    // h^2). Every substep starts from lambda = 0, so this changes nothing else.
    for (double& l : lambda) l /= h * h;
    return report;
  }

 private:
  // The update of item j (model constraint j < m, else contact j - m) at the current positions
  // work_.p; x_n holds the positions at the start of the substep.
  Projection project(const Model& model, int j, double t_end, double h, const Points& x_n,
                     const std::vector<double>& lambda, Stencil& st) {
    if (j < constraints_) {
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      if (is_strain_kind(c.kind)) return project_strain(model, j, c, h, st);
      const XpbdCoefficients& k = coefficients_[static_cast<size_t>(j)];
      const Weights w = constraint_stencil(model, c, st);
      std::array<Vec3, 4> displacement{};
      if (k.gamma != 0.0)
        for (int i = 0; i < st.count; ++i) {
          const int p = st.particles[static_cast<size_t>(i)];
          displacement[static_cast<size_t>(i)] = work_.p.row(p) - x_n.row(p);
        }
      const ConstraintEval e = eval_constraint(model, c, work_.p);
      return xpbd_project(e, w, st.count, k, lambda[static_cast<size_t>(j)], displacement,
                          st.correction);
    }
    const size_t kc = static_cast<size_t>(j - constraints_);
    Weights w;
    const ConstraintEval e = contact_stencil(model, kc, t_end, work_, st, w);
    return xpbd_project_contact(e, w, st.count, work_.contact_lambda[kc], st.correction);
  }

  // A strain-vector element: the block update of its components (see the top of this file).
  Projection project_strain(const Model& model, int j, const Constraint& c, double h, Stencil& st) {
    const Weights w = constraint_stencil(model, c, st);
    const int slot = strain_slot_[static_cast<size_t>(j)];
    const fem::StrainEval e = fem::eval_strain(model.elements[static_cast<size_t>(c.element)], work_.p);
    fem::Vec6 dlambda;
    fem::Vec6& lambda = strain_lambda_[static_cast<size_t>(slot)];
    if (!fem::xpbd_strain_update(e, w, strain_alpha_[static_cast<size_t>(slot)] / (h * h), lambda,
                                 st.correction.dx, dlambda))
      return Projection::Skipped;
    lambda += (ordering_.jacobi() ? options_.jacobi_relaxation : 1.0) * dlambda;
    st.correction.dlambda = 0.0;
    return Projection::Applied;
  }

  // Macklin et al. 2016, eqs. 8 and 9, at the final positions work_.p of the substep.
  void residuals(const Model& model, double t_end, double h, const std::vector<double>& lambda,
                 StepReport& report) const {
    const Points& p = work_.p;
    Points g = Points::Zero(particles_, 3);
    for (int i = 0; i < particles_; ++i) {
      const double w = model.inv_mass[static_cast<size_t>(i)];
      if (w > 0.0) g.row(i) = (p.row(i) - x_pred_.row(i)) / w;
    }
    double h2 = 0.0;
    if (compiled_) {
      h2 = compiled_->constraint_residuals(model, p, g);
    } else {
      for (size_t j = 0; j < model.constraints.size(); ++j) {
        const Constraint& c = model.constraints[j];
        if (is_strain_kind(c.kind)) {  // g -= J^T lambda, h = C + alpha~ lambda (vectors)
          const int slot = strain_slot_[j];
          const fem::StrainEval e = fem::eval_strain(model.elements[static_cast<size_t>(c.element)], p);
          const fem::Vec6& l = strain_lambda_[static_cast<size_t>(slot)];
          for (int i = 0; i < arity(c.kind); ++i)
            for (int k = 0; k < e.components; ++k)
              g.row(c.particles[static_cast<size_t>(i)]) -=
                  l(k) * e.grad[static_cast<size_t>(k)][static_cast<size_t>(i)].transpose();
          const fem::Vec6 hj = e.C + strain_alpha_[static_cast<size_t>(slot)] * l / (h * h);
          h2 += hj.squaredNorm();  // its entries past the components are 0
          continue;
        }
        const ConstraintEval e = eval_constraint(model, c, p);
        for (int i = 0; i < arity(c.kind); ++i)
          g.row(c.particles[static_cast<size_t>(i)]) -=
              lambda[j] * e.grad[static_cast<size_t>(i)].transpose();
        const double hj = e.C + coefficients_[j].alpha_tilde * lambda[j];
        h2 += hj * hj;
      }
    }
    for (size_t k = 0; k < work_.contacts.size(); ++k) {
      const double lambda_k = work_.contact_lambda[k];
      if (!(lambda_k > 0.0)) continue;
      const Contact& c = work_.contacts[k];
      const ConstraintEval e = eval_contact(model, c, p, t_end);
      std::array<int, 4> ps{};
      const int count = contact_particles(model, c, ps);
      for (int i = 0; i < count; ++i)
        g.row(ps[static_cast<size_t>(i)]) -= lambda_k * e.grad[static_cast<size_t>(i)].transpose();
      h2 += e.C * e.C;
    }
    double g2 = 0.0;
    for (int i = 0; i < particles_; ++i)
      if (model.inv_mass[static_cast<size_t>(i)] > 0.0) g2 += g.row(i).squaredNorm();
    report.residual_g = std::sqrt(g2);
    report.residual_h = std::sqrt(h2);
  }

  SolverOptions options_;
  int particles_;
  int constraints_;
  Ordering ordering_;
  std::vector<XpbdCoefficients> coefficients_;  // (m) for the current h (per-item path only)
  // Strain kinds: slot of constraint j (-1 for the other kinds), and per slot the compliance
  // matrix (fem::strain_compliance, 1/(Pa m^3)) and the substep's multiplier vector (units of C kg).
  std::vector<int> strain_slot_;           // (m)
  std::vector<fem::Mat6> strain_alpha_;    // (strain constraints)
  std::vector<fem::Vec6> strain_lambda_;   // (strain constraints)

  // Scratch, kept between steps to avoid reallocation.
  Points x_pred_;        // (n x 3) m, x~, the predicted positions
  SubstepScratch work_;  // work_.p is the iterate x of Algorithm 1
  std::unique_ptr<CompiledProjection> compiled_;  // null on the per-item path
};

}  // namespace

std::unique_ptr<Solver> make_xpbd_solver(const SolverOptions& options, const Model& model,
                                         ProjectionPath path) {
  // FEM elements enter xpbd only through their constraint form (the FEM kinds: Macklin and
  // Mueller 2021 for the stable neo-Hookean, Macklin et al. 2016 for StVK and linear); corotated
  // has none.
  for (size_t k = 0; k < model.elements.size(); ++k)
    if (!fem::has_constraint_form(model.elements[k].material))
      throw std::invalid_argument(
          "xpbd cannot simulate element " + std::to_string(k) + ": its material " +
          to_string(model.elements[k].material) +
          " has no XPBD constraint form (stable_neo_hookean, stvk and linear have); use a "
          "reference solver");
  for (size_t j = 0; j < model.constraints.size(); ++j)
    if (is_strain_kind(model.constraints[j].kind) && model.constraints[j].damping != 0.0)
      throw std::invalid_argument("xpbd: constraint " + std::to_string(j) + " (" +
                                  to_string(model.constraints[j].kind) +
                                  ") has damping: the strain-vector constraints have none");
  return std::make_unique<XpbdSolver>(options, model, path);
}

}  // namespace pbdbench
