#include "catalog/solver_catalog.hpp"
#include "harness/converge.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "core/contacts.hpp"
#include "reference/global_ceres.hpp"
#include "reference/global_newton.hpp"
#include "reference/global_problem.hpp"
#include "solver_api/solver.hpp"
#include "solvers/step_common.hpp"
#include "solvers/substep.hpp"

namespace fs = std::filesystem;

namespace pbdbench {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// A step shorter than this is timed again (up to kRepeats times in all) and the fastest kept:
// one sample of a millisecond is mostly noise.
constexpr double kShortStep = 0.02;  // s
constexpr int kRepeats = 5;

// sqrt(sum m_i |a_i - b_i|^2 / sum m_i) over the dynamic particles, m.
double mass_weighted_rms(const Model& model, const Points& a, const Points& b) {
  double sum = 0.0, mass = 0.0;
  for (int i = 0; i < model.particle_count(); ++i) {
    const double w = model.inv_mass[static_cast<size_t>(i)];
    if (!(w > 0.0)) continue;
    sum += (a.row(i) - b.row(i)).squaredNorm() / w;
    mass += 1.0 / w;
  }
  return mass > 0.0 ? std::sqrt(sum / mass) : 0.0;
}

struct OrderCase {
  ProjectionOrder order;
  const char* key;
  const char* description;
};

constexpr OrderCase kOrders[] = {
    {ProjectionOrder::Sequential, "xpbd-sequential",
     "xpbd, Gauss-Seidel in the model's order (solver.order = sequential), one substep"},
    {ProjectionOrder::Colored, "xpbd-colored",
     "xpbd, coloured Gauss-Seidel (solver.order = colored), one substep"},
    {ProjectionOrder::Jacobi, "xpbd-jacobi",
     "xpbd, Jacobi (solver.order = jacobi, the configured relaxation and averaging), one substep"},
};

// The step's global problem, set up as reference/global_solver.cpp sets up its substep.
void begin_problem(const Model& model, const State& start, double h, double contact_margin,
                   GlobalProblem& problem) {
  Points x = start.x, v = start.v, p;
  const double t_end = start.time + h;
  set_kinematic(model, x, v, t_end);
  apply_gravity(model, h, v);
  predict_positions(model, x, v, h, p);
  std::vector<Contact> contacts = find_contacts(model, p, t_end, contact_margin);
  problem.begin_step(x, p, h, t_end, std::move(contacts));
}

ConvergeMethod from_history(const GlobalResult& r, std::string key, std::string description,
                            std::string kind) {
  ConvergeMethod m;
  m.key = std::move(key);
  m.description = std::move(description);
  m.iteration_kind = std::move(kind);
  for (const IterationRecord& rec : r.history) {
    m.iteration.push_back(rec.iteration);
    m.residual.push_back(rec.residual);
    m.time.push_back(rec.time);
    m.inner_iterations.push_back(rec.inner_iterations);
  }
  m.converged = r.converged;
  return m;
}

std::string num(double v) { return fmt::format("{:.3g}", v == 0.0 ? 0.0 : v); }

}  // namespace

const std::vector<std::string>& converge_method_keys() {
  static const std::vector<std::string> keys = {
      "xpbd-sequential", "xpbd-colored",          "xpbd-jacobi", "global-cholmod",
      "global-cg",       "global-cg-matrix-free", "global-ceres"};
  return keys;
}

std::vector<int> sweep_counts(int max_sweeps) {
  std::vector<int> out;
  for (int v : {1, 2, 3, 5, 7})
    if (v <= max_sweeps) out.push_back(v);
  for (long decade = 1; decade * 10 <= max_sweeps; decade *= 10)
    for (long m : {10, 15, 20, 30, 50, 70}) {
      const long v = m * decade;
      if (v <= max_sweeps) out.push_back(static_cast<int>(v));
    }
  if (max_sweeps >= 1 && (out.empty() || out.back() < max_sweeps)) out.push_back(max_sweeps);
  return out;
}

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

