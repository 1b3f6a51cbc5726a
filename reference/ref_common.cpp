#include "reference/ref_common.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace pbdbench {

namespace {

// "constraint 3 (distance, group 'link')"
std::string describe_constraint(const Model& model, int j) {
  const Constraint& c = model.constraints[static_cast<size_t>(j)];
  std::string s = "constraint " + std::to_string(j) + " (" + to_string(c.kind);
  if (c.group < model.group_names.size())
    s += ", group '" + model.group_names[c.group] + "'";
  return s + ")";
}

}  // namespace

void check_reference_model(const std::string& solver, const Model& model,
                           const SolverOptions& options) {
  std::vector<int> rigid;
  for (int j = 0; j < model.constraint_count(); ++j) {
    const Constraint& c = model.constraints[static_cast<size_t>(j)];
    if (c.compliance == 0.0 && !is_fem_kind(c.kind)) rigid.push_back(j);
  }
  if (!rigid.empty()) {
    std::ostringstream os;
    os << solver << " cannot simulate rigid constraints (compliance 0): ";
    const size_t shown = std::min<size_t>(rigid.size(), 3);
    for (size_t k = 0; k < shown; ++k) os << (k ? ", " : "") << describe_constraint(model, rigid[k]);
    if (rigid.size() > shown) os << " and " << rigid.size() - shown << " more";
    os << "; use ref-dae, or give them a compliance";
    throw std::invalid_argument(os.str());
  }
  if (!options.ref_ignore_colliders) {
    std::vector<std::string> what;
    if (!model.planes.empty()) what.push_back(std::to_string(model.planes.size()) + " plane collider(s)");
    if (!model.spheres.empty()) what.push_back(std::to_string(model.spheres.size()) + " sphere collider(s)");
    if (!model.meshes.empty()) what.push_back(std::to_string(model.meshes.size()) + " mesh collider(s)");
    if (model.particle_contact) what.push_back("particle contact");
    if (model.surface_contact || model.self_contact) what.push_back("vertex-triangle contact");
    if (!what.empty()) {
      std::ostringstream os;
      os << solver << " does not simulate contacts, and the scene has ";
      for (size_t k = 0; k < what.size(); ++k) os << (k ? " and " : "") << what[k];
      os << "; set solver.ref.ignore_colliders = true to run it without them";
      if (solver == "ref-bdf" || solver == "ref-sdirk2")
        os << ", or use ref-be, which simulates contact with a barrier (an adaptive or "
              "multistep method would need the collision check inside its own step and error "
              "control, which CVODE and ARKODE do not offer)";
      throw std::invalid_argument(os.str());
    }
  }
}

bool has_contact(const Model& model) {
  return !model.planes.empty() || !model.spheres.empty() || !model.meshes.empty() ||
         model.particle_contact || model.surface_contact || model.self_contact;
}

LinearSolverKind linear_solver_kind(const SolverOptions& options) {
  LinearSolverKind kind{};
  if (!parse_linear_solver_kind(options.ref_linear_solver, kind))
    throw std::invalid_argument("solver.ref.linear_solver: unknown linear solver '" +
                                options.ref_linear_solver + "' (reduced or full)");
  return kind;
}

std::vector<double> motion_breakpoints(const Model& model) {
  std::vector<double> t;
  for (const Attachment& a : model.attachments) {
    if (a.motion < 0) continue;
    const Motion& m = model.motions[static_cast<size_t>(a.motion)];
    switch (m.kind) {
      case MotionKind::Static: break;
      case MotionKind::Linear:
        t.push_back(m.start);
        if (std::isfinite(m.stop) && m.stop < 1e300 && m.stop > m.start) t.push_back(m.stop);
        break;
      case MotionKind::Oscillate:
      case MotionKind::Circle: t.push_back(m.start); break;
    }
  }
  std::sort(t.begin(), t.end());
  t.erase(std::unique(t.begin(), t.end()), t.end());
  return t;
}

void add_counters(StepReport& report, const sun::Counters& d) {
  report.ref_steps += d.steps;
  report.newton_iterations += d.newton_iterations;
  report.linear_setups += d.linear_setups;
  report.linear_solves += d.linear_solves;
  report.error_test_failures += d.error_test_failures;
  report.convergence_failures += d.convergence_failures;
  report.cholesky_factorizations += d.cholesky_factorizations;
  report.lu_factorizations += d.lu_factorizations;
  report.time_linear += d.time_linear;
}

// ---------------------------------------------------------------------------------------------

SceneStepper::SceneStepper(const Model& model) : model_(&model), system_(model) {}

void SceneStepper::check_step(const Model& model, const State& state, double dt) const {
  if (!std::isfinite(dt) || !(dt > 0.0)) {
    std::ostringstream os;
    os << "dt = " << dt << " must be a finite number > 0";
    throw std::invalid_argument(os.str());
  }
  if (&model != model_)
    throw std::invalid_argument("the solver was built for another model");
  const auto n = static_cast<Eigen::Index>(model.particle_count());
  if (state.x.rows() != n || state.v.rows() != n)
    throw std::invalid_argument("the state has " + std::to_string(state.x.rows()) +
                                " positions and " + std::to_string(state.v.rows()) +
                                " velocities; the model has " + std::to_string(n) + " particles");
}

bool SceneStepper::continues(const State& state) const {
  return has_last_ && state.time == last_time_ && state.x == last_x_ && state.v == last_v_;
}

void SceneStepper::gather(const State& state, Eigen::VectorXd& q, Eigen::VectorXd& u) const {
  system_.gather(state, q, u);
}

void SceneStepper::finish(State& state, double t_new, const Eigen::VectorXd& q,
                          const Eigen::VectorXd& u) {
  if (dofs() > 0) {
    system_.scatter(q, u, t_new, state);
  } else {
    // Nothing to integrate: the kinematic particles still follow their targets.
    const Eigen::VectorXd none;
    system_.scatter(none, none, t_new, state);
  }
  state.time = t_new;
  state.step += 1;
  has_last_ = true;
  last_time_ = state.time;
  last_x_ = state.x;
  last_v_ = state.v;
}

}  // namespace pbdbench
