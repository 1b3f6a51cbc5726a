// pbdbench converge: how fast each solver approaches the global step, on one step of a scene.
//
//   scene <- config; advance warmup_steps steps with the scene's own solver (a representative
//   state); from there solve ONE step (h = time.dt, one substep) in every way:
//     xpbd in the orders sequential, colored and jacobi, for each sweep count n of
//       sweep_counts(max_sweeps): a fresh solver with iterations = n takes the step from a copy
//       of the state; recorded: the residual of its result, its distance from x*, its wall time
//     global-cholmod, global-cg (assembled, incomplete Cholesky), global-cg matrix-free and
//       global-ceres from x = x~ and zero multipliers: their histories (residual, time and inner
//       iterations after every outer iteration)
//   x* = global-cholmod's solution, to solver.global.tolerance.
//
// The common measure is GlobalProblem::residuals(x, row_lambda).position (m): max_i |g_i| / m_i
// over the dofs, plus the rows' terms (reference/global_problem.hpp). Without rows (no rigid
// constraint, no contact) it is defined for any point, XPBD's results included. With rows, an
// xpbd result is scored with its own multipliers for the rigid rows (State::lambda h^2) and zero
// for the contacts, whose row part then measures violation only; the file says so.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "config/config.hpp"

namespace pbdbench {

struct ConvergeOptions {
  int warmup_steps = 0;   // steps of the scene's own solver before the measured step, >= 0
  int max_sweeps = 1000;  // the largest xpbd sweep count, >= 1
  double target = 1e-6;   // m, the residual the table reports the cost of reaching
  bool progress = false;  // a line on stderr per method
  // The methods to measure, by key (converge_method_keys()); empty: all. x* is computed in any
  // case.
  std::vector<std::string> methods;
};

// Every method's key, in the file's order: xpbd-sequential, xpbd-colored, xpbd-jacobi,
// global-cholmod, global-cg, global-cg-matrix-free, global-ceres.
const std::vector<std::string>& converge_method_keys();

// 1, 2, 3, 5, 7, 10, 15, 20, 30, 50, 70, 100, ... up to max_sweeps (about five a decade); the
// last is max_sweeps itself.
std::vector<int> sweep_counts(int max_sweeps);

// One way of solving the step, and how it converged.
struct ConvergeMethod {
  std::string key;             // the file's group name: "xpbd-sequential", "global-cholmod", ...
  std::string description;     // one line
  std::string iteration_kind;  // "sweeps", "Newton iterations", "Levenberg-Marquardt iterations"
  bool xpbd = false;
  std::vector<long> iteration;         // sweeps (xpbd) or outer iterations (0: the start)
  std::vector<double> residual;        // m, Residuals::position of the result or iterate
  std::vector<double> time;            // s, wall time of the step (xpbd) or since the solve began
  std::vector<double> error;           // m, mass-weighted RMS distance from x* (xpbd only)
  std::vector<long> inner_iterations;  // cumulative CG or Levenberg-Marquardt iterations (global)
  bool converged = false;              // global: reached solver.global.tolerance
  double final_error = 0.0;            // m, distance of the last result or iterate from x*
};

struct ConvergeResult {
  std::string scene;          // the scenario's name
  std::string scenario_file;
  std::string config;         // the resolved configuration (TOML)
  double dt = 0.0;            // s, time.dt = h (one substep)
  double time = 0.0;          // s, the simulated time at the start of the measured step
  int warmup_steps = 0;
  std::string warmup_solver;  // the scene's own solver.name
  int particles = 0;
  int dynamic_particles = 0;
  int constraints = 0;
  int rows = 0;               // rigid rows and contacts of the step
  int contacts = 0;
  double tolerance = 0.0;     // m, solver.global.tolerance
  double start_residual = 0.0;  // m, the residual at x~ (the global solvers' starting point)
  std::string residual_note;  // how the residual is scored (see the header comment)
  std::vector<ConvergeMethod> methods;
};

// Builds the scene, warms it up and measures every method. Throws config::ConfigError when the
// scene cannot be built or a solver refuses it.
ConvergeResult run_converge(const config::Config& config, const ConvergeOptions& options);

// The convergence file: root attributes (scene, dt, warmup, machine, build), one group per
// method with datasets iteration, residual, time (and error or inner_iterations).
void write_converge_file(const std::filesystem::path& path, const ConvergeResult& result);

// The terminal table: per method, the iterations and time to reach `target` (m), the last
// iteration, its residual and its distance from x*.
std::string converge_table(const ConvergeResult& result, double target);

// The CPU model from /proc/cpuinfo ("unknown" when it cannot be read).
std::string cpu_model();

}  // namespace pbdbench