ConvergeResult run_converge(const config::Config& config, const ConvergeOptions& options) {
  if (options.warmup_steps < 0)
    throw config::ConfigError({"--warmup-steps", 0}, "", "must be >= 0");
  if (options.max_sweeps < 1) throw config::ConfigError({"--max-sweeps", 0}, "", "must be >= 1");
  const std::vector<std::string>& known = converge_method_keys();
  for (const std::string& k : options.methods)
    if (std::find(known.begin(), known.end(), k) == known.end()) {
      std::string list;
      for (const std::string& n : known) list += (list.empty() ? "" : ", ") + n;
      throw config::ConfigError({"--methods", 0}, "", "unknown method '" + k + "' (known: " + list + ")");
    }
  auto selected = [&](const std::string& key) {
    return options.methods.empty() ||
           std::find(options.methods.begin(), options.methods.end(), key) != options.methods.end();
  };
  Scene scene = config::build_scene(config);
  const Model& model = scene.model;
  State state = std::move(scene.initial);
  const SolverOptions base = config::solver_options(config);
  const double dt = config::run_options(config).dt;
  const config::Source source{config.file.string(), 0};
  auto log = [&](const std::string& line) {
    if (options.progress) std::cerr << "converge: " << line << std::endl;
  };

  ConvergeResult result;
  result.scene = config.scenario_name;
  result.scenario_file = config.file.string();
  result.config = config.to_toml();
  result.dt = dt;
  result.warmup_steps = options.warmup_steps;
  result.warmup_solver = base.name;
  result.tolerance = base.global_tolerance;
  result.machine = cpu_model();

  // The global problem first: a scene it cannot hold is refused before any work.
  std::unique_ptr<GlobalProblem> problem_ptr;
  try {
    problem_ptr = std::make_unique<GlobalProblem>(model);
  } catch (const std::invalid_argument& e) {
    throw config::ConfigError(source, "scene", e.what());
  }
  GlobalProblem& problem = *problem_ptr;

  // A representative state: the scene's own solver, warmup_steps steps.
  if (options.warmup_steps > 0) {
    std::unique_ptr<Solver> own;
    try {
      own = make_solver(base, model);
    } catch (const std::invalid_argument& e) {
      throw config::ConfigError(source, "solver.name", e.what());
    }
    for (int k = 0; k < options.warmup_steps; ++k) own->step(model, state, dt);
    log(fmt::format("warmed up {} steps with {} to t = {} s", options.warmup_steps, base.name,
                    num(state.time)));
  }
  const State start = state;
  result.time = start.time;

  begin_problem(model, start, dt, base.contact_margin, problem);
  result.particles = model.particle_count();
  result.constraints = model.constraint_count();
  for (double w : model.inv_mass) result.dynamic_particles += w > 0.0 ? 1 : 0;
  result.rows = static_cast<int>(problem.rows().size());
  result.contacts = static_cast<int>(problem.contacts().size());
  const std::vector<double> zero_rows(problem.rows().size(), 0.0);
  result.start_residual = problem.residuals(problem.x_pred(), zero_rows).position;
  result.residual_note =
      result.rows == 0
          ? "no rows: the residual is max_i |g_i| / m_i at each point, with g = grad E"
          : "with rows: xpbd results are scored with their own multipliers for the rigid rows "
            "(State::lambda h^2) and zero for the contacts, so the contacts' part measures "
            "violation only; global iterates with their own multipliers";

  // x*: global-cholmod to the configured tolerance. Its Newton object is kept for the recorded
  // solve below, which then reuses the symbolic analysis as every step of a run does; its
  // numeric factorisation is forgotten first, so that the recorded solve factorises from x~ as
  // the first step of a run does, and ends on x* bit for bit.
  SolverOptions cholmod_opts = base;
  cholmod_opts.name = "global-cholmod";
  GlobalNewton cholmod(cholmod_opts, GlobalLinearSolver::Cholmod);
  Points x_star = problem.x_pred();
  {
    std::vector<double> lambda = zero_rows;
    const GlobalResult r = cholmod.solve(problem, x_star, lambda);
    log(fmt::format("x*: global-cholmod, {} Newton iterations, residual {} m{}", r.iterations,
                    num(r.residual), r.converged ? "" : " (not converged)"));
  }

  // xpbd: one step per (order, sweep count), each from a copy of the start.
  const std::vector<int> counts = sweep_counts(options.max_sweeps);
  for (const OrderCase& oc : kOrders) {
    if (!selected(oc.key)) continue;
    ConvergeMethod m;
    m.key = oc.key;
    m.description = oc.description;
    m.iteration_kind = "sweeps";
    m.xpbd = true;
    const auto t_method = Clock::now();
    for (int n : counts) {
      SolverOptions o = base;
      o.name = "xpbd";
      o.order = oc.order;
      o.iterations = n;
      o.substeps = 1;
      o.xpbd_residuals = false;  // not part of the step's cost
      std::unique_ptr<Solver> solver;
      try {
        solver = make_solver(o, model);
      } catch (const std::invalid_argument& e) {
        throw config::ConfigError(source, "solver", e.what());
      }
      State s;
      double best = std::numeric_limits<double>::infinity();
      for (int rep = 0; rep < kRepeats; ++rep) {
        s = start;
        const auto t0 = Clock::now();
        solver->step(model, s, dt);
        best = std::min(best, seconds_since(t0));
        if (best >= kShortStep) break;
      }
      std::vector<double> lambda = zero_rows;
      for (size_t r = 0; r < problem.rows().size(); ++r) {
        const GlobalRow& row = problem.rows()[r];
        if (!row.inequality && row.constraint >= 0)
          lambda[r] = s.lambda[static_cast<size_t>(row.constraint)] * dt * dt;
      }
      m.iteration.push_back(n);
      m.residual.push_back(problem.residuals(s.x, lambda).position);
      m.time.push_back(best);
      m.error.push_back(mass_weighted_rms(model, s.x, x_star));
    }
    m.final_error = m.error.empty() ? 0.0 : m.error.back();
    log(fmt::format("{}: {} sweep counts up to {} in {} s", m.key, counts.size(), counts.back(),
                    num(seconds_since(t_method))));
    result.methods.push_back(std::move(m));
  }

  // The global solvers from x~ and zero multipliers.
  struct GlobalCase {
    const char* key;
    const char* description;
    const char* kind;
    bool ceres;
    GlobalLinearSolver linear;
    bool matrix_free;
  };
  const GlobalCase cases[] = {
      {"global-cholmod",
       "global-cholmod: Newton, sparse Cholesky (symbolic analysis reused from the solve that "
       "gave x*, as in a run)",
       "Newton iterations", false, GlobalLinearSolver::Cholmod, false},
      {"global-cg", "global-cg: Newton, conjugate gradients on the assembled matrix, incomplete "
                    "Cholesky preconditioner",
       "Newton iterations", false, GlobalLinearSolver::ConjugateGradient, false},
      {"global-cg-matrix-free",
       "global-cg matrix-free: Newton, conjugate gradients applied term by term, Jacobi "
       "preconditioner",
       "Newton iterations", false, GlobalLinearSolver::ConjugateGradient, true},
      {"global-ceres", "global-ceres: nonlinear least squares, Levenberg-Marquardt on sparse "
                       "normal Cholesky",
       "Levenberg-Marquardt iterations", true, GlobalLinearSolver::Cholmod, false},
  };
  for (const GlobalCase& c : cases) {
    if (!selected(c.key)) continue;
    SolverOptions o = base;
    o.name = c.ceres ? "global-ceres" : (c.linear == GlobalLinearSolver::Cholmod ? "global-cholmod"
                                                                                  : "global-cg");
    if (!c.ceres && c.linear == GlobalLinearSolver::ConjugateGradient) {
      o.global_matrix_free = c.matrix_free;
      if (!c.matrix_free) o.global_cg_preconditioner = "incomplete_cholesky";
    }
    Points x = problem.x_pred();
    std::vector<double> lambda = zero_rows;
    GlobalResult r;
    if (c.ceres) {
      r = solve_global_ceres(problem, o, x, lambda);
    } else if (c.linear == GlobalLinearSolver::Cholmod) {
      cholmod.forget_factorisation();
      r = cholmod.solve(problem, x, lambda);
    } else {
      GlobalNewton newton(o, c.linear);
      r = newton.solve(problem, x, lambda);
    }
    ConvergeMethod m = from_history(r, c.key, c.description, c.kind);
    m.final_error = mass_weighted_rms(model, x, x_star);
    log(fmt::format("{}: {} iterations, residual {} m in {} s", m.key, r.iterations,
                    num(r.residual), num(m.time.empty() ? 0.0 : m.time.back())));
    result.methods.push_back(std::move(m));
  }
  return result;
}

