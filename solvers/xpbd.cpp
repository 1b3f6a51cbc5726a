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
//
// Jacobi order: every dlambda_j and correction is computed from the positions at the start of the
// sweep; then x_i += omega (sum of corrections) / n_i (n_i with jacobi_averaging, else 1) and
// lambda_j += omega dlambda_j. With averaging the positions move by less than M^-1 grad C^T
// dlambda while lambda takes the full omega dlambda, so at the fixed point h = 0 but g != 0: the
// multipliers (forces) then overestimate the impulse that actually moved the particles.
#include <cmath>
#include <memory>
#include <vector>

#include "core/contacts.hpp"
#include "solvers/kernels.hpp"
#include "solvers/ordering.hpp"
#include "solvers/step_common.hpp"
#include "solvers/velocity_pass.hpp"

namespace pbdbench {

namespace {

class XpbdSolver final : public Solver {
 public:
  XpbdSolver(const SolverOptions& options, const Model& model)
      : options_(options),
        particles_(model.particle_count()),
        constraints_(model.constraint_count()),
        ordering_(model, options),
        jacobi_(model.particle_count()) {}

  std::string name() const override { return "xpbd"; }

  StepReport step(const Model& model, State& state, double dt) override {
    check_step(model, state, dt, particles_, constraints_);
    StepReport report;
    const int substeps = options_.substeps;
    const double h = dt / substeps;
    report.substeps = substeps;
    const int n = particles_;
    const int m = constraints_;
    Points& x = state.x;
    Points& v = state.v;
    coefficients_.resize(model.constraints.size());
    for (size_t j = 0; j < model.constraints.size(); ++j)
      coefficients_[j] =
          xpbd_coefficients(model.constraints[j].compliance, model.constraints[j].damping, h);
    state.lambda.assign(model.constraints.size(), 0.0);
    std::vector<double>& lambda = state.lambda;

    for (int s = 0; s < substeps; ++s) {
      const double t_end = state.time + (s + 1) * h;
      PhaseTimer timer;
      set_kinematic(model, x, v, t_end);
      for (int i = 0; i < n; ++i)
        if (model.inv_mass[static_cast<size_t>(i)] > 0.0)
          v.row(i) += (h * model.gravity).transpose();
      x_pred_ = x;
      for (int i = 0; i < n; ++i)
        if (model.inv_mass[static_cast<size_t>(i)] > 0.0) x_pred_.row(i) += h * v.row(i);
      p_ = x_pred_;
      v_before_ = v;
      std::fill(lambda.begin(), lambda.end(), 0.0);
      timer.lap(report.time_predict);

      contacts_ = find_contacts(model, x_pred_, t_end, options_.contact_margin);
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
            if (project(model, j, m, t_end, x, lambda, st, report) != Projection::Applied) continue;
            for (int i = 0; i < st.count; ++i)
              jacobi_.add(st.particles[static_cast<size_t>(i)],
                          st.correction.dx[static_cast<size_t>(i)]);
            pending_.push_back({j, st.correction.dlambda});
          }
          jacobi_.apply(p_, options_.jacobi_relaxation, options_.jacobi_averaging);
          for (const auto& [j, dl] : pending_)
            multiplier(j, m, lambda) += options_.jacobi_relaxation * dl;
        } else {
          for (int j : sequence_) {
            Stencil st;
            if (project(model, j, m, t_end, x, lambda, st, report) != Projection::Applied) continue;
            for (int i = 0; i < st.count; ++i)
              p_.row(st.particles[static_cast<size_t>(i)]) +=
                  st.correction.dx[static_cast<size_t>(i)].transpose();
            multiplier(j, m, lambda) += st.correction.dlambda;
          }
        }
        ++report.iterations;
      }
      for (char a : contact_active_) report.active_contacts += a;
      if (options_.xpbd_residuals && s == substeps - 1) residuals(model, t_end, lambda, report);
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

  double& multiplier(int j, int m, std::vector<double>& lambda) {
    return j < m ? lambda[static_cast<size_t>(j)] : contact_lambda_[static_cast<size_t>(j - m)];
  }

