// What the reference solvers built on a SceneSystem share (ref-bdf, ref-be, ref-sdirk2,
// ref-static): the model checks of their factories, the breakpoints of scripted motions, the
// step's argument checks, the hand-over between a State and the integrator's (q, u), and the
// report fields from counter differences.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/model.hpp"
#include "core/state.hpp"
#include "reference/reduced_linear_solver.hpp"
#include "reference/scene_system.hpp"
#include "reference/sundials_support.hpp"
#include "solver_api/options.hpp"
#include "solver_api/solver.hpp"

namespace pbdbench {

// Throws std::invalid_argument naming what `solver` cannot simulate: rigid constraints
// (compliance 0, not FEM-kind: "use ref-dae, or give them a compliance"), and colliders or
// particle contact unless options.ref_ignore_colliders. Lists the first few offenders by index,
// kind and group.
void check_reference_model(const std::string& solver, const Model& model,
                           const SolverOptions& options);

// options.ref_linear_solver as a LinearSolverKind (throws std::invalid_argument when unknown).
LinearSolverKind linear_solver_kind(const SolverOptions& options);

// True when the model has colliders or particle contact.
bool has_contact(const Model& model);

// The times where the scripted motion of an attached particle is not smooth (sorted, distinct):
// a Linear motion's start and stop (finite, after the start), an Oscillate or Circle motion's
// start. The kinematic particle's velocity jumps there, so the force has a kink in t (a jump
// when a damped constraint sees that velocity). Motions that drive only colliders are left out.
std::vector<double> motion_breakpoints(const Model& model);

// The report's reference fields from a counter difference (what one step did).
void add_counters(StepReport& report, const sun::Counters& delta);

// A SceneSystem and the hand-over between State and (q, u): the integrator continues from its
// own state when the State is exactly what the last finish() wrote, and restarts otherwise (the
// first step, or a State someone changed in between).
class SceneStepper {
 public:
  // Keeps a pointer to `model`, which must outlive this object.
  explicit SceneStepper(const Model& model);

  const SceneSystem& system() const { return system_; }
  int dofs() const { return system_.dofs(); }

  // Throws std::invalid_argument unless dt is finite and > 0, `model` is the model this was
  // built for, and the state's arrays have its sizes.
  void check_step(const Model& model, const State& state, double dt) const;
  // True when `state` is bitwise the state the last finish() left.
  bool continues(const State& state) const;
  void gather(const State& state, Eigen::VectorXd& q, Eigen::VectorXd& u) const;
  // Writes (q, u) at t_new into the state (SceneSystem::scatter: kinematic particles on their
  // targets, compliant constraints' lambda = -C/alpha), sets state.time = t_new, counts the step,
  // and remembers the result for continues().
  void finish(State& state, double t_new, const Eigen::VectorXd& q, const Eigen::VectorXd& u);

 private:
  const Model* model_;
  SceneSystem system_;
  bool has_last_ = false;
  double last_time_ = 0.0;
  Points last_x_, last_v_;
};

}  // namespace pbdbench
