// pbd: Position Based Dynamics, Mueller et al. 2007, Algorithm 1, run in substeps.
//
// Per substep of h = dt / substeps (t_end = the time at its end):
//   kinematic particles: x_i = target(t_end), v_i = motion velocity           (attachments)
//   v_i += h g                                                   (dynamic particles, line 5)
//   damp velocities (sec. 3.5) when solver.pbd.velocity_damping > 0            (line 6)
//   p_i = x_i + h v_i                                                          (line 7)
//   contacts = find_contacts(p, t_end, contact_margin)                         (line 8)
//   `iterations` sweeps in the chosen order: each model constraint projected with its
//   stiffness k (or k' = 1-(1-k)^(1/iterations) with solver.pbd.stiffness_correction), each
//   contact projected with k = 1 when C < 0                                    (lines 9-11)
//   v_i = (p_i - x_i) / h,  x_i = p_i                                          (lines 12-15)
//   velocity pass: friction and restitution on the touching contacts           (line 16)
#include <memory>
#include <vector>

#include "core/contacts.hpp"
#include "solvers/kernels.hpp"
#include "solvers/ordering.hpp"
#include "solvers/step_common.hpp"
#include "solvers/velocity_pass.hpp"

namespace pbdbench {

namespace {

class PbdSolver final : public Solver {
 public:
  PbdSolver(const SolverOptions& options, const Model& model)
      : options_(options),
        particles_(model.particle_count()),
        constraints_(model.constraint_count()),
        ordering_(model, options),
        jacobi_(model.particle_count()) {
    stiffness_.reserve(model.constraints.size());
    for (const Constraint& c : model.constraints)
      stiffness_.push_back(options.pbd_stiffness_correction
                               ? pbd_corrected_stiffness(c.stiffness, options.iterations)
                               : c.stiffness);
    if (options.pbd_velocity_damping > 0.0) bodies_ = dynamic_bodies(model);
  }

  std::string name() const override { return "pbd"; }

  StepReport step(const Model& model, State& state, double dt) override {
    check_step(model, state, dt, particles_, constraints_);
    StepReport report;
    const int substeps = options_.substeps;
    const double h = dt / substeps;
    report.substeps = substeps;
    state.lambda.assign(model.constraints.size(), 0.0);  // PBD has no multipliers
    Points& x = state.x;
    Points& v = state.v;
    const int n = particles_;
    const int m = constraints_;

    for (int s = 0; s < substeps; ++s) {
      const double t_end = state.time + (s + 1) * h;
      PhaseTimer timer;
      set_kinematic(model, x, v, t_end);
      for (int i = 0; i < n; ++i)
        if (model.inv_mass[static_cast<size_t>(i)] > 0.0)
          v.row(i) += (h * model.gravity).transpose();
      damp_velocities(bodies_, model.inv_mass, x, v, options_.pbd_velocity_damping);
      p_ = x;
      for (int i = 0; i < n; ++i)
        if (model.inv_mass[static_cast<size_t>(i)] > 0.0) p_.row(i) += h * v.row(i);
      v_before_ = v;
      timer.lap(report.time_predict);

      contacts_ = find_contacts(model, p_, t_end, options_.contact_margin);
      ordering_.set_contacts(model, contacts_);
      contact_lambda_.assign(contacts_.size(), 0.0);
      contact_active_.assign(contacts_.size(), 0);
      report.contacts += static_cast<int>(contacts_.size());
      timer.lap(report.time_contacts);

      for (int sweep = 0; sweep < options_.iterations; ++sweep) {
        ordering_.sweep(state.step, s, sweep, sequence_);
        if (ordering_.jacobi()) {
          pending_.clear();
          for (int j : sequence_) {
            Stencil st;
            if (project(model, j, m, t_end, st, report) != Projection::Applied) continue;
            for (int i = 0; i < st.count; ++i)
              jacobi_.add(st.particles[static_cast<size_t>(i)],
                          st.correction.dx[static_cast<size_t>(i)]);
            if (j >= m) pending_.push_back({j - m, st.correction.dlambda});
          }
          jacobi_.apply(p_, options_.jacobi_relaxation, options_.jacobi_averaging);
          for (const auto& [k, dl] : pending_)
            contact_lambda_[static_cast<size_t>(k)] += options_.jacobi_relaxation * dl;
        } else {
          for (int j : sequence_) {
            Stencil st;
            if (project(model, j, m, t_end, st, report) != Projection::Applied) continue;
            for (int i = 0; i < st.count; ++i)
              p_.row(st.particles[static_cast<size_t>(i)]) +=
                  st.correction.dx[static_cast<size_t>(i)].transpose();
            if (j >= m) contact_lambda_[static_cast<size_t>(j - m)] += st.correction.dlambda;
          }
        }
        ++report.iterations;
      }
      for (char a : contact_active_) report.active_contacts += a;
      timer.lap(report.time_project);

      for (int i = 0; i < n; ++i) {
        if (model.inv_mass[static_cast<size_t>(i)] > 0.0) v.row(i) = (p_.row(i) - x.row(i)) / h;
        x.row(i) = p_.row(i);
      }
      velocity_pass(model, contacts_, contact_lambda_, x, v_before_, v, t_end, h);
      timer.lap(report.time_velocity);
    }
    state.time += dt;
    state.step += 1;
    return report;
  }

