#include "harness/relax.hpp"

#include <cmath>

#include "catalog/solver_catalog.hpp"
#include "core/constraint_functions.hpp"

namespace pbdbench {

std::vector<double> initial_rest_values(const Model& model, const Points& x) {
  std::vector<double> start;
  start.reserve(model.constraints.size());
  for (const Constraint& c : model.constraints) {
    if (is_fem_kind(c.kind)) {
      start.push_back(c.rest);
      continue;
    }
    const double measured = eval_constraint(c, x).C + c.rest;
    start.push_back(std::isfinite(measured) ? measured : c.rest);
  }
  return start;
}

void blend_rest_values(const Model& model, const std::vector<double>& start, double fraction,
                       Model& working) {
  for (size_t j = 0; j < model.constraints.size(); ++j)
    working.constraints[j].rest = (1.0 - fraction) * start[j] + fraction * model.constraints[j].rest;
}

bool solver_supports_relaxation(const std::string& solver_name) {
  const SolverEntry* entry = find_solver(solver_name);
  return entry != nullptr && entry->can.relaxation;
}

}  // namespace pbdbench
