// The seed article's tuning rules that pbd-seed (solvers/pbd_seed.cpp) applies on request, as
// pure functions so that each can be tested alone (docs/seed-departures.md, "tuning options from
// sections 4 and 5").
#pragma once

#include <vector>

#include "core/model.hpp"
#include "core/types.hpp"
#include "solver_api/options.hpp"

namespace pbdbench {

// Sweeps per substep of the step with index `step` (State::step, 0 for the run's first) when the
// fastest particle's speed at the start of the step is `fastest` (m/s), by
// options.seed_iteration_schedule:
//   "fixed":   options.iterations;
//   "dynamic": 10 when step == 0, else 5 when fastest > options.seed_fast_speed, else 3 (4.1);
//   "mixed":   1 when fastest > options.seed_fast_speed, else 3 (5.3).
int seed_iterations(const SolverOptions& options, long step, double fastest);

// Article 4.2, dynamic inverse mass: (n) 1/kg, for each particle with model inv_mass > 0,
// 0.1 when |v_i| > fast_speed (m/s), else 0.3; 0 for the others. v: (n x 3) m/s.
std::vector<double> seed_dynamic_inverse_masses(const Model& model, const Points& v,
                                                double fast_speed);

// Article 4.2, inverse mass graded from the pinned edge: (n) 1/kg,
//   w_i = 0.3 min(1, d_i / d_c)  for each particle with model inv_mass > 0,
//   w_i = 0                      for the others,
// d_i the hop distance from the nearest particle with inverse mass 0 in the graph whose edges
// join every two particles of a constraint, d_c = max(1, (largest finite d_i) / 2). The article
// says only "then decreasing toward the other side" without a value, so beyond d_c the inverse
// mass stays 0.3; a particle that no pin reaches has d_i = infinity and 0.3. Throws
// std::invalid_argument when no particle has inverse mass 0 (there is no edge to grade from).
std::vector<double> seed_graded_inverse_masses(const Model& model);

}  // namespace pbdbench
