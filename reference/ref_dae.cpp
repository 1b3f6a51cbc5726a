// ref-dae: IDA on the constrained equations of motion of a scene in the stabilised index-2 form
// of Gear, Gupta and Leimkuhler (1985); reference/dae_system.hpp has the equations, this file
// maps a Model onto them (docs/reference.md, section "ref-dae").
//
// - f(t, q, u) comes from the SceneSystem: compliant constraints, FEM elements, gravity and the
//   damping of compliant constraints.
// - Every rigid constraint (compliance 0, EnergyModel::rigid_constraints()) must be a distance
//   constraint; its ends are dofs (dynamic particles) or prescribed points (kinematic particles on
//   their attachment targets at time t, pinned ones on their rest positions). A rigid constraint
//   between two non-dynamic particles constrains no dof: it is left out of the DAE, its lambda is
//   0 and it does not count in the drift.
// - A model with no rigid constraint is accepted: the DAE is then the implicit ODE
//   q' = u, M u' = f (index 0), integrated by IDA, a cross-check of ref-bdf.
// - Output at exactly t + dt (IDA_NORMAL, interpolated by IDA). The integrator keeps its history
//   between steps; it restarts (start(): consistent multipliers, velocities projected) on the
//   first step, whenever the state it is handed is not the one it wrote last, and on every kink
//   of a scripted motion (motion_breakpoints), which it never steps over: a kinematic end whose
//   velocity jumps jerks the rigid constraints, an impulse that the velocity projection applies.
// - Colliders and particle contact are refused unless solver.ref.ignore_colliders.
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "reference/dae_system.hpp"
#include "reference/integrators.hpp"
#include "reference/ref_common.hpp"
#include "reference/ref_dae.hpp"
#include "reference/scene_system.hpp"