  // The update of item j (model constraint j < m, else contact j - m) at the current positions
  // p_; x_n holds the positions at the start of the substep.
  Projection project(const Model& model, int j, int m, double t_end, const Points& x_n,
                     const std::vector<double>& lambda, Stencil& st, StepReport& report) {
    Weights w{};
    Projection result;
    if (j < m) {
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      const XpbdCoefficients& k = coefficients_[static_cast<size_t>(j)];
      st.count = arity(c.kind);
      std::array<Vec3, 4> displacement{};
      for (int i = 0; i < st.count; ++i) {
        const int p = c.particles[static_cast<size_t>(i)];
        st.particles[static_cast<size_t>(i)] = p;
        w[static_cast<size_t>(i)] = model.inv_mass[static_cast<size_t>(p)];
        if (k.gamma != 0.0) displacement[static_cast<size_t>(i)] = p_.row(p) - x_n.row(p);
      }
      const ConstraintEval e = eval_constraint(c, p_);
      result = xpbd_project(e, w, st.count, k, lambda[static_cast<size_t>(j)], displacement,
                            st.correction);
    } else {
      const size_t kc = static_cast<size_t>(j - m);
      const Contact& c = contacts_[kc];
      st.count = c.kind == ContactKind::Particle ? 2 : 1;
      st.particles = {c.a, c.b, -1, -1};
      w[0] = model.inv_mass[static_cast<size_t>(c.a)];
      if (st.count == 2) w[1] = model.inv_mass[static_cast<size_t>(c.b)];
      const ConstraintEval e = eval_contact(model, c, p_, t_end);
      if (e.valid && e.C < 0.0) contact_active_[kc] = 1;
      result = xpbd_project_contact(e, w, st.count, contact_lambda_[kc], st.correction);
    }
    if (result == Projection::Skipped) ++report.skipped;
    return result;
  }

  // Macklin et al. 2016, eqs. 8 and 9, at the final positions p_ of the substep.
  void residuals(const Model& model, double t_end, const std::vector<double>& lambda,
                 StepReport& report) const {
    Points g = Points::Zero(particles_, 3);
    for (int i = 0; i < particles_; ++i) {
      const double w = model.inv_mass[static_cast<size_t>(i)];
      if (w > 0.0) g.row(i) = (p_.row(i) - x_pred_.row(i)) / w;
    }
    double h2 = 0.0;
    for (size_t j = 0; j < model.constraints.size(); ++j) {
      const Constraint& c = model.constraints[j];
      const ConstraintEval e = eval_constraint(c, p_);
      for (int i = 0; i < arity(c.kind); ++i)
        g.row(c.particles[static_cast<size_t>(i)]) -=
            lambda[j] * e.grad[static_cast<size_t>(i)].transpose();
      const double hj = e.C + coefficients_[j].alpha_tilde * lambda[j];
      h2 += hj * hj;
    }
    for (size_t k = 0; k < contacts_.size(); ++k) {
      if (!(contact_lambda_[k] > 0.0)) continue;
      const Contact& c = contacts_[k];
      const ConstraintEval e = eval_contact(model, c, p_, t_end);
      g.row(c.a) -= contact_lambda_[k] * e.grad[0].transpose();
      if (c.kind == ContactKind::Particle) g.row(c.b) -= contact_lambda_[k] * e.grad[1].transpose();
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
  JacobiAccumulator jacobi_;
  std::vector<XpbdCoefficients> coefficients_;  // (m) for the current h

  // Scratch, kept between steps to avoid reallocation.
  Points p_;                                     // (n x 3) m, the iterate x of Algorithm 1
  Points x_pred_;                                // (n x 3) m, x~, the predicted positions
  Points v_before_;                              // (n x 3) m/s, velocities before the solve
  std::vector<Contact> contacts_;                // this substep's contacts
  std::vector<double> contact_lambda_;           // (contacts) kg m, accumulated multipliers (>= 0)
  std::vector<char> contact_active_;             // (contacts) C < 0 at some projection
  std::vector<int> sequence_;                    // this sweep's visiting order
  std::vector<std::pair<int, double>> pending_;  // Jacobi: (item, dlambda)
};

}  // namespace

std::unique_ptr<Solver> make_xpbd_solver(const SolverOptions& options, const Model& model) {
  return std::make_unique<XpbdSolver>(options, model);
}

}  // namespace pbdbench
