// Runs one configuration to its end and writes its run file: the loop every command shares.
//
//   scene, solver, writer  <- config
//   row 0: metrics of the initial state
//   each step: solver.step(model, state, dt) -> metrics -> one row (-> a frame every k steps)
//              (the metrics, rows, frames and checks on a thread of their own when the run has
//              a core to spare: harness/step_logger.hpp; the file is the same either way)
//              (the first relax.frames steps give the solver a relaxed copy of the model:
//              harness/relax.hpp; the metrics always measure against the model itself)
//              explosion check: NaN, Inf, speed or extent beyond the limits -> stop, "exploded"
//   finish: "complete", "exploded", "failed" (an exception), or "incomplete" (interrupted),
//           with the warnings of metrics/health.hpp (energy gained, volume lost, error growth,
//           tunnelling) whatever the status
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "config/config.hpp"
#include "harness/step_logger.hpp"
#include "metrics/metrics.hpp"
#include "runfile/run_file.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

struct RunOutcome {
  RunStatus status = RunStatus::Incomplete;
  std::string reason;       // why it exploded, failed or stopped; empty when complete
  long steps_planned = 0;
  long steps_completed = 0;
  long exploded_step = -1;  // the step at which the explosion was detected, or -1
  double wall_time = 0.0;   // s, the whole run including metrics and output
  double solver_time = 0.0; // s, inside solver.step() only
  // s, before the run file is created: the scene built, the solver (and shadow) constructed
  // (colouring, compiled projections), the initial state measured and the run planned. The rest
  // of wall_time outside solver_time is the harness's logging: metrics, frames and HDF5
  // (the file created, rows and frames appended, published, finished).
  double setup_time = 0.0;
  // The same in the CPU time of the run's thread (s): what other processes on a shared machine do
  // not inflate. solver_cpu_time misses the time of the solver's own worker threads
  // (solver.threads > 1); the frame worker's is in no field (the process's CPU time has it).
  double solver_cpu_time = 0.0;
  double setup_cpu_time = 0.0;
  Sample final_sample;      // metrics of the last state
  // What a reader would call a failure though no limit was crossed (metrics/health.hpp), one
  // line each; also in the run file's "warnings" attribute.
  std::vector<std::string> warnings;
  // How close the run came to each detector's threshold (metrics/health.hpp HealthMonitor::margins).
  std::vector<HealthMargin> health_margins;
  bool health_whole_energy = false;  // energy_gain watched the whole energy (else the motion's)
};

struct RunControl {
  // Called after each step with (steps completed, steps planned); may be empty.
  std::function<void(long, long)> progress;
  // When set, builds the run's solver instead of the registry (make_solver): the regression
  // tests use it to run deliberately broken variants that are never shipped.
  std::function<std::unique_ptr<Solver>(const SolverOptions&, const Model&)> make_solver;
  // When set and true, the run stops after the current step and is recorded as incomplete.
  // A cancellation (core/cancel.hpp) stops it within the step.
  const std::atomic<bool>* stop = nullptr;
  // Run even when the plan does not fit the machine (harness/plan.hpp).
  bool force = false;
  // The caller exports the run to ParaView after it (`pbdbench run`): the plan counts the
  // export's memory and file too.
  bool exported = false;
  // Told the plan of a run expected to take more than a minute, before it starts; may be empty.
  std::function<void(const std::string&)> notice;
  // Where each step's metrics, row and frame are made (harness/step_logger.hpp): the file is the
  // same either way; Auto gives them a thread of their own when the run has a core to spare.
  StepLogging logging = StepLogging::Auto;
};

// solver.name is a solver of the catalogue (catalog/) and shadow.solver empty or one that can run
// as a shadow: config/, below the catalogue, does not check them. Throws ConfigError naming the
// key, with the file and line (or --set) that set it. run_config calls it; whatever validates
// runs before starting any (sweeps, experiments, the regression) calls it too.
void check_solver_names(const config::Config& config);

// Whether substeps of h seconds resolve the model's material, so that its elastic energy
// C^2 / 2 alpha is the material's rather than an unconverged iteration's residual: every compliant
// constraint has alpha / h^2 >= its generalised inverse mass sum at rest (pbd_inverse_mass_sums),
// and there are no FEM elements (their stiffness is a matrix this rule does not read). The run
// health watches the whole energy only there (metrics/health.hpp energy_gain).
bool elastic_energy_resolved(const Model& model, double h);

// Runs `config` and writes `out` (its directory is created). Throws config::ConfigError when the
// scene cannot be built or the planned run does not fit the machine (before any file is
// written), OutputRefused (runfile/output_guard.hpp) when `out` may not be written or another
// process is writing it, and std::runtime_error when the file cannot be written; everything that
// goes wrong after the file exists is recorded in it.
RunOutcome run_config(const config::Config& config, const std::filesystem::path& out,
                      const RunControl& control = {});

}  // namespace pbdbench
