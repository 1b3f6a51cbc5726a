// The global solvers as whole simulations (reference/global_solver.cpp): global-cholmod, global-cg and
// global-ceres, made by make_solver() like every other solver.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/model.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

// Every global solver, in a stable order.
const std::vector<SolverInfo>& global_solver_catalog();

bool is_global_solver(const std::string& name);

// Throws std::invalid_argument when the model has what the global problem cannot hold (a rigid
// bending constraint, an element without a constraint form), naming it.
std::unique_ptr<Solver> make_global_solver(const SolverOptions& options, const Model& model);

}  // namespace pbdbench
