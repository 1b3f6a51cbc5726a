// The solver catalogue and the factory.
#include <stdexcept>

#include "reference/reference_solvers.hpp"
#include "solvers/force_symplectic.hpp"
#include "reference/global_solver.hpp"
#include "solver_api/solver.hpp"
#include "solvers/step_common.hpp"

namespace pbdbench {

const std::vector<SolverInfo>& solver_catalog() {
  static const std::vector<SolverInfo> catalog = [] {
    std::vector<SolverInfo> all = {
      {"pbd-seed",
       "the seed article's PBD listing to the letter (float, its departures D1-D11 switchable "
       "with solver.seed.fixes)"},
      {"pbd", "Position Based Dynamics, Mueller et al. 2007, Algorithm 1, with substeps"},
      {"xpbd",
       "Extended Position Based Dynamics, Macklin et al. 2016, with substeps "
       "(Macklin et al. 2019)"},
      {"force-symplectic",
       "force-based: explicit symplectic Euler, constraints as springs C^2/(2 alpha) with "
       "damping, penalty contacts (solver.force.*)"},
    };
    for (const SolverInfo& r : reference_solver_catalog()) all.push_back(r);
    for (const SolverInfo& g : global_solver_catalog()) all.push_back(g);
    return all;
  }();
  return catalog;
}

std::unique_ptr<Solver> make_solver(const SolverOptions& options, const Model& model) {
  {
    std::string names;
    bool known = false;
    for (const SolverInfo& s : solver_catalog()) {
      known = known || s.name == options.name;
      names += (names.empty() ? "" : ", ") + s.name;
    }
    if (!known)
      throw std::invalid_argument("solver.name = '" + options.name + "' is not one of " + names);
  }
  const std::string problem = options.validate();
  if (!problem.empty()) throw std::invalid_argument(problem);
  if (options.name == "pbd") return make_pbd_solver(options, model);
  if (options.name == "xpbd") return make_xpbd_solver(options, model);
  if (options.name == "pbd-seed") return make_pbd_seed_solver(options, model);
  if (options.name == "force-symplectic") return make_force_symplectic_solver(options, model);
  if (is_reference_solver(options.name)) return make_reference_solver(options, model);
  if (is_global_solver(options.name)) return make_global_solver(options, model);
  throw std::invalid_argument("solver.name = '" + options.name + "' is not a registered solver");
}

}  // namespace pbdbench