 private:
  struct Stencil {
    int count = 0;
    std::array<int, 4> particles{-1, -1, -1, -1};
    Correction correction;
  };

  // The correction of item j of the constraint list (model constraint j < m, else contact
  // j - m) at the current predicted positions p_.
  Projection project(const Model& model, int j, int m, double t_end, Stencil& st,
                     StepReport& report) {
    Weights w{};
    Projection result;
    if (j < m) {
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      st.count = arity(c.kind);
      for (int i = 0; i < st.count; ++i) {
        st.particles[static_cast<size_t>(i)] = c.particles[static_cast<size_t>(i)];
        w[static_cast<size_t>(i)] =
            model.inv_mass[static_cast<size_t>(c.particles[static_cast<size_t>(i)])];
      }
      const ConstraintEval e = eval_constraint(c, p_);
      result = pbd_project(e, w, st.count, stiffness_[static_cast<size_t>(j)], st.correction);
    } else {
      const size_t k = static_cast<size_t>(j - m);
      const Contact& c = contacts_[k];
      st.count = c.kind == ContactKind::Particle ? 2 : 1;
      st.particles = {c.a, c.b, -1, -1};
      w[0] = model.inv_mass[static_cast<size_t>(c.a)];
      if (st.count == 2) w[1] = model.inv_mass[static_cast<size_t>(c.b)];
      const ConstraintEval e = eval_contact(model, c, p_, t_end);
      if (e.valid && e.C < 0.0) contact_active_[k] = 1;
      result = pbd_project_contact(e, w, st.count, st.correction);
    }
    if (result == Projection::Skipped) ++report.skipped;
    return result;
  }

  SolverOptions options_;
  int particles_;
  int constraints_;
  Ordering ordering_;
  JacobiAccumulator jacobi_;
  std::vector<double> stiffness_;         // (m) k, or k' with the stiffness correction
  std::vector<std::vector<int>> bodies_;  // for velocity damping

  // Scratch, kept between steps to avoid reallocation.
  Points p_;                                     // (n x 3) m, predicted and projected positions
  Points v_before_;                              // (n x 3) m/s, velocities before the solve
  std::vector<Contact> contacts_;                // this substep's contacts
  std::vector<double> contact_lambda_;           // (contacts) kg m, accumulated corrections
  std::vector<char> contact_active_;             // (contacts) C < 0 at some projection
  std::vector<int> sequence_;                    // this sweep's visiting order
  std::vector<std::pair<int, double>> pending_;  // Jacobi: (contact, dlambda)
};

}  // namespace

std::unique_ptr<Solver> make_pbd_solver(const SolverOptions& options, const Model& model) {
  return std::make_unique<PbdSolver>(options, model);
}

}  // namespace pbdbench