namespace pbdbench {

namespace {

std::string describe_constraint(const Model& model, int j) {
  const Constraint& c = model.constraints[static_cast<size_t>(j)];
  std::string s = "constraint " + std::to_string(j) + " (" + to_string(c.kind) + ", particles";
  for (int i = 0; i < arity(c.kind); ++i) {
    s += ' ';
    s += std::to_string(c.particles[static_cast<size_t>(i)]);
  }
  if (c.group < model.group_names.size()) s += ", group '" + model.group_names[c.group] + "'";
  return s + ")";
}

// Refuses what the DAE does not simulate, naming it.
void check_model(const SolverOptions& options, const Model& model) {
  if (!options.ref_ignore_colliders) {
    const std::string hint =
        ": the reference solvers simulate no contacts (set solver.ref.ignore_colliders = true to "
        "run without them)";
    if (!model.planes.empty())
      throw std::invalid_argument(options.name + ": the model has plane collider 0 (of " +
                                  std::to_string(model.planes.size()) + ")" + hint);
    if (!model.spheres.empty())
      throw std::invalid_argument(options.name + ": the model has sphere collider 0 (of " +
                                  std::to_string(model.spheres.size()) + ")" + hint);
    if (!model.meshes.empty())
      throw std::invalid_argument(options.name + ": the model has mesh collider 0 (of " +
                                  std::to_string(model.meshes.size()) + ")" + hint);
    if (model.particle_contact)
      throw std::invalid_argument(options.name + ": the model has particle contact on" + hint);
    if (model.surface_contact || model.self_contact)
      throw std::invalid_argument(options.name + ": the model has vertex-triangle contact on" + hint);
  }
}

// The acceleration of a motion at t (right limit), from the closed forms of core/model.hpp. A
// Circle's centre offset, -r u, is half its offset half a turn after the start.
Vec3 motion_acceleration(const Motion& m, double t) {
  const double s = t - m.start;
  const double w = 2.0 * std::numbers::pi * m.frequency;
  if (s < 0.0 || w == 0.0) return Vec3::Zero();
  switch (m.kind) {
    case MotionKind::Static:
    case MotionKind::Linear: return Vec3::Zero();
    case MotionKind::Oscillate: return -w * w * std::sin(w * s) * m.amplitude;
    case MotionKind::Circle: {
      const Vec3 centre = 0.5 * motion_offset(m, m.start + std::numbers::pi / w);
      return -w * w * (motion_offset(m, t) - centre);
    }
  }
  return Vec3::Zero();
}

class RefDae final : public Solver {
 public:
  RefDae(const SolverOptions& options, const Model& model)
      : options_(options),
        stepper_((check_model(options, model), model)),
        breakpoints_(motion_breakpoints(model)) {
    const EnergyModel& energy = stepper_.system().energy();
    std::vector<int> block_of(static_cast<size_t>(model.particle_count()), -1);
    for (size_t k = 0; k < energy.dynamic_particles().size(); ++k)
      block_of[static_cast<size_t>(energy.dynamic_particles()[k])] = static_cast<int>(k);
    attachment_of_.assign(static_cast<size_t>(model.particle_count()), -1);
    for (size_t a = 0; a < model.attachments.size(); ++a)
      attachment_of_[static_cast<size_t>(model.attachments[a].particle)] = static_cast<int>(a);

    std::vector<RigidDistance> rigid;
    for (int j : energy.rigid_constraints()) {
      const Constraint& c = model.constraints[static_cast<size_t>(j)];
      if (c.kind != ConstraintKind::Distance)
        throw std::invalid_argument(
            options.name + ": " + describe_constraint(model, j) + " is rigid (compliance 0), and " +
            options.name + " supports rigid distance constraints only: give it a compliance > 0");
      RigidDistance r;
      r.rest = c.rest;
      r.name = describe_constraint(model, j);
      for (size_t e = 0; e < 2; ++e) {
        const int p = c.particles[e];
        r.block[e] = block_of[static_cast<size_t>(p)];
        r.point[e] = r.block[e] < 0 ? p : -1;
      }
      if (r.block[0] < 0 && r.block[1] < 0) {
        skipped_.push_back(j);
        continue;
      }
      rigid_.push_back(j);
      rigid.push_back(r);
    }

    if (stepper_.dofs() == 0) return;  // nothing to integrate: kinematic particles only
    DaeSettings settings;
    settings.rtol = options.ref_rtol;
    settings.atol = options.ref_atol;
    settings.max_steps = options.ref_max_steps;
    settings.max_newton = options.ref_max_newton;
    const Model* m = &model;
    const std::vector<int>* attachment_of = &attachment_of_;
    dae_ = std::make_unique<DaeIntegrator>(
        stepper_.system(), std::move(rigid),
        [m, attachment_of](int p, double t) { return prescribed_point(*m, *attachment_of, p, t); },
        settings);
  }

