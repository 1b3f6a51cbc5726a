// The projection sweeps of pbd and xpbd, compiled at solver setup. The model's constraints become
// one block per kind (solvers/projection_kernels.hpp: struct of arrays with the particle indices,
// rest values, inverse masses and the constant parts of each projection), ordered as the order
// visits them, and the sweeps run straight-line kernels over those blocks in the precision of
// the run (T = double or float: the positions, multipliers and every operation in T).
//
//   auto c = compile_projection(model, options, rule, ordering);   // at setup
//   per substep:  c->set_substep(model, h)             (rest values; xpbd: alpha~, gamma, 1/D)
//                 c->begin_substep(model, p, x_n, contacts, t_end, ordering)
//                 c->sweeps(iterations, step, substep, ordering, report)
//                 c->end_substep(p, &lambda, contact_lambda, contact_active)
//
// How each order runs (every one gives what visiting the items one by one in the ordering's
// sequence gives, bit for bit, whatever the thread count):
//   sequential, reversed: in dependency levels. An item's level is one more than the highest
//     level of the earlier items (in the order) that share a moving particle with it, so the
//     items of a level are independent and every particle sees its items in the order's
//     sequence: the same operations on the same values as one by one. The contacts (after the
//     model's items, or before them when reversed) run one by one.
//   colored: colour by colour (the ordering's greedy colouring); the items of a colour share no
//     moving particle. A colour's contacts run after its constraints.
//   jacobi: every item from the same positions into a buffer of corrections, then each
//     particle's corrections summed in item order (contacts last) and applied.
//   shuffled, grouped_shuffled, bottom_up (and colored when an inverse mass is negative, since
//     the colouring ignores such particles): item by item in the ordering's sequence.
// Within a level or a colour the items are split in fixed chunks over `threads` OpenMP threads
// (solver.threads); Jacobi splits the items, then the particles.
#pragma once

#include <memory>
#include <vector>

#include "core/contacts.hpp"
#include "core/model.hpp"
#include "solver_api/options.hpp"
#include "solvers/ordering.hpp"
#include "solvers/projection_kernels.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

class CompiledProjection {
 public:
  virtual ~CompiledProjection() = default;

  // The most threads a sweep runs on: 1 when its sweeps never run threaded (sequential and
  // reversed orders, small colours), else solver.threads resolved (for 0, each sweep runs on
  // that many or on one, whichever is faster at the time: solvers/sweep_threads.hpp).
  virtual int threads() const = 0;

  // The substep's length h and the model of this step (its rest values may differ from the
  // model compiled: relax.frames gives the solver a relaxed copy; its topology may not).
  virtual void set_substep(const Model& model, double h) = 0;

  // The substep's predicted positions p and its starting positions x_n ((n x 3) m each), and its
  // contacts (the ordering has been told of them). Multipliers start at 0.
  virtual void begin_substep(const Model& model, const Points& p, const Points& x_n,
                             const std::vector<Contact>& contacts, double t_end,
                             const Ordering& ordering) = 0;

  // `iterations` sweeps. report: iterations (+iterations), skipped (+ the skipped projections).
  virtual void sweeps(int iterations, long step, int substep, const Ordering& ordering,
                      StepReport& report) = 0;

  // xpbd: the model constraints' part of Macklin et al. 2016's residuals (eqs. 8 and 9) at the
  // projected positions p ((n x 3) m, after end_substep) with the multipliers of the substep and
  // the alpha~ of its h, in double whatever the precision: g_i -= sum_j lambda_j grad_i C_j
  // (g: (n x 3), kg m), and the return value sum_j (C_j + alpha~_j lambda_j)^2. One thread, in a
  // fixed order.
  virtual double constraint_residuals(const Model& model, const Points& p, Points& g) const = 0;

  // The projected positions into p; xpbd: the model constraints' multipliers (units of C kg, in
  // model order) into *lambda when not null. The contacts' multipliers (kg m; pbd: the sum of
  // its applied -C / sum w |grad C|^2, as the per-item path keeps them) and whether each was
  // violated (C < 0) at some projection.
  virtual void end_substep(Points& p, std::vector<double>* lambda,
                           std::vector<double>& contact_lambda,
                           std::vector<char>& contact_active) const = 0;
};

// The compiled sweeps in the run's precision (options.precision) on at most
// resolve_threads(options.threads) threads (for options.threads = 0, each threaded sweep on that
// many or on one: solvers/sweep_threads.hpp). `ordering` is the solver's, built for the model.
// With one_by_one every order runs item by item in the ordering's sequence through the same
// kernels (what the levels and colours must reproduce bit for bit; Jacobi ignores it). `width`
// caps the registers: the widest the processor has (widest_vector_width()) by default.
std::unique_ptr<CompiledProjection> compile_projection(const Model& model,
                                                       const SolverOptions& options,
                                                       ProjectionRule rule,
                                                       const Ordering& ordering,
                                                       bool one_by_one = false,
                                                       int width = 64);

}  // namespace pbdbench
