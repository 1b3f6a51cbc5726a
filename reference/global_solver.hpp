// The global solvers as whole simulations (reference/global_solver.cpp): global-cholmod, global-cg and
// global-ceres, made by make_solver() like every other solver (catalog/solver_catalog.cpp holds their rows).
#pragma once

#include <memory>

#include "core/model.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

// Throws std::invalid_argument when the model has what the global problem cannot hold (a rigid
// bending constraint, an element without a constraint form), naming it.
std::unique_ptr<Solver> make_global_solver(const SolverOptions& options, const Model& model);

}  // namespace pbdbench