std::string converge_table(const ConvergeResult& r, double target) {
  std::string out = fmt::format(
      "{}: one step of {} s (one substep) at t = {} s, after {} warm-up steps of {}; {} "
      "particles, {} constraints, {} rows; residual at x~ {} m\n",
      r.scene, num(r.dt), num(r.time), r.warmup_steps, r.warmup_solver, r.particles,
      r.constraints, r.rows, num(r.start_residual));
  out += fmt::format("{:<22} {:<14} {:>10} {:>12} {:>7} {:>12} {:>12}\n", "method", "iterations",
                     fmt::format("to {} m", num(target)), "time (ms)", "last", "residual (m)",
                     "error (m)");
  for (const ConvergeMethod& m : r.methods) {
    std::string reach = "-", time = "-";
    for (size_t k = 0; k < m.residual.size(); ++k)
      if (m.residual[k] <= target) {
        reach = std::to_string(m.iteration[k]);
        time = fmt::format("{:.3g}", 1e3 * m.time[k]);
        break;
      }
    const std::string kind = m.xpbd ? "sweeps" : m.iteration_kind == "Newton iterations"
                                                     ? "Newton"
                                                     : "LM";
    out += fmt::format("{:<22} {:<14} {:>10} {:>12} {:>7} {:>12} {:>12}\n", m.key, kind, reach,
                       time, m.iteration.empty() ? 0 : m.iteration.back(),
                       num(m.residual.empty() ? std::nan("") : m.residual.back()),
                       num(m.final_error));
  }
  return out;
}

}  // namespace pbdbench
