// The convergence file of `pbdbench converge`: its content (ConvergeResult, measured by
// harness/converge.hpp), its layout declared once as tables (converge_file.cpp), the writer and
// the reader. The layout (results/README.md):
//
//   /           attributes: content ("pbdbench converge"), converge_format_version, scene,
//               scenario_file, config, dt, h, substeps, time, warmup_steps, warmup_solver,
//               particles, dynamic_particles, constraints, rows, contacts, tolerance,
//               start_residual, residual_note, error_note, methods (keys, comma-separated),
//               machine, created and the build's provenance
//   /<method>   one group per method, its key's name: attributes method, iteration_kind, xpbd,
//               converged, final_error; datasets iteration, residual, time, and error (xpbd) or
//               inner_iterations (the global solvers)
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "runfile/file_read.hpp"

namespace pbdbench {

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
  std::string residual_note;  // how the residual is scored (harness/converge.hpp)
  std::string machine;        // the CPU model (/proc/cpuinfo), "unknown" when unreadable
  std::vector<ConvergeMethod> methods;
};

// True when `path` is a regular file holding a convergence file (what `converge --out` may replace).
bool is_converge_file(const std::filesystem::path& path);

// Writes the convergence file. Throws std::runtime_error naming the path on failure.
void write_converge_file(const std::filesystem::path& path, const ConvergeResult& result);

// A convergence file read back: the result as written, and every scalar root attribute (the
// provenance, created, error_note, ...).
using ConvergeFile = FileRead<ConvergeResult>;

// Throws std::runtime_error naming the path when the file cannot be read or is not a
// convergence file.
ConvergeFile read_converge_file(const std::filesystem::path& path);

// The attributes of a convergence file as converge_file.cpp's tables declare them, in the order
// they are written: the root's (then provenance_attributes()), and each method group's.
std::vector<AttributeInfo> converge_root_attributes();
std::vector<AttributeInfo> converge_method_attributes();

}  // namespace pbdbench
