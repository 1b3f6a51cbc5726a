// The solver catalogue: one table of every solver, {name, doc, family, capabilities, factory}
// (catalog/solver_catalog.cpp). It composes the families from above: solvers/ (the PBD family
// and force-symplectic) and reference/ (the reference integrators and the global solvers) both
// build on solver_api/ and neither knows the other; only this table names them all. It stands
// above config/, which reads only the option rows of solver_api/ and links no solver library:
// the harness reads the table to build the run's solver (a name of no row is refused there, with
// the file and line of solver.name), the command line to list it and to say which options the
// scenario's solver reads (describe, the warnings of config::unread_solver_keys).
//
//   auto solver = make_solver(options, model);      // precomputation (colourings, ...)
//   StepReport r = solver->step(model, state, dt);  // advance state by dt
//
// A new solver is one file in its family's folder and one row of the table (docs/solvers.md,
// "Adding a PBD variant").
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/model.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

// What a solver can run, instead of name checks in config/ and harness/.
struct SolverCapabilities {
  bool contacts = false;      // colliders and particle contact (without solver.ref.ignore_colliders)
  bool rigid = false;         // constraints of compliance 0
  bool fem = false;           // FEM elements (those with a constraint form, for xpbd and global-*)
  bool float_precision = false;  // solver.precision = "float"
  bool threads = false;       // solver.threads > 1 (colored and Jacobi sweeps)
  bool multipliers = false;   // leaves constraint forces in State::lambda (support_force)
  bool shadow = false;        // can run as shadow.solver (the converged step)
  bool relaxation = false;    // relax.frames (rest values blended over the first steps)
};

using SolverFactory = std::unique_ptr<Solver> (*)(const SolverOptions& options, const Model& model);

struct SolverEntry {
  std::string name;  // solver.name: "pbd-seed", "pbd", "xpbd", "ref-bdf", ...
  std::string doc;   // one line
  SolverFamily family = SolverFamily::Xpbd;  // solver_api/options.hpp: the options it reads
  SolverCapabilities can;
  SolverFactory make = nullptr;
};

// Every solver, in a stable order: the PBD family first, then force-symplectic, the references
// and the global solvers.
const std::vector<SolverEntry>& solver_catalog();

// The entry named `name`, or nullptr.
const SolverEntry* find_solver(const std::string& name);

// Builds the solver named options.name for this model. Throws std::invalid_argument naming the
// field when options.validate(its family) fails or the name is unknown, and whatever the solver's factory
// throws for a model it cannot run (naming what).
std::unique_ptr<Solver> make_solver(const SolverOptions& options, const Model& model);

}  // namespace pbdbench
