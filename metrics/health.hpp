// Run health: what a practitioner watching the run would call a failure, named by its symptom,
// even when no explosion limit (metrics/metrics.hpp explosion_reason) was crossed. Pure
// bookkeeping over the samples of one run, fed one step at a time by the runner; the run file
// keeps the warnings (root attribute "warnings", one per line) and every summary shows them. The
// detectors only name: none stops a run (the explosion limits and a non-finite state do), so a
// run's trajectory is the same with or without them. docs/failures.md gives each detector's
// threshold with its reason, the margin of every catalog scene at its default settings and the
// detector each scene of scenarios/failures/ trips.
//
// What a practitioner sees, and the code that names it:
//   overstretched  a link (a distance constraint with a rest length) longer than twice its rest
//                  length, |d - d0| / d0 > link_stretch = 1: no cloth, rope or rod material
//                  stretches 100 %; the cloth looks torn, the chain comes apart.
//   inverted       a tet (Model::tets, positively oriented at rest) with a negative signed
//                  volume: the body has turned (part of) itself inside out.
//   left_region    a dynamic particle further from the initial centroid than the scene's
//                  region R(t) = region_factor max(R0, region_floor) + 2 (v0 t + g t^2 / 2):
//                  R0 the initial extent, v0 the fastest initial speed, g |gravity|; what
//                  gravity and the initial velocities can carry a particle in time t, twice,
//                  around ten times the scene's size: the body "flies off the screen".
//                  Off in scenes with an energy source (a kinematic particle or collider moves
//                  them).
//   too_fast       a particle faster than the scene can explain: max speed above speed_factor x
//                  (v0 + g t + sqrt(2 g H) + sqrt(2 (E_el(0) + E_push) / m_min)), the initial
//                  speed, what gravity adds in time t, a fall through the energy scale's height
//                  H, and the speed the initial elastic and push-out energy give the lightest
//                  particle m_min if it all went into it. Off in scenes with an energy source and
//                  where E_el(0) is unknown (below).
//   energy_gain    energy made by the solver, in a scene with no energy source (no kinematic
//                  particle or collider moves, no relaxation of rest values), beyond
//                  energy_gain x the run's energy scale. Watched on the whole energy
//                  (kinetic + gravitational + elastic) where the elastic energy means something,
//                  on the motion energy (kinetic + gravitational) against the initial total where
//                  it does not:
//                  - whole: the run simulates the scene's physical material (elastic_energy
//                    defined) and the step resolves it (HealthRun::whole_energy, set by the
//                    runner, harness/runner.hpp elastic_energy_resolved: every compliant
//                    constraint's alpha / h^2 >= its generalised inverse mass sum
//                    S = sum w_i |grad_i C|^2 at rest, h the substep; no FEM elements, whose
//                    stiffness is a matrix the rule does not read). There a state's
//                    C^2 / 2 alpha is the material's energy, and more of it than the scene held
//                    is energy the solver made.
//                  - motion: elsewhere. A stiff constraint (alpha / h^2 < S) the iterations do not
//                    converge keeps an error whose C^2 / 2 alpha is the iteration's residual, not
//                    stored energy (the 20-link chain of compliance 1e-8 at 10 iterations holds
//                    hundreds of joules in 4 % of stretch); and with no source the motion energy
//                    can reach the initial total only by emptying the elastic energy (E_el >= 0),
//                    so crossing it is energy made by the solver, whatever the elastic energy's
//                    accounting. The overstretch a stiff material's non-convergence produces is
//                    named by overstretched.
//                  Energy scale: m g H + |E_kin(0)| + |E_el(0)| with m the dynamic mass, g the
//                  gravity, H = max(2 x the initial extent, 1 mm), + E_push. E_push = 1/2 m
//                  (d0 / dt)^2, d0 the initial deepest penetration (penetration_max at t = 0)
//                  and dt the step, bounds the kinetic energy of pushing an initial overlap out
//                  within one step (no particle moves faster than d0 / dt to do it): an energy
//                  source the scene states, added to the initial total as well as to the scale,
//                  so that overlapping bodies without gravity or motion (whose scale was a
//                  degenerate 1e-12 J) are not warned for their push-out. Where elastic_energy is
//                  NaN (a run that does not simulate the scene's physical material: pbd with an
//                  explicit k, pbd-seed), E_el(0) = 0 when every constraint starts satisfied
//                  (normalised error <= 1e-9), whatever the material; otherwise the check is off.
//   penetration    bodies that stay inside each other or inside a collider: the deepest contact
//                  penetration (penetration_max) above penetration x the smallest particle radius
//                  in every step of the run's last quarter (a resting contact's residual, not an
//                  impact's transient).
//   not_settling   a scene that should rest keeps trembling: the mean jitter (velocity_hf_rms)
//                  of the run's last quarter above jitter x g dt, the speed gravity adds in a step,
//                  in a scene with gravity, colliders and no energy source (runs of at least 8
//                  steps).
//   volume         |tet volume drift| or |enclosed surface volume drift| beyond volume_change.
//   error_growth   the mean RMS constraint error grew in each quarter of the run, and the last
//                  quarter's is above error_growth_ratio x the first's and above error_floor
//                  (runs of at least 8 steps).
//   tunnelling     a dynamic particle ended a step on the forbidden side of a collider by more
//                  than its radius (a plane, a sphere or a bowl), or its path in the step went
//                  through an outside sphere while both ends are outside.
//   solver_stop    steps whose solve stopped for a reason that is not trusted (the solver's
//                  StopReason, solver_api/solver.hpp: an iteration limit spent above the tolerance,
//                  a stall, a failed line search or linear solve), counted per reason.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"
#include "metrics/metrics.hpp"