  StepReport step(const Model& model, State& state, double dt) override {
    try {
      stepper_.check_step(model, state, dt);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(options_.name + ": " + e.what());
    }
    const double t_end = state.time + dt;
    if (!dae_) {
      stepper_.finish(state, t_end, Eigen::VectorXd(), Eigen::VectorXd());
      for (int j : skipped_) state.lambda[static_cast<size_t>(j)] = 0.0;
      StepReport r;
      r.substeps = 1;
      r.stop = StopReason::Converged;  // nothing to integrate
      r.constraint_drift = 0.0;
      return r;
    }
    const DaeCounters before = dae_->counters();
    if (!stepper_.continues(state)) {
      Eigen::VectorXd q, u;
      stepper_.gather(state, q, u);
      restart(state.time, q, u);
    } else if (is_breakpoint(state.time) && last_start_ != state.time) {
      // The last step stopped on a kink of a scripted motion: the prescribed velocity jumps here.
      restart(state.time, Eigen::VectorXd(dae_->q()), Eigen::VectorXd(dae_->u()));
    }
    // Never step over a kink: stop on each one inside the step and restart there (the velocity
    // projection of start() is the impulse the rigid constraints transmit).
    for (;;) {
      const double tb = next_breakpoint(dae_->time());
      if (tb < t_end) {
        dae_->advance(tb, tb);
        restart(tb, Eigen::VectorXd(dae_->q()), Eigen::VectorXd(dae_->u()));
        continue;
      }
      dae_->advance(t_end, tb);
      break;
    }
    const DaeCounters after = dae_->counters();

    stepper_.finish(state, t_end, dae_->q(), dae_->u());
    for (size_t k = 0; k < rigid_.size(); ++k)
      state.lambda[static_cast<size_t>(rigid_[k])] = dae_->lambda()[static_cast<Eigen::Index>(k)];
    for (int j : skipped_) state.lambda[static_cast<size_t>(j)] = 0.0;

    StepReport r;
    r.substeps = 1;
    r.stop = StopReason::Converged;  // IDA's failures stop the run (they throw)
    r.ref_steps = after.steps - before.steps;
    r.newton_iterations = after.newton_iterations - before.newton_iterations;
    r.linear_setups = after.linear_setups - before.linear_setups;
    r.linear_solves = after.linear_solves - before.linear_solves;
    r.error_test_failures = after.error_test_failures - before.error_test_failures;
    r.convergence_failures = after.convergence_failures - before.convergence_failures;
    r.time_linear = after.time_linear - before.time_linear;
    r.constraint_drift = dae_->drift();
    return r;
  }

  std::string name() const override { return options_.name; }

 private:
  void restart(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& u) {
    dae_->start(t, q, u);
    last_start_ = t;
  }
  bool is_breakpoint(double t) const {
    return std::binary_search(breakpoints_.begin(), breakpoints_.end(), t);
  }
  // The first kink after t, or +inf.
  double next_breakpoint(double t) const {
    const auto it = std::upper_bound(breakpoints_.begin(), breakpoints_.end(), t);
    return it == breakpoints_.end() ? std::numeric_limits<double>::infinity() : *it;
  }

  // A kinematic particle on its attachment target, or a pinned one at rest.
  static PrescribedPoint prescribed_point(const Model& model, const std::vector<int>& attachment_of,
                                          int p, double t) {
    const int a = attachment_of[static_cast<size_t>(p)];
    if (a >= 0) return ref_dae::attachment_point(model, a, t);
    PrescribedPoint pt;
    pt.x = model.rest_positions.row(p).transpose();
    return pt;
  }

  SolverOptions options_;
  SceneStepper stepper_;               // the SceneSystem and the State hand-over
  std::vector<double> breakpoints_;    // s, kinks of the scripted motions (sorted)
  std::vector<int> attachment_of_;     // (particles) attachment index, or -1
  std::vector<int> rigid_;             // model index of each DAE constraint
  std::vector<int> skipped_;           // rigid constraints between two non-dynamic particles
  std::unique_ptr<DaeIntegrator> dae_;  // null when the model has no dynamic particle
  double last_start_ = std::numeric_limits<double>::quiet_NaN();  // s, time of the last start()
};

}  // namespace

PrescribedPoint ref_dae::attachment_point(const Model& model, int attachment, double t) {
  const Attachment& at = model.attachments[static_cast<size_t>(attachment)];
  PrescribedPoint pt;
  pt.x = attachment_target(model, at, t);
  if (at.motion < 0) return pt;
  const Motion& motion = model.motions[static_cast<size_t>(at.motion)];
  const bool smooth_start = motion.kind == MotionKind::Oscillate || motion.kind == MotionKind::Circle;
  pt.v = motion_velocity(motion, smooth_start && t == motion.start
                                     ? std::nextafter(t, std::numeric_limits<double>::infinity())
                                     : t);
  pt.a = motion_acceleration(motion, t);
  return pt;
}

std::unique_ptr<Solver> make_ref_dae(const SolverOptions& options, const Model& model) {
  return std::make_unique<RefDae>(options, model);
}

}  // namespace pbdbench
