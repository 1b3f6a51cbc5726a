// The substep that pbd and xpbd share around their own projections (pbd.cpp, xpbd.cpp). With
// h = dt / substeps and t_end the time at the end of the substep:
//   v_i += h g;  p_i = x_i + h v_i        (dynamic particles)   apply_gravity, predict_positions
//   contacts = find_contacts(p, t_end, contact_margin)                   find_substep_contacts
//   `iterations` sweeps over the constraint list in the chosen order,
//   each item projected by the solver's kernel                                   run_sweeps
//   v_i = (p_i - x_i) / h,  x_i = p_i;  velocity pass                        finish_substep
// What differs stays in the solvers: the prediction's velocity damping and the stiffness k / k'
// (pbd); the multipliers, compliance, damping and residuals (xpbd).
#pragma once

#include <array>
#include <utility>
#include <vector>

#include "core/cancel.hpp"
#include "core/contacts.hpp"
#include "core/model.hpp"
#include "core/surface_contact.hpp"
#include "solvers/kernels.hpp"
#include "solver_api/options.hpp"
#include "solvers/ordering.hpp"
#include "solver_api/solver.hpp"
#include "solvers/step_common.hpp"

namespace pbdbench {

// One item of the constraint list as a sweep applies it: its particles and its correction.
struct Stencil {
  int count = 0;                                 // particles in the stencil, 1 to 4
  std::array<int, 4> particles{-1, -1, -1, -1};  // model indices, -1 padded
  Correction correction;                         // filled by the projection
};

// The scratch of a substep, kept by the solver between steps to avoid reallocation.
struct SubstepScratch {
  explicit SubstepScratch(int particles) : jacobi(particles) {}

  Points p;                                     // (n x 3) m, predicted, then projected positions
  Points v_before;                              // (n x 3) m/s, velocities before the solve
  std::vector<Contact> contacts;                // this substep's contacts
  std::vector<double> contact_lambda;           // (contacts) kg m, accumulated dlambda (>= 0)
  std::vector<char> contact_active;             // (contacts) C < 0 at some projection
  std::vector<int> sequence;                    // this sweep's visiting order
  std::vector<std::pair<int, double>> pending;  // Jacobi: (item, dlambda) of this sweep
  JacobiAccumulator jacobi;                     // Jacobi: the corrections of this sweep
  SurfaceContactCache surface_cache;            // vertex-triangle broad phase, refit per substep
};

// The contacts of the substep at the predicted positions work.p (find_contacts at t_end with
// `margin`); the ordering is told of them (and of x, the positions at the start of the substep),
// their multipliers and activity flags are cleared, and report.contacts counts them.
void find_substep_contacts(const Model& model, double t_end, double margin, const Points& x,
                           Ordering& ordering, SubstepScratch& work, StepReport& report);

// Model constraint c: fills st.count and st.particles; returns the particles' inverse masses
// (0 past st.count). Inline: it runs once per projection.
inline Weights constraint_stencil(const Model& model, const Constraint& c, Stencil& st) {
  Weights w{};
  st.count = arity(c.kind);
  for (int i = 0; i < st.count; ++i) {
    const int p = c.particles[static_cast<size_t>(i)];
    st.particles[static_cast<size_t>(i)] = p;
    w[static_cast<size_t>(i)] = model.inv_mass[static_cast<size_t>(p)];
  }
  return w;
}

// Contact k of work.contacts: fills st.count, st.particles and the inverse masses w, returns the
// contact evaluated at work.p, and marks it active when C < 0 (the kernels project it then).
ConstraintEval contact_stencil(const Model& model, size_t k, double t_end, SubstepScratch& work,
                               Stencil& st, Weights& w);

// `options.iterations` sweeps over the constraint list: the model's constraints 0..m-1, then the
// substep's contacts m.. (m = model.constraint_count()), each in the ordering's sequence for
// (step, substep, sweep). project(j, st) projects item j at the current positions work.p: it
// fills st and returns what it did. For an Applied item:
//   Gauss-Seidel orders: p_i += dx_i at once, and multiplier_j += dlambda;
//   Jacobi: after the sweep, p_i += omega (sum of dx_i) / (n_i or 1)  (JacobiAccumulator), and
//           multiplier_j += omega dlambda   (omega = jacobi_relaxation).
// multiplier_j is work.contact_lambda[j - m] for a contact and lambda[j] for a model constraint;
// with lambda == nullptr (PBD, which keeps no multipliers) model constraints have none.
// With options.precision = Float every position and multiplier written is rounded to float: the
// rows of the stencil after each Gauss-Seidel update, all of work.p after a Jacobi sweep.
// report: skipped counts the Skipped projections, iterations the sweeps, active_contacts the
// contacts with C < 0 at some projection.
template <class Project>
void run_sweeps(const Model& model, const SolverOptions& options, const Ordering& ordering,
                long step, int substep, std::vector<double>* lambda, SubstepScratch& work,
                StepReport& report, Project&& project) {
  const int m = model.constraint_count();
  auto multiplier = [&](int j) -> double* {
    if (j >= m) return &work.contact_lambda[static_cast<size_t>(j - m)];
    return lambda != nullptr ? &(*lambda)[static_cast<size_t>(j)] : nullptr;
  };
  const bool jacobi = ordering.jacobi();
  const bool single = options.precision == Precision::Float;
  for (int sweep = 0; sweep < options.iterations; ++sweep) {
    throw_if_cancelled("a projection sweep");
    ordering.sweep(step, substep, sweep, work.sequence);
    work.pending.clear();
    for (int j : work.sequence) {
      Stencil st;
      const Projection result = project(j, st);
      if (result == Projection::Skipped) ++report.skipped;
      if (result != Projection::Applied) continue;
      double* l = multiplier(j);
      if (jacobi) {
        for (int i = 0; i < st.count; ++i)
          work.jacobi.add(st.particles[static_cast<size_t>(i)],
                          st.correction.dx[static_cast<size_t>(i)]);
        if (l != nullptr) work.pending.push_back({j, st.correction.dlambda});
      } else {
        for (int i = 0; i < st.count; ++i) {
          const int p = st.particles[static_cast<size_t>(i)];
          work.p.row(p) += st.correction.dx[static_cast<size_t>(i)].transpose();
          if (single) round_row_to_float(work.p, p);
        }
        if (l != nullptr) {
          *l += st.correction.dlambda;
          if (single) *l = round_to_float(*l);
        }
      }
    }
    if (jacobi) {
      work.jacobi.apply(work.p, options.jacobi_relaxation, options.jacobi_averaging);
      if (single) round_to_float(work.p);
      for (const auto& [j, dl] : work.pending) {
        double* l = multiplier(j);
        *l += options.jacobi_relaxation * dl;
        if (single) *l = round_to_float(*l);
      }
    }
    ++report.iterations;
  }
  for (char a : work.contact_active) report.active_contacts += a;
}

// v_i = (p_i - x_i) / h for the dynamic particles and x = p; then the velocity pass (friction
// and restitution) on the substep's contacts, from work.v_before. With Precision::Float the
// velocity update is float arithmetic (p and x hold floats), and every velocity the velocity pass
// changes is computed in double and rounded to float.
void finish_substep(const Model& model, double t_end, double h, SubstepScratch& work, Points& x,
                    Points& v, Precision precision = Precision::Double);

}  // namespace pbdbench
