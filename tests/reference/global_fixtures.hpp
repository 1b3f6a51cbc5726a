// Helpers shared by the tests of the global projection: catalog scenes made small, the start of
// a step set up as reference/global_solver.cpp sets it up, and finite differences.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "catalog/solver_catalog.hpp"
#include "config/config.hpp"
#include "core/contacts.hpp"
#include "core/state.hpp"
#include "reference/global_problem.hpp"
#include "solver_api/solver.hpp"
#include "solvers/step_common.hpp"
#include "solvers/substep.hpp"

namespace pbdbench::test {

// A catalog scene with overrides ("key=value").
inline Scene catalog_scene(const std::string& name, const std::vector<std::string>& sets = {}) {
  std::vector<config::Override> overrides;
  for (const std::string& s : sets) overrides.push_back(config::parse_override(s));
  return config::build_scene(config::load(name, overrides));
}

inline SolverOptions catalog_options(const std::string& name,
                                     const std::vector<std::string>& sets = {}) {
  std::vector<config::Override> overrides;
  for (const std::string& s : sets) overrides.push_back(config::parse_override(s));
  return config::solver_options(config::load(name, overrides));
}

// Advances the scene's state by `steps` steps of dt with the named solver.
inline void advance(const Model& model, State& state, const std::string& solver, int steps,
                    double dt, int iterations = 20) {
  SolverOptions o;
  o.name = solver;
  o.iterations = iterations;
  auto s = make_solver(o, model);
  for (int k = 0; k < steps; ++k) s->step(model, state, dt);
}

// The global step of one substep h from `state`, set up as reference/global_solver.cpp does: kinematic
// targets at t + h, gravity, prediction, contacts at the prediction (margin 0). Returns x~.
inline Points begin_global_step(GlobalProblem& problem, const State& state, double h) {
  const Model& model = problem.model();
  Points x = state.x, v = state.v, x_pred;
  const double t_end = state.time + h;
  set_kinematic(model, x, v, t_end);
  apply_gravity(model, h, v);
  predict_positions(model, x, v, h, x_pred);
  problem.begin_step(x, x_pred, h, t_end, find_contacts(model, x_pred, t_end, 0.0));
  return x_pred;
}

// Mass-weighted RMS distance between two position sets over the dynamic particles (m).
inline double gap_rms(const Model& model, const Points& a, const Points& b) {
  double s = 0.0, m = 0.0;
  for (int i = 0; i < model.particle_count(); ++i) {
    const double w = model.inv_mass[static_cast<size_t>(i)];
    if (!(w > 0.0)) continue;
    s += (a.row(i) - b.row(i)).squaredNorm() / w;
    m += 1.0 / w;
  }
  return std::sqrt(s / m);
}

}  // namespace pbdbench::test
