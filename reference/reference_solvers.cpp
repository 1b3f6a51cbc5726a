#include "reference/reference_solvers.hpp"

#include <stdexcept>

#include "reference/integrators.hpp"

namespace pbdbench {

const std::vector<SolverInfo>& reference_solver_catalog() {
  static const std::vector<SolverInfo> catalog = {
      {"ref-bdf", "reference: CVODE BDF, adaptive, tolerances solver.ref.rtol/atol (the continuous-time truth)"},
      {"ref-be", "reference: backward Euler with the fixed step dt/substeps (ARKODE), what converged XPBD is"},
      {"ref-sdirk2", "reference: second-order SDIRK with the fixed step dt/substeps (ARKODE)"},
      {"ref-dae", "reference: IDA on the constrained equations (index 2, stabilised) for rigid distance constraints"},
      {"ref-static", "reference: static equilibrium at each output time (KINSOL, Newton with line search)"},
  };
  return catalog;
}

bool is_reference_solver(const std::string& name) {
  for (const SolverInfo& s : reference_solver_catalog())
    if (s.name == name) return true;
  return false;
}

std::unique_ptr<Solver> make_reference_solver(const SolverOptions& options, const Model& model) {
  if (options.name == "ref-bdf") return make_ref_bdf(options, model);
  if (options.name == "ref-be") return make_ref_be(options, model);
  if (options.name == "ref-sdirk2") return make_ref_sdirk2(options, model);
  if (options.name == "ref-dae") return make_ref_dae(options, model);
  if (options.name == "ref-static") return make_ref_static(options, model);
  throw std::invalid_argument("solver.name = '" + options.name + "' is not a reference solver");
}

}  // namespace pbdbench
