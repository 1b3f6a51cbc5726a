// The mutable state of a simulation. A solver's step advances it by an explicit dt.
#pragma once

#include <vector>

#include "core/model.hpp"
#include "core/types.hpp"

namespace pbdbench {

struct State {
  double time = 0.0;           // s
  long step = 0;               // number of steps taken
  Points x;                    // (n x 3) m, positions
  Points v;                    // (n x 3) m/s, velocities
  std::vector<double> lambda;  // (m) constraint forces per unit of C from the last step (N for a
                               // distance constraint): the force of constraint j on particle i is
                               // grad_i C_j lambda_j. xpbd: the last substep's accumulated
                               // multiplier / h^2 (h = dt / substeps, Macklin et al. 2016); the
                               // references: reference/reference_solvers.hpp; NaN for solvers
                               // without multipliers (pbd, pbd-seed). 0 in rest_state().
};

// A state at rest in the model's reference configuration at t = 0.
State rest_state(const Model& model);

// A model together with the state it starts from (they may differ: a pendulum released at an
// angle, a spring stretched to 1.5 times its rest length).
struct Scene {
  Model model;
  State initial;
};

}  // namespace pbdbench