namespace pbdbench {

// The thresholds, declared once (their reasons: above and docs/failures.md).
struct HealthThresholds {
  double energy_gain = 0.1;          // 1, of the energy scale
  double volume_change = 0.1;        // 1, relative
  double error_growth_ratio = 10.0;  // 1
  double error_floor = 0.1;          // 1 (normalised constraint error: 10 % RMS)
  double link_stretch = 1.0;         // 1: |d - d0| / d0, a link at twice its rest length
  double region_factor = 10.0;       // 1, of the initial extent
  double region_floor = 0.01;        // m, the smallest initial extent the region is scaled from
  double speed_factor = 10.0;        // 1, of the speed the scene explains
  double penetration = 0.1;          // 1, of the smallest particle radius
  double jitter = 1.0;               // 1, of g dt
};

// What the runner knows of the run beyond its model and initial state.
struct HealthRun {
  long steps_planned = 0;
  bool energy_sources = false;  // a kinematic particle or collider moves, or rest values relax
  double dt = 0.0;              // s, the step (the push-out energy, the jitter bound); 0: unknown
  bool whole_energy = false;    // the elastic energy means something: energy_gain above
};

struct RunWarning {
  std::string code;     // "overstretched", "left_region", "energy_gain", ...: above
  long step = 0;        // the first step at which it was seen
  double time = 0.0;    // s, the same
  std::string message;  // one line, with the numbers
  std::string line() const;  // "code @step (t = ... s): message"
};

// How close a run came to a detector's threshold: the largest value / threshold it reached over
// the run (>= 1: warned; NaN: the detector was off or had nothing to read), and where.
struct HealthMargin {
  std::string code;
  double ratio = 0.0;
  long step = 0;
  std::string line() const;  // "code 0.23 @step" or "code off"
};

class HealthMonitor {
 public:
  HealthMonitor(const Model& model, const State& initial, const Sample& initial_sample, const HealthRun& run,
                HealthThresholds thresholds = {});
  // The same with the run's facts as arguments (dt 0: unknown; whole_energy false).
  HealthMonitor(const Model& model, const State& initial, const Sample& initial_sample,
                long steps_planned, bool energy_sources, double dt = 0.0,
                HealthThresholds thresholds = {});
  // After each step k (1-based) with the state and its sample.
  void observe(long step, const State& state, const Sample& sample);
  // After step k, when the solver's step stopped for a reason that is not trusted: `reason` is
  // its name ("iteration_limit", ...), time the time after the step (s).
  void observe_untrusted_stop(long step, double time, const std::string& reason);
  // What was seen so far, in a fixed order (the symptoms first: overstretched, inverted,
  // left_region, too_fast, energy_gain, penetration, not_settling; then volume, error growth,
  // tunnelling, solver stops).
  std::vector<RunWarning> warnings() const;
  // Each detector's margin so far, in the same order (volume, error growth, tunnelling and solver
  // stops have none).
  std::vector<HealthMargin> margins() const;
  // Whether energy_gain watches the whole energy (else the motion energy): the header.
  bool whole_energy() const { return whole_energy_; }

 private:
  struct Worst {
    bool seen = false;
    long first_step = 0;
    double first_time = 0.0;
    double worst = 0.0;
    long worst_step = 0;
  };
  // The largest value / threshold reached, warned or not.
  struct Peak {
    bool on = false;  // the detector read a value
    double ratio = 0.0;
    long step = 0;
    double value = 0.0, bound = 0.0;  // at that step
  };
  void peak(Peak& p, long step, double value, double bound);

  const Model* model_;
  HealthThresholds th_;
  long steps_planned_;
  bool energy_sources_;
  double dt_;
  bool whole_energy_;
  double e0_, energy_scale_;
  // The scene's region and speeds (left_region, too_fast).
  double region0_ = 0.0, v0_ = 0.0, g_ = 0.0, v_fall_ = 0.0, v_stored_ = 0.0;
  double radius_min_ = 0.0;  // m, the smallest positive radius of a dynamic particle
  bool colliders_ = false;
  Points x_prev_;
  Worst energy_, volume_, tunnel_, stretch_, inverted_, region_, speed_;
  Peak stretch_peak_, inverted_peak_, region_peak_, speed_peak_, energy_peak_;
  std::string volume_what_;
  long tunnel_particles_ = 0;  // the most particles tunnelled in one step
  long last_step_ = 0;         // the last step observed
  Worst stop_;                 // untrusted stops: first step; worst = their count
  std::map<std::string, long> stops_;  // reason -> steps
  double quarter_sum_[4] = {0, 0, 0, 0};
  long quarter_n_[4] = {0, 0, 0, 0};
  long quarter_step_[4] = {0, 0, 0, 0};
  double quarter_time_[4] = {0, 0, 0, 0};
  // The last quarter's smallest penetration and mean jitter (penetration, not_settling).
  double last_penetration_min_ = 0.0;
  long last_penetration_n_ = 0;
  long last_first_step_ = 0;
  double last_first_time_ = 0.0;
  double last_jitter_sum_ = 0.0;
  long last_jitter_n_ = 0;
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

// What a practitioner sees, for a warning's code ("a link stretched beyond twice its rest
// length" for overstretched), "" for a code that is not a detector's.
std::string symptom_of(const std::string& code);

}  // namespace pbdbench
