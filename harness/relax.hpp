// Relaxation of the initial configuration (relax.frames; the seed article, sec. 2.3: "relax over
// 5-10 frames"). An initial state that violates its constraints is not projected onto them in
// one step: during the first N steps the solver is given a working copy of the model whose rest
// values move linearly from the values the initial state has to the model's own.
//
//   start = initial_rest_values(model, initial.x)           // once, from the initial state
//   step k = 0, 1, ..., N-1: blend_rest_values(model, start, (k + 1) / N, working)
//                            solver.step(working, state, dt)
//   from step N on:          solver.step(model, state, dt)
//
// The metrics always measure against the model's own rest values.
#pragma once

#include <string>
#include <vector>

#include "core/model.hpp"

namespace pbdbench {

// (m) the rest value each constraint would need for `x` (n x 3) to satisfy it: C(x) + rest
// (m for distance, m^3 for volume, rad for bending). The FEM kinds keep their own rest (an
// energy term's offset, not a target: core/model.hpp), and so does a constraint whose value is
// not finite at x.
std::vector<double> initial_rest_values(const Model& model, const Points& x);

// working.constraints[j].rest = (1 - fraction) start[j] + fraction model.constraints[j].rest,
// which is exactly the model's rest at fraction = 1. `working` is a copy of `model` (same
// constraints); fraction in [0, 1].
void blend_rest_values(const Model& model, const std::vector<double>& start, double fraction,
                       Model& working);

// The solvers that read the rest values from the model they are given at every step, and so can
// be relaxed: pbd, xpbd, pbd-seed. (The reference and global solvers build their energy models
// once, from the model they were made for.)
bool solver_supports_relaxation(const std::string& solver_name);

}  // namespace pbdbench
