// PLACEHOLDER while this solver is being written: it refuses to run. (Removed before landing.)
#include <stdexcept>

#include "reference/integrators.hpp"

namespace pbdbench {

std::unique_ptr<Solver> make_ref_be(const SolverOptions& options, const Model&) {
  throw std::invalid_argument(options.name + " is not implemented yet");
}
std::unique_ptr<Solver> make_ref_sdirk2(const SolverOptions& options, const Model&) {
  throw std::invalid_argument(options.name + " is not implemented yet");
}

}  // namespace pbdbench
