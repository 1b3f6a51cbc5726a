// Pieces the PBD family shares beyond the substep driver (solver_api/substep_driver.hpp): the
// projection paths, the Jacobi accumulator, and the constructors the catalogue calls (one solver
// per file: pbd.cpp, xpbd.cpp, pbd_seed.cpp).
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"
#include "solver_api/substep_driver.hpp"

namespace pbdbench {

// How pbd and xpbd project.
enum class ProjectionPath : std::uint8_t {
  Compiled,          // compiled blocks (solvers/compiled_projection.hpp): what runs
  CompiledOneByOne,  // the same kernels item by item in the ordering's sequence (tests: the
                     // levels and colours must give its bits)
  PerItem,           // item by item through core/constraint_functions.hpp and solvers/kernels.hpp:
                     // the reference implementation the compiled path is compared with
};

std::unique_ptr<Solver> make_pbd_solver(const SolverOptions& options, const Model& model,
                                        ProjectionPath path = ProjectionPath::Compiled);
std::unique_ptr<Solver> make_xpbd_solver(const SolverOptions& options, const Model& model,
                                         ProjectionPath path = ProjectionPath::Compiled);
std::unique_ptr<Solver> make_pbd_seed_solver(const SolverOptions& options, const Model& model);

// Jacobi sweep: corrections are gathered per particle, then applied together:
//   x_i += omega * (sum of the corrections of particle i) / (n_i if averaging, else 1),
// n_i = the number of constraints that gave particle i a non-zero correction.
class JacobiAccumulator {
 public:
  explicit JacobiAccumulator(int particles = 0);
  void resize(int particles);
  void add(int particle, const Vec3& dx);
  void apply(Points& x, double omega, bool averaging);  // and clears the accumulator

 private:
  std::vector<Vec3> sum_;     // (n) m
  std::vector<int> count_;    // (n)
  std::vector<int> touched_;  // particles with count > 0, in first-touch order
};

}  // namespace pbdbench
