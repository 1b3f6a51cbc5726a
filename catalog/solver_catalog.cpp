// The solver catalogue: one table, one row per solver (catalog/solver_catalog.hpp). A row is the
// solver's name, its one-line doc, its family (the option table it reads), what it can run, and
// its factory (declared by its family: solvers/step_common.hpp, solvers/force_symplectic.hpp,
// reference/integrators.hpp, reference/global_solver.hpp).
#include "catalog/solver_catalog.hpp"

#include <stdexcept>

#include "reference/global_solver.hpp"
#include "reference/integrators.hpp"
#include "solvers/force_symplectic.hpp"
#include "solvers/step_common.hpp"

namespace pbdbench {

namespace {

// Capabilities, written as the list of what a solver can run.
struct Can {
  static SolverCapabilities of(std::initializer_list<bool SolverCapabilities::*> fields) {
    SolverCapabilities c;
    for (bool SolverCapabilities::*f : fields) c.*f = true;
    return c;
  }
};
using C = SolverCapabilities;

std::unique_ptr<Solver> make_pbd(const SolverOptions& o, const Model& m) { return make_pbd_solver(o, m); }
std::unique_ptr<Solver> make_xpbd(const SolverOptions& o, const Model& m) { return make_xpbd_solver(o, m); }

}  // namespace

const std::vector<SolverEntry>& solver_catalog() {
  static const std::vector<SolverEntry> catalog = {
      // name, doc, family, what it can run, factory
      {"pbd-seed",
       "the seed article's PBD listing to the letter (float, its departures D1-D11 switchable "
       "with solver.seed.fixes)",
       SolverFamily::PbdSeed, Can::of({&C::contacts, &C::rigid, &C::relaxation}),
       make_pbd_seed_solver},
      {"pbd", "Position Based Dynamics, Mueller et al. 2007, Algorithm 1, with substeps",
       SolverFamily::Pbd,
       Can::of({&C::contacts, &C::rigid, &C::float_precision, &C::threads, &C::relaxation}),
       make_pbd},
      {"xpbd",
       "Extended Position Based Dynamics, Macklin et al. 2016, with substeps "
       "(Macklin et al. 2019)",
       SolverFamily::Xpbd,
       Can::of({&C::contacts, &C::rigid, &C::fem, &C::float_precision, &C::threads,
                &C::multipliers, &C::relaxation}),
       make_xpbd},
      {"force-symplectic",
       "force-based: explicit symplectic Euler, constraints as springs C^2/(2 alpha) with "
       "damping, penalty contacts (solver.force.*)",
       SolverFamily::Force, Can::of({&C::contacts, &C::fem, &C::multipliers}),
       make_force_symplectic_solver},
      {"ref-bdf",
       "reference: CVODE BDF, adaptive, tolerances solver.ref.rtol/atol (the continuous-time truth)",
       SolverFamily::Reference, Can::of({&C::fem, &C::multipliers}), make_ref_bdf},
      {"ref-be",
       "reference: backward Euler with the fixed step dt/substeps (ARKODE), what converged XPBD is",
       SolverFamily::Reference, Can::of({&C::contacts, &C::fem, &C::multipliers}), make_ref_be},
      {"ref-sdirk2", "reference: second-order SDIRK with the fixed step dt/substeps (ARKODE)",
       SolverFamily::Reference, Can::of({&C::fem, &C::multipliers}), make_ref_sdirk2},
      {"ref-dae",
       "reference: IDA on the constrained equations (index 2, stabilised) for rigid distance "
       "constraints",
       SolverFamily::Reference, Can::of({&C::rigid, &C::fem, &C::multipliers}), make_ref_dae},
      {"ref-static",
       "reference: static equilibrium at each output time (KINSOL, Newton with line search)",
       SolverFamily::Reference, Can::of({&C::fem, &C::multipliers}), make_ref_static},
      {"global-cholmod",
       "global projection: every step's converged implicit step, Newton on an augmented "
       "Lagrangian, sparse Cholesky (CHOLMOD)",
       SolverFamily::Global,
       Can::of({&C::contacts, &C::rigid, &C::fem, &C::multipliers, &C::shadow}),
       make_global_solver},
      {"global-cg",
       "global projection: the same Newton iterations with preconditioned conjugate gradients "
       "(assembled or matrix-free)",
       SolverFamily::Global,
       Can::of({&C::contacts, &C::rigid, &C::fem, &C::multipliers, &C::shadow}),
       make_global_solver},
      {"global-ceres",
       "global projection: the same step as nonlinear least squares (Ceres, "
       "Levenberg-Marquardt on SuiteSparse)",
       SolverFamily::Global,
       Can::of({&C::contacts, &C::rigid, &C::fem, &C::multipliers, &C::shadow}),
       make_global_solver},
  };
  return catalog;
}

const SolverEntry* find_solver(const std::string& name) {
  for (const SolverEntry& e : solver_catalog())
    if (e.name == name) return &e;
  return nullptr;
}

std::unique_ptr<Solver> make_solver(const SolverOptions& options, const Model& model) {
  const SolverEntry* entry = find_solver(options.name);
  if (entry == nullptr) {
    std::string names;
    for (const SolverEntry& e : solver_catalog()) names += (names.empty() ? "" : ", ") + e.name;
    throw std::invalid_argument("solver.name = '" + options.name + "' is not one of " + names);
  }
  const std::string problem = options.validate(entry->family);  // the options it reads
  if (!problem.empty()) throw std::invalid_argument(problem);
  return entry->make(options, model);
}

}  // namespace pbdbench
