// force-symplectic: explicit symplectic Euler with springs and penalty contacts
// (solvers/force_symplectic.hpp, docs/solvers.md).
//
// Per substep of h = dt / substeps (t_end = the time at its end):
//   kinematic particles: x_i = target(t_end), v_i = motion velocity             (set_kinematic)
//   contacts = find_contacts(x, t_end, contact_margin)
//   f = sum_j grad C_j lambda_j,  lambda_j = -C_j / alpha_j - beta_j dC_j/dt  (model constraints)
//     - grad E_e                      (FEM elements other than stable neo-Hookean: corotated,
//                                      StVK, linear; their strain constraints are skipped)
//     + sum_k F_k grad C_k,  F_k = max(0, k_c (-C_k) - d_c v_n,k) for C_k < 0   (contacts)
//   v_i += h g + h w_i f_i,  x_i += h v_i                                     (dynamic particles)
// All forces are evaluated at the positions and velocities at the start of the substep (with
// the kinematic particles and moving spheres at t_end, where pbd and xpbd project against them).
// With only conservative forces this is the symplectic Euler method: on a linear spring it keeps
// v^2 + omega^2 u^2 - h omega^2 u v exactly and is stable for omega h < 2.
// State::lambda: the last substep's lambda_j (N for a distance constraint), so that
// grad_i C_j lambda_j is the force of constraint j on particle i (core/state.hpp).
#include "solvers/force_symplectic.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "core/cancel.hpp"
#include "core/constraint_functions.hpp"
#include "core/fem.hpp"
#include "solvers/step_common.hpp"

namespace pbdbench {

double add_constraint_force(const Model& model, const Constraint& c, const Points& x,
                            const Points& v, Points& f, bool& valid) {
  const ConstraintEval e = eval_constraint(model, c, x);
  valid = e.valid;
  if (!e.valid) return 0.0;
  const int count = arity(c.kind);
  double rate = 0.0;  // dC/dt = grad C . v, units of C per second
  if (c.damping != 0.0)
    for (int i = 0; i < count; ++i)
      rate += e.grad[static_cast<size_t>(i)].dot(
          Vec3(v.row(c.particles[static_cast<size_t>(i)])));
  const double lambda = -e.C / c.compliance - c.damping * rate;
  for (int i = 0; i < count; ++i)
    f.row(c.particles[static_cast<size_t>(i)]) +=
        (lambda * e.grad[static_cast<size_t>(i)]).transpose();
  return lambda;
}

ContactForce add_contact_force(const Model& model, const Contact& contact, const Points& x,
                               const Points& v, double t, double stiffness, double damping,
                               Points& f) {
  const ConstraintEval e = eval_contact(model, contact, x, t);
  ContactForce out;
  out.C = e.C;
  out.valid = e.valid;
  if (!e.valid || !(e.C < 0.0)) return out;
  const Vec3 relative = Vec3(v.row(contact.a)) - contact_surface_velocity(model, contact, v, t);
  const double normal_velocity = e.grad[0].dot(relative);  // > 0: separating
  out.force = std::max(0.0, -stiffness * e.C - damping * normal_velocity);
  f.row(contact.a) += (out.force * e.grad[0]).transpose();
  if (contact.kind == ContactKind::Particle)
    f.row(contact.b) += (out.force * e.grad[1]).transpose();
  return out;
}

namespace {

class ForceSymplecticSolver final : public Solver {
 public:
  ForceSymplecticSolver(const SolverOptions& options, const Model& model)
      : options_(options),
        particles_(model.particle_count()),
        constraints_(model.constraint_count()) {
    for (size_t k = 0; k < model.elements.size(); ++k)
      if (model.elements[k].material != Material::StableNeoHookean)
        energy_elements_.push_back(static_cast<int>(k));
  }

  std::string name() const override { return "force-symplectic"; }

  StepReport step(const Model& model, State& state, double dt) override {
    check_step(model, state, dt, particles_, constraints_);
    Points& x = state.x;
    Points& v = state.v;
    state.lambda.assign(model.constraints.size(), 0.0);
    f_.resize(particles_, 3);

    return run_substeps(model, state, dt, options_.substeps,
                        [&](const Substep& sub, PhaseTimer& timer, StepReport& report) {
      note_stop(report, StopReason::FixedWork);  // an explicit step
      const double h = sub.h;
      const double t_end = sub.t_end;
      timer.lap(report.time_predict);

      contacts_ = find_contacts(model, x, t_end, options_.contact_margin);
      report.contacts += static_cast<int>(contacts_.size());
      timer.lap(report.time_contacts);

      // Forces at (x, v), the start of the substep.
      f_.setZero();
      for (size_t j = 0; j < model.constraints.size(); ++j) {
        if (is_strain_kind(model.constraints[j].kind)) continue;  // its element's energy (below)
        bool valid = true;
        state.lambda[j] = add_constraint_force(model, model.constraints[j], x, v, f_, valid);
        if (!valid) ++report.skipped;
      }
      for (int k : energy_elements_) {
        const FemElement& e = model.elements[static_cast<size_t>(k)];
        const fem::Vec12 grad = fem::element_gradient(e, x);
        for (int i = 0; i < e.vertices; ++i)
          f_.row(e.particles[static_cast<size_t>(i)]) -= grad.segment<3>(3 * i).transpose();
      }
      for (const Contact& c : contacts_) {
        const ContactForce r = add_contact_force(model, c, x, v, t_end,
                                                 options_.force_contact_stiffness,
                                                 options_.force_contact_damping, f_);
        if (!r.valid) ++report.skipped;
        else if (r.C < 0.0) ++report.active_contacts;
      }
      timer.lap(report.time_project);

      // Symplectic Euler: the velocity first, then the position with the new velocity.
      for (int i = 0; i < particles_; ++i) {
        const double w = model.inv_mass[static_cast<size_t>(i)];
        if (!(w > 0.0)) continue;
        v.row(i) += (h * (model.gravity + w * Vec3(f_.row(i)))).transpose();
        x.row(i) += h * v.row(i);
      }
      timer.lap(report.time_velocity);
    });
  }

 private:
  SolverOptions options_;
  int particles_;
  int constraints_;
  std::vector<int> energy_elements_;  // FEM elements with no constraint form (corotated): their
                                      // force is -grad E from core/fem.hpp

  // Scratch, kept between steps to avoid reallocation.
  Points f_;                       // (n x 3) N, the forces of the substep
  std::vector<Contact> contacts_;  // the substep's contact candidates
};

}  // namespace

std::unique_ptr<Solver> make_force_symplectic_solver(const SolverOptions& options,
                                                     const Model& model) {
  if (model.surface_contact || model.self_contact)
    throw std::invalid_argument(
        "force-symplectic does not simulate vertex-triangle contact (scene.surface_contact or "
        "scene.self_contact): pbd and xpbd do; ref-be refuses it too");
  for (size_t j = 0; j < model.constraints.size(); ++j) {
    const Constraint& c = model.constraints[j];
    if (!(c.compliance > 0.0)) {
      std::ostringstream what;
      what << "force-symplectic cannot simulate constraint " << j << " (" << to_string(c.kind)
           << ", compliance " << c.compliance
           << "): a force-based solver needs a compliance alpha > 0, the spring of energy "
              "C^2 / (2 alpha); a rigid constraint has no force law (give it a compliance, or "
              "use pbd or xpbd)";
      throw std::invalid_argument(what.str());
    }
  }
  return std::make_unique<ForceSymplecticSolver>(options, model);
}

}  // namespace pbdbench
