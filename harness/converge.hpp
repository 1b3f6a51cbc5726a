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
//
// The result (ConvergeResult) and its file (write_converge_file) are runfile/converge_file.hpp's.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "config/config.hpp"
#include "runfile/converge_file.hpp"

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

// Builds the scene, warms it up and measures every method. Throws config::ConfigError when the
// scene cannot be built or a solver refuses it.
ConvergeResult run_converge(const config::Config& config, const ConvergeOptions& options);

// The terminal table: per method, the iterations and time to reach `target` (m), the last
// iteration, its residual and its distance from x*.
std::string converge_table(const ConvergeResult& result, double target);

// The CPU model from /proc/cpuinfo ("unknown" when it cannot be read).
std::string cpu_model();

}  // namespace pbdbench
