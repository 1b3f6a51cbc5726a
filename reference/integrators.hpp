// The factories of the reference solvers, one per file (reference_solvers.hpp says what each is).
#pragma once

#include <memory>

#include "core/model.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

std::unique_ptr<Solver> make_ref_bdf(const SolverOptions& options, const Model& model);      // ref_bdf.cpp
std::unique_ptr<Solver> make_ref_be(const SolverOptions& options, const Model& model);       // ref_fixed_step.cpp
std::unique_ptr<Solver> make_ref_sdirk2(const SolverOptions& options, const Model& model);   // ref_fixed_step.cpp
std::unique_ptr<Solver> make_ref_dae(const SolverOptions& options, const Model& model);      // ref_dae.cpp
std::unique_ptr<Solver> make_ref_static(const SolverOptions& options, const Model& model);   // ref_static.cpp

}  // namespace pbdbench
