// Pieces every PBD-family step shares: argument checks, kinematic particles, the Jacobi
// accumulator, a phase timer, and the constructors the registry calls (one solver per file:
// pbd.cpp, xpbd.cpp, pbd_seed.cpp).
#pragma once

#include <array>
#include <chrono>
#include <memory>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"

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

// Throws std::invalid_argument when dt is not a finite positive number, or when the model or
// the state do not have the sizes the solver was built for (particles, constraints).
void check_step(const Model& model, const State& state, double dt, int particles, int constraints);

// Kinematic particles (those with an Attachment): x_i = attachment_target(t),
// v_i = the motion's velocity at t (0 for a static pin).
void set_kinematic(const Model& model, Points& x, Points& v, double t);

// solver.precision = "float" (pbd, xpbd): a value stored in float32, held in a double. The
// conversion rounds to nearest, ties to even; a float held in a double converts back exactly.
inline double round_to_float(double value) {
  return static_cast<double>(static_cast<float>(value));
}
inline void round_row_to_float(Points& p, Eigen::Index row) {
  for (Eigen::Index k = 0; k < 3; ++k) p(row, k) = round_to_float(p(row, k));
}
void round_to_float(Points& p);  // every entry

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

// Adds the wall-clock time since construction (or the last lap) to a report field.
class PhaseTimer {
 public:
  PhaseTimer() : last_(std::chrono::steady_clock::now()) {}
  void lap(double& field) {
    const auto now = std::chrono::steady_clock::now();
    field += std::chrono::duration<double>(now - last_).count();
    last_ = now;
  }

 private:
  std::chrono::steady_clock::time_point last_;
};

}  // namespace pbdbench
