// The substep driver: the step skeleton that every family stepping in substeps shares (pbd-seed,
// pbd, xpbd, force-symplectic in solvers/; the global solvers in reference/), and the pieces of a substep
// they have in common. With h = dt / substeps and t_end the time at the end of substep s:
//
//   check_step(...)                                  (the caller, before run_substeps)
//   for s in 0 .. substeps-1:
//     a cancelled run stops here (core/cancel.hpp), before the substep touches the state
//     kinematic particles: x_i = target(t_end), v_i = motion velocity      set_kinematic
//     the family's substep (its prediction, contacts, solve, velocity update)   substep(...)
//   state.time += dt;  state.step += 1
//
// The driver is a template: the family's substep is inlined into it, with no virtual call and no
// indirection (the compiled projection kernels below it stay as they are).
#pragma once

#include <chrono>

#include "core/cancel.hpp"
#include "core/model.hpp"
#include "core/state.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

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

// v_i += h g for the dynamic particles (inv_mass > 0). With Precision::Float in float arithmetic
// (h and g rounded to float, the sum rounded to float): v must hold floats.
void apply_gravity(const Model& model, double h, Points& v, Precision precision = Precision::Double);

// p = x, then p_i += h v_i for the dynamic particles; with Precision::Float in float arithmetic
// (x and v must hold floats).
void predict_positions(const Model& model, const Points& x, const Points& v, double h, Points& p,
                       Precision precision = Precision::Double);

// The end of a position-based substep: v_i = (p_i - x_i) / h for the dynamic particles, then
// x = p. With Precision::Float the velocity is float arithmetic (p and x hold floats).
void update_from_positions(const Model& model, double h, const Points& p, Points& x, Points& v,
                           Precision precision = Precision::Double);

// Where a substep stands: its index, its length h = dt / substeps and the time at its end.
struct Substep {
  int index = 0;
  double h = 0.0;
  double t_end = 0.0;
};

// The step skeleton (see the top of this file): for each substep, the kinematic particles are
// set at t_end, then substep(const Substep&, PhaseTimer&, StepReport&) runs the family's own
// part (the timer was started before set_kinematic, so its first lap counts it as prediction).
// report.substeps is set; state.time and state.step advance at the end.
template <class Body>
StepReport run_substeps(const Model& model, State& state, double dt, int substeps, Body&& substep) {
  StepReport report;
  const double h = dt / substeps;
  report.substeps = substeps;
  for (int s = 0; s < substeps; ++s) {
    throw_if_cancelled("a substep");
    const Substep here{s, h, state.time + (s + 1) * h};
    PhaseTimer timer;
    set_kinematic(model, state.x, state.v, here.t_end);
    substep(here, timer, report);
  }
  state.time += dt;
  state.step += 1;
  return report;
}

}  // namespace pbdbench
