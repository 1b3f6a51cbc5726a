// Run health: warnings for what a reader would call a failure even when no explosion limit was
// crossed (metrics/metrics.hpp explosion_reason). Pure bookkeeping over the samples of one run,
// fed one step at a time by the runner; the run file keeps the warnings (root attribute
// "warnings", one per line) and every summary shows them.
//
//   energy_gain   the motion energy (kinetic + gravitational) rose above the initial total
//                 energy (kinetic + gravitational + elastic) by more than energy_gain x the
//                 run's energy scale, in a scene with no energy source (no kinematic particle
//                 or collider moves, no relaxation of rest values). With no source the motion
//                 energy can reach the initial total only by emptying the elastic energy
//                 (E_el >= 0), so crossing it is energy made by the solver, whatever the elastic
//                 energy's own accounting: an unconverged stiff constraint's C^2 / 2 alpha is
//                 large without any motion gained, so the total energy is not the quantity
//                 watched.
//                 Energy scale: m g H + |E_kin(0)| + |E_el(0)| with m the dynamic mass, g the
//                 gravity, H = max(2 x the initial extent, 1 mm), + E_push. E_push = 1/2 m
//                 (d0 / dt)^2, d0 the initial deepest penetration (penetration_max at t = 0)
//                 and dt the step, bounds the kinetic energy of pushing an initial overlap out
//                 within one step (no particle moves faster than d0 / dt to do it): an energy
//                 source the scene states, added to the initial total as well as to the scale,
//                 so that overlapping bodies without gravity or motion (whose scale was a
//                 degenerate 1e-12 J) are not warned for their push-out. Where elastic_energy is NaN
//                 (a run that does not simulate the scene's physical material: pbd with an
//                 explicit k, pbd-seed), E_el(0) = 0 when every constraint starts satisfied
//                 (normalised error <= 1e-9), whatever the material; otherwise the check is off.
//   volume        |tet volume drift| or |enclosed surface volume drift| beyond volume_change.
//   error_growth  the mean RMS constraint error grew in each quarter of the run, and the last
//                 quarter's is above error_growth_ratio x the first's and above error_floor
//                 (runs of at least 8 steps).
//   tunnelling    a dynamic particle ended a step on the forbidden side of a collider by more
//                 than its radius (a plane, a sphere or a bowl), or its path in the step went
//                 through an outside sphere while both ends are outside.
//   solver_stop   steps whose solve stopped for a reason that is not trusted (the solver's
//                 StopReason, solver_api/solver.hpp: an iteration limit spent above the tolerance,
//                 a stall, a failed line search or linear solve), counted per reason.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"
#include "metrics/metrics.hpp"

namespace pbdbench {

struct HealthThresholds {
  double energy_gain = 0.1;         // 1, of the energy scale
  double volume_change = 0.1;       // 1, relative
  double error_growth_ratio = 10.0;  // 1
  double error_floor = 0.1;         // 1 (normalised constraint error: 10 % RMS)
};

struct RunWarning {
  std::string code;     // "energy_gain", "volume", "error_growth", "tunnelling"
  long step = 0;        // the first step at which it was seen
  double time = 0.0;    // s, the same
  std::string message;  // one line, with the numbers
  std::string line() const;  // "code @step (t = ... s): message"
};

class HealthMonitor {
 public:
  // dt: the run's step (s), for the push-out energy of an initial overlap (energy_gain above);
  // 0 leaves it out.
  HealthMonitor(const Model& model, const State& initial, const Sample& initial_sample,
                long steps_planned, bool energy_sources, double dt = 0.0,
                HealthThresholds thresholds = {});
  // After each step k (1-based) with the state and its sample.
  void observe(long step, const State& state, const Sample& sample);
  // After step k, when the solver's step stopped for a reason that is not trusted: `reason` is
  // its name ("iteration_limit", ...), time the time after the step (s).
  void observe_untrusted_stop(long step, double time, const std::string& reason);
  // What was seen so far, in a fixed order (energy, volume, error growth, tunnelling, solver
  // stops).
  std::vector<RunWarning> warnings() const;

 private:
  struct Worst {
    bool seen = false;
    long first_step = 0;
    double first_time = 0.0;
    double worst = 0.0;
    long worst_step = 0;
  };
  const Model* model_;
  HealthThresholds th_;
  long steps_planned_;
  bool energy_sources_;
  double e0_, energy_scale_;
  Points x_prev_;
  Worst energy_, volume_, tunnel_;
  std::string volume_what_;
  long tunnel_particles_ = 0;  // the most particles tunnelled in one step
  long last_step_ = 0;         // the last step observed
  Worst stop_;                 // untrusted stops: first step; worst = their count
  std::map<std::string, long> stops_;  // reason -> steps
  double quarter_sum_[4] = {0, 0, 0, 0};
  long quarter_n_[4] = {0, 0, 0, 0};
  long quarter_step_[4] = {0, 0, 0, 0};
  double quarter_time_[4] = {0, 0, 0, 0};
};

// Particles that tunnelled in the step from x_prev to x (time t): the count and the deepest
// depth beyond the particle's radius (m; a path through a sphere counts with depth 0).
struct Tunnelled {
  int count = 0;
  double depth = 0.0;
};
Tunnelled tunnelled_particles(const Model& model, const Points& x_prev, const Points& x, double t);

// The warnings as stored in a run file's "warnings" attribute: one line each ("" for none).
std::string warnings_text(const std::vector<RunWarning>& warnings);

}  // namespace pbdbench
