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
  std::vector<double> lambda;  // (m) Lagrange multipliers of the model's constraints from the
                               // last step (XPBD's accumulated lambda); 0 for solvers without
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
